// locaid-bench-frame-cost: where the time of one real frame goes, stage by
// stage, on the calling thread only (one core): the frame loop's work for a
// KITTI raw drive split into
//   read     both PNG files into memory (page cache after the first pass)
//   decode   both PNGs to 8-bit gray (cv::imdecode)
//   rectify  both images through the drive's precomputed maps (cv::remap)
//   fuse     the frame's OXTS samples through the scenario stage into the EKF
//   vo       stereo VO on the frame (Localizer::Process: VO part)
//   ekf      the VO update and the pose (Localizer::Process: fusion part)
//   publish  the PoseUpdate a session streams, filled and serialized
// then the sum ("all-in"). Every frame of the drive is run --passes times; the
// first pass is reported apart (cold file cache). Prints a table, or JSON with
// --json.
//
//   locaid-bench-frame-cost --drive DIR [--passes 3] [--max-frames N] [--json]
#include "kitti/dataset.hpp"
#include "kitti/raw_drive.hpp"
#include "output/pose_message.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/run_assembly.hpp"
#include "pipeline/scenario_stage.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
namespace lp = locaid::pipeline;

double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

std::vector<uchar> ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

const std::vector<std::string> kStages = {"read", "decode", "rectify", "fuse", "vo", "ekf", "publish", "all_in"};

struct Samples {
  std::map<std::string, std::vector<double>> ms;
  nlohmann::json Summary() const {
    nlohmann::json j;
    for (const auto& stage : kStages) {
      std::vector<double> v = ms.at(stage);
      std::sort(v.begin(), v.end());
      double sum = 0;
      for (double x : v) sum += x;
      j[stage] = {{"mean_ms", sum / static_cast<double>(v.size())},
                  {"median_ms", v[v.size() / 2]},
                  {"p90_ms", v[v.size() * 9 / 10]}};
    }
    j["frames"] = ms.at("all_in").size();
    return j;
  }
};

// One pass over the drive with a fresh localizer (so every pass does the same work).
Samples RunPass(const std::string& drive_dir, size_t max_frames) {
  auto dataset = locaid::kitti::OpenDataset(drive_dir);
  const auto* raw = dynamic_cast<const locaid::kitti::RawDrive*>(dataset.get());
  if (!raw) throw std::runtime_error(drive_dir + ": not a KITTI raw drive (the profile splits decode and rectify)");
  const size_t n = max_frames > 0 ? std::min(max_frames, raw->size()) : raw->size();
  std::vector<std::pair<std::string, std::string>> paths;
  for (size_t i = 0; i < n; ++i) paths.emplace_back(raw->left_path(i).string(), raw->right_path(i).string());
  const locaid::kitti::RawDrive& drive = *raw;
  // Times and OXTS from the frame loop's own source, images loaded here stage by stage.
  lp::DatasetFrameSource source(std::move(dataset), 0, static_cast<int64_t>(n) - 1, /*load_images=*/false);
  // The run every session and replay assembles (pipeline/run_assembly.hpp),
  // its stages driven here one by one.
  lp::RunOptions options;
  options.scenario = lp::LoadScenario("open-sky");
  const lp::PlacedRun run = lp::PlaceRun(source, options);
  lp::ScenarioStage stage(run.scenario);
  const std::unique_ptr<lp::Estimator> localizer = lp::MakeLocalizer(run.estimator);
  Samples s;
  for (const auto& name : kStages) s.ms[name];
  for (uint64_t sequence = 0;; ++sequence) {
    lp::SourceItem item = source.Next();
    if (item.kind == lp::SourceItem::Kind::kEnd) break;
    if (item.kind != lp::SourceItem::Kind::kFrame) continue;
    const auto i = static_cast<size_t>(item.index);
    auto t = Clock::now();
    const std::vector<uchar> left_png = ReadBytes(paths[i].first), right_png = ReadBytes(paths[i].second);
    const double read_ms = MsSince(t);
    t = Clock::now();
    const cv::Mat left_raw = cv::imdecode(left_png, cv::IMREAD_GRAYSCALE);
    const cv::Mat right_raw = cv::imdecode(right_png, cv::IMREAD_GRAYSCALE);
    const double decode_ms = MsSince(t);
    if (left_raw.empty() || right_raw.empty()) throw std::runtime_error(paths[i].first + ": cannot decode");
    t = Clock::now();
    locaid::vo::StereoFrame frame{item.t_ns, drive.Rectify(0, left_raw), drive.Rectify(1, right_raw)};
    const double rectify_ms = MsSince(t);
    t = Clock::now();
    stage.BeginFrame(item.t_ns, item.samples);
    if (!item.samples.empty()) localizer->Fuse(stage.Apply(item.samples));
    const double fuse_ms = MsSince(t);
    lp::StepResult r;
    r.kind = lp::StepResult::Kind::kPose;
    r.frame_index = item.index;
    r.t_ns = item.t_ns;
    r.frame = localizer->Process(frame);
    t = Clock::now();
    locaid::v1::PoseUpdate msg;
    locaid::output::FillPoseUpdate(r, r.frame.vo_ms + r.frame.fusion_ms, &msg);
    msg.set_sequence(sequence);
    const std::string wire = msg.SerializeAsString();
    const double publish_ms = MsSince(t);
    if (wire.empty()) throw std::runtime_error("empty PoseUpdate");
    const double values[] = {read_ms, decode_ms, rectify_ms, fuse_ms, r.frame.vo_ms, r.frame.fusion_ms, publish_ms};
    double all_in = 0;
    for (size_t k = 0; k < std::size(values); ++k) {
      s.ms[kStages[k]].push_back(values[k]);
      all_in += values[k];
    }
    s.ms["all_in"].push_back(all_in);
  }
  if (s.ms["all_in"].empty()) throw std::runtime_error(drive_dir + ": no frame with both images");
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Per-stage cost of a real frame on one core (decode, rectify, VO, EKF, publish)"};
  std::string drive;
  int passes = 3;
  size_t max_frames = 0;
  bool json = false;
  app.add_option("--drive", drive, "KITTI raw drive folder (…_extract or …_sync)")->required();
  app.add_option("--passes", passes, "passes over the drive; the first (cold cache) is reported apart")
      ->check(CLI::Range(2, 100));
  app.add_option("--max-frames", max_frames, "frames per pass (0: all)");
  app.add_flag("--json", json, "print JSON");
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);  // one core: what one session of the server gets
  try {
    const Samples cold = RunPass(drive, max_frames);
    Samples warm;
    for (int p = 1; p < passes; ++p) {
      const Samples s = RunPass(drive, max_frames);
      for (const auto& [stage, v] : s.ms) warm.ms[stage].insert(warm.ms[stage].end(), v.begin(), v.end());
    }
    nlohmann::json out{{"drive", drive}, {"passes", passes}, {"first_pass", cold.Summary()}, {"warm", warm.Summary()}};
    if (json) {
      std::cout << out.dump(2) << "\n";
      return 0;
    }
    std::printf("%-8s %9s %9s %9s   (warm passes, %d frames; first pass all-in mean %.2f ms)\n", "stage", "mean_ms",
                "median_ms", "p90_ms", out["warm"]["frames"].get<int>(),
                out["first_pass"]["all_in"]["mean_ms"].get<double>());
    for (const auto& stage : kStages) {
      const auto& j = out["warm"][stage];
      std::printf("%-8s %9.2f %9.2f %9.2f\n", stage.c_str(), j["mean_ms"].get<double>(),
                  j["median_ms"].get<double>(), j["p90_ms"].get<double>());
    }
  } catch (const std::exception& e) {
    std::cerr << "locaid-bench-frame-cost: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
