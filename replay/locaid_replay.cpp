// locaid-replay: VO + degraded GPS (+ IMU) + EKF over a recorded drive, as fast
// as possible, with accuracy against the untouched OXTS ground truth. It runs
// the frame loop every server session runs (pipeline/frame_loop.hpp) over the
// drive's frames.
//
// Threads (started and joined here): PrefetchSource reads and rectifies the
// next frames on one thread; the main thread runs VO and the filter.
#include "fusion/fixed_lag_smoother.hpp"
#include "fusion/offline_smoother.hpp"
#include "kitti/dataset.hpp"
#include "kitti/parse_number.hpp"
#include "bag/bag_topics.hpp"
#include "replay/prefetch_source.hpp"
#include "replay/replay_mcap.hpp"
#include "replay/replay_run.hpp"
#include "replay/vo_cache.hpp"
#include "pipeline/bag_frame_source.hpp"
#include "pipeline/frame_loop.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/run_assembly.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

using namespace locaid;

namespace {

// "--ekf NAME=VALUE": a numeric filter setting (fusion/ekf_config.hpp), by
// its name "model.field" or its earlier flat name.
void ApplyEkfSetting(fusion::EkfConfig& c, const std::string& setting) {
  const auto eq = setting.find('=');
  double* field = eq == std::string::npos ? nullptr : fusion::FindEkfSetting(c, setting.substr(0, eq));
  if (field == nullptr) {
    std::string known;
    for (const auto& s : fusion::NumericEkfSettings(c)) known += (known.empty() ? "" : ", ") + s.name;
    throw std::runtime_error("--ekf " + setting + ": expected NAME=VALUE with NAME one of " + known);
  }
  double value = 0;
  std::string why;
  if (!kitti::ParseFiniteDouble(std::string_view(setting).substr(eq + 1), value, why)) {
    throw std::runtime_error("--ekf " + setting + ": value must be a finite number >= 0 (it " + why + ")");
  }
  if (value < 0) throw std::runtime_error("--ekf " + setting + ": value must be a finite number >= 0");
  *field = value;
}

// Everything the command line says.
struct ReplayArgs {
  std::string drive_dir, bag_path, bag_topics_path, scenario = "open-sky", vo_method = "default";
  std::string out_tum, out_csv, out_fixes, out_mcap, out_bag, vo_cache_path;
  std::string vehicle_constraints = "auto", vo_rotation_noise = "adaptive";
  bool json = false, no_imu = false, fixed_vo_noise = false, fixed_gps_noise = false, inspect = false;
  bool smooth = false;
  double smooth_memory_mb = 256, lag_s = 0;
  bool scenario_given = false;  // --scenario on the command line (a bag is then scanned whole)
  int max_frames = 0;
  int64_t seed = -1;
  double stereo_tolerance_ms = 10, reorder_window_ms = 500;
  std::vector<std::string> ekf_settings;
};

void AddOptions(CLI::App& app, ReplayArgs& a) {
  auto* drive_opt = app.add_option("--drive", a.drive_dir, "drive folder (raw sync/extract, or synthetic)");
  auto* bag_opt = app.add_option("--bag", a.bag_path, "a ROS 2 bag instead of a drive: a .mcap file or a rosbag2 "
                                                      "directory (docs/ros2-bags.md)");
  drive_opt->excludes(bag_opt);
  app.add_option("--bag-topics", a.bag_topics_path, "YAML naming the bag's topics (left_image, left_info, "
                                                    "right_image, right_info, imu, gps, speed); unnamed ones are "
                                                    "picked by type")
      ->check(CLI::ExistingFile);
  app.add_flag("--inspect", a.inspect, "with --bag: print the bag's topics and the choice, then exit");
  app.add_option("--stereo-tolerance-ms", a.stereo_tolerance_ms,
                 "with --bag: left/right image stamps further apart than this are no stereo pair")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--reorder-window-ms", a.reorder_window_ms,
                 "with --bag: messages are merged by header stamp within this window")
      ->check(CLI::Range(0.0, 60000.0));
  app.add_option("--scenario", a.scenario, "built-in scenario name or YAML file");
  app.add_option("--out-tum", a.out_tum, "fused poses T_enu_body as TUM");
  app.add_option("--out-csv", a.out_csv, "per-frame CSV for clients/plot_outage.py");
  app.add_option("--out-fixes", a.out_fixes,
                 "the GPS fixes the filter saw as CSV (t_ns,lat_deg,lon_deg,alt_m,sigma_h_m,sigma_v_m)");
  app.add_option("--out-mcap", a.out_mcap,
                 "the poses as an MCAP recording (the Foxglove channels of `locaid subscribe --format mcap`)");
  app.add_option("--out-bag", a.out_bag,
                 "the poses as a ROS 2 bag (MCAP, ros2msg/CDR: odometry, fix, tf; see docs/api.md \"ROS 2 output\")");
  app.add_flag("--json", a.json, "print metrics as JSON on stdout");
  app.add_flag("--smooth", a.smooth,
               "also smooth the whole drive (Rauch-Tung-Striebel, docs/smoothing.md): --json gains an "
               "object \"smoothed\", and every --out-* file holds the smoothed trajectory");
  app.add_option("--smooth-memory-mb", a.smooth_memory_mb,
                 "with --smooth: filter epochs kept in memory for the backward pass; the rest wait in an "
                 "unlinked file in TMPDIR")
      ->check(CLI::Range(1.0, 1e6));
  app.add_option("--lag", a.lag_s,
                 "smooth with a fixed lag of S seconds instead of the whole drive (what a live subscriber with "
                 "smoothing_lag_s S gets); implies --smooth")
      ->check(CLI::Range(0.001, 30.0));
  app.add_flag("--no-imu", a.no_imu, "VO + GPS only (no IMU)");
  app.add_flag("--fixed-vo-noise", a.fixed_vo_noise,
               "the fixed VO noise model: neither learnt nor adapted from the innovations (docs/api.md \"Learned noise\")");
  app.add_flag("--fixed-gps-noise", a.fixed_gps_noise, "the fixes' stated sigmas as they are, not a learnt multiple");
  app.add_option("--vo-rotation-noise", a.vo_rotation_noise,
                 "the VO rotation axes' noise: adaptive (default: adapted from the rotation innovations at "
                 "every update, outages included; the learnt scale only up to --ekf "
                 "vo.noise_rotation_scale_max, default 1) or learned (the learnt scale only); "
                 "--fixed-vo-noise: the fixed model, neither")
      ->check(CLI::IsMember({"adaptive", "learned"}));
  app.add_option("--vehicle-constraints", a.vehicle_constraints,
                 "car motion constraints (non-holonomic, zero-velocity updates): auto (once a speed sensor "
                 "reports, and at every frame VO cannot use), on (always), off (a platform that slides)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  app.add_option("--vo-method", a.vo_method, "VO method (default, thesis)");
  app.add_option("--max-frames", a.max_frames, "stop after N frames (0: all)");
  app.add_option("--seed", a.seed, "override the scenario seed");
  app.add_option("--vo-cache", a.vo_cache_path,
                 "reuse the VO results in FILE (same drive, method and frame count) or write them there");
  app.add_option("--ekf", a.ekf_settings, "filter setting NAME=VALUE (repeatable), e.g. vo_sigma_t_per_m=0.01");
}

// What is wrong with the combination of options, "" if nothing.
std::string CheckArgs(const ReplayArgs& a) {
  if (a.drive_dir.empty() == a.bag_path.empty()) return "give --drive DIR or --bag PATH";
  if (a.bag_path.empty() && (a.inspect || !a.bag_topics_path.empty())) return "--inspect and --bag-topics need --bag";
  return "";
}

pipeline::BagSourceOptions BagOptionsOf(const ReplayArgs& a) {
  pipeline::BagSourceOptions options;
  if (!a.bag_topics_path.empty()) options.topics = bag::LoadBagTopics(a.bag_topics_path);
  options.stereo_tolerance_s = a.stereo_tolerance_ms * 1e-3;
  options.reorder_window_s = a.reorder_window_ms * 1e-3;
  // A scenario's outages are placed over the whole drive: scan it all for its length.
  if (a.scenario_given) options.preview_s = 0;
  return options;
}

int Inspect(const ReplayArgs& a) {
  std::cout << bag::InspectBag(a.bag_path, BagOptionsOf(a).topics, [](double f) {
    std::cerr << "\rscanning " << static_cast<int>(100 * f) << " %" << std::flush;
  }) << std::flush;
  std::cerr << "\r              \r";
  return 0;
}

// The input: a drive folder (with ground truth) or a ROS 2 bag.
struct ReplayInput {
  std::unique_ptr<kitti::StereoDataset> dataset_owned;  // until the frame source takes it
  const kitti::StereoDataset* dataset = nullptr;        // nullptr for a bag
  std::unique_ptr<pipeline::BagFrameSource> bag_owned;  // until the frame loop takes it
  pipeline::BagFrameSource* bag = nullptr;
  size_t n_frames = 0;  // 0: not known (a bag without a summary)
  std::string path;
};

ReplayInput OpenInput(const ReplayArgs& a) {
  ReplayInput in;
  const size_t max_frames = static_cast<size_t>(a.max_frames);
  if (!a.bag_path.empty()) {
    in.path = a.bag_path;
    in.bag_owned = std::make_unique<pipeline::BagFrameSource>(a.bag_path, BagOptionsOf(a));
    in.bag = in.bag_owned.get();
    for (const auto& note : in.bag->notes()) std::cerr << "locaid-replay: " << note << "\n";
    in.n_frames = static_cast<size_t>(in.bag->total_frames());
    if (max_frames > 0 && (in.n_frames == 0 || in.n_frames > max_frames)) in.n_frames = max_frames;
    return in;
  }
  in.path = a.drive_dir;
  in.dataset_owned = kitti::OpenDataset(a.drive_dir);
  in.dataset = in.dataset_owned.get();
  if (in.dataset->oxts().empty())
    throw std::runtime_error(a.drive_dir + ": no OXTS records (needed for GPS/IMU and ground truth)");
  in.n_frames = in.dataset->size();
  if (max_frames > 0) in.n_frames = std::min(in.n_frames, max_frames);
  if (in.n_frames < 2) throw std::runtime_error(a.drive_dir + ": fewer than 2 frames");
  return in;
}

// The frames, read ahead on one thread: images are not decoded when VO comes from a cache.
std::unique_ptr<pipeline::FrameSource> FramesOf(ReplayInput& in, bool need_images) {
  std::unique_ptr<pipeline::FrameSource> frames;
  if (in.bag_owned) {
    frames = std::move(in.bag_owned);
  } else {
    frames = std::make_unique<pipeline::DatasetFrameSource>(std::move(in.dataset_owned), 0,
                                                            static_cast<int64_t>(in.n_frames) - 1, need_images);
  }
  return std::make_unique<pipeline::PrefetchSource>(std::move(frames), 4);
}

// The filter is IMU-driven unless --no-imu, or a bag has no IMU topic.
bool UsesImu(const ReplayArgs& a, const pipeline::BagFrameSource* bag) {
  return !a.no_imu && (!bag || bag->has_imu());
}

pipeline::RunOptions RunOptionsOf(const ReplayArgs& a, const pipeline::BagFrameSource* bag) {
  pipeline::RunOptions run;
  run.scenario = pipeline::LoadScenario(a.scenario);
  if (a.seed >= 0) run.scenario.seed = static_cast<uint64_t>(a.seed);
  pipeline::LocalizerOptions& options = run.localizer;
  options.vo_method = a.vo_method;
  options.ekf.imu.enabled = UsesImu(a, bag);
  options.ekf.vo.learn_noise = !a.fixed_vo_noise;
  options.ekf.gps.learn_noise = !a.fixed_gps_noise;
  options.ekf.vo.adaptive_rotation_noise = a.vo_rotation_noise == "adaptive";
  options.ekf.vehicle.constraints = a.vehicle_constraints != "off";
  options.ekf.vehicle.constraints_need_speed = a.vehicle_constraints == "auto";
  if (bag) options.ekf.gps.lever_arm_body_m = bag->gps_lever_arm_body_m();
  for (const auto& setting : a.ekf_settings) ApplyEkfSetting(options.ekf, setting);
  return run;
}

// Where the poses go besides the metrics: MCAP, a ROS 2 bag, the VO cache.
struct ReplayOutputs {
  std::optional<pipeline::ReplayMcap> mcap;
  std::optional<pipeline::ReplayBag> bag;
  std::optional<pipeline::VoResults> vo_computed;  // to write to --vo-cache
  // --smooth: the recordings wait for the smoothed poses.
  bool defer = false;
  std::vector<pipeline::StepResult> deferred;

  void Add(const pipeline::StepResult& step) {
    if (vo_computed) vo_computed->emplace(step.frame_index, step.frame.vo);
    if (defer && (mcap || bag)) {
      deferred.push_back(step);
      return;
    }
    if (mcap) mcap->Add(step);
    if (bag) bag->Add(step);
  }
  // The deferred steps with their smoothed poses (one per step, in order).
  void AddSmoothed(const std::vector<fusion::FusedPose>& smoothed) {
    for (size_t i = 0; i < deferred.size() && i < smoothed.size(); ++i) {
      deferred[i].frame.pose = smoothed[i];
      if (mcap) mcap->Add(deferred[i]);
      if (bag) bag->Add(deferred[i]);
    }
    deferred.clear();
  }
};

// --smooth: the whole drive after the forward pass (offline), or --lag S:
// a fixed lag as the poses come (what a live subscriber gets).
struct ReplaySmoothing {
  std::optional<fusion::OfflineSmoother> offline;
  std::optional<fusion::FixedLagSmoother> lag;
  std::optional<fusion::EpochLog> lag_log;
  std::vector<fusion::FusedPose> released;  // --lag: in order, one per pose
  nlohmann::json info;                      // what --json prints as "smoothing"

  ReplaySmoothing(const ReplayArgs& a, pipeline::Localizer& localizer) {
    if (a.lag_s > 0) {
      lag.emplace(a.lag_s, localizer.ekf().error_layout());
      lag_log.emplace([this](fusion::Epoch&& e) { lag->AddEpoch(e); });
      localizer.set_epoch_log(&*lag_log);
    } else {
      offline.emplace(fusion::EpochStoreOptions{.memory_budget_bytes = static_cast<size_t>(a.smooth_memory_mb * 1e6)});
      localizer.set_epoch_log(&offline->log());
    }
  }
  void Add(const pipeline::StepResult& step) {
    if (!lag) return;
    for (auto& p : lag->AddPose(step.frame.pose, step.frame.epoch, lag_log->open())) released.push_back(std::move(p));
  }
  // The backward pass (offline) or the last lag's poses; the run and the
  // recordings take the smoothed poses.
  void Finish(const pipeline::Localizer& localizer, pipeline::ReplayRun& run, ReplayOutputs& outputs) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<fusion::FusedPose> smoothed;
    if (lag) {
      for (auto& p : lag->Flush(lag_log->open())) released.push_back(std::move(p));
      smoothed = std::move(released);
    } else {
      std::cerr << "\rsmoothing " << offline->log().epochs() << " filter epochs..." << std::flush;
      smoothed = offline->Smooth(run.forward_poses(), run.epochs(), localizer.ekf().error_layout());
      const fusion::EpochStore& store = offline->store();
      std::cerr << "\rsmoothed " << store.size() << " filter epochs in "
                << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s ("
                << (store.bytes_in_memory() + store.bytes_spilled()) / 1e6 << " MB, "
                << store.bytes_spilled() / 1e6 << " MB of it spilled to TMPDIR)\n";
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (lag) {
      info = {{"kind", "fixed_lag"}, {"lag_s", lag->lag_s()}, {"flush_s", seconds}};
    } else {
      const fusion::EpochStore& store = offline->store();
      info = {{"kind", "offline"}, {"epochs", store.size()}, {"backward_pass_s", seconds},
              {"bytes_per_epoch", fusion::EpochBytes(localizer.ekf().error_layout().size)},
              {"bytes_spilled", store.bytes_spilled()}};
    }
    run.ApplySmoothed(smoothed);
    outputs.AddSmoothed(smoothed);
  }
};

// Runs the loop to the source's end (true) or --max-frames (false).
bool RunToEnd(pipeline::FrameLoop& loop, pipeline::ReplayRun& run, ReplayOutputs& outputs,
              ReplaySmoothing* smoothing, size_t max_frames, size_t n_frames) {
  for (;;) {
    if (max_frames > 0 && run.poses() >= max_frames) return false;  // a bag: no frame count
    const pipeline::StepResult step = loop.Step();
    if (step.kind == pipeline::StepResult::Kind::kEnd) return true;
    if (!step.error.empty()) std::cerr << "\nwarning: " << step.error << "\n";
    if (step.kind != pipeline::StepResult::Kind::kPose) continue;
    run.Add(step);
    outputs.Add(step);
    if (smoothing) smoothing->Add(step);
    if (step.frame_index % 50 == 0)
      std::cerr << "\rframe " << step.frame_index << (n_frames > 0 ? "/" + std::to_string(n_frames) : "") << " mode "
                << fusion::ToString(step.frame.pose.mode) << "      " << std::flush;
  }
}

nlohmann::json BagReport(const pipeline::BagFrameSource& bag, const std::string& path) {
  const pipeline::BagSourceStats& b = bag.stats();
  std::cerr << "locaid-replay: bag: " << b.frames << " frames, " << b.unpaired_images << " unpaired images, "
            << b.bad_images << " bad images, " << b.imu << " IMU, " << b.fixes << " fixes (" << b.no_fix
            << " no fix), " << b.speed << " speed, " << b.late << " late and " << b.undecodable
            << " undecodable messages dropped\n";
  return {{"path", path},
          {"topics", {{"left_image", bag.topics().left_image},
                      {"right_image", bag.topics().right_image},
                      {"imu", bag.topics().imu},
                      {"gps", bag.topics().gps},
                      {"speed", bag.topics().speed}}},
          {"frames", b.frames}, {"unpaired_images", b.unpaired_images}, {"bad_images", b.bad_images},
          {"imu_samples", b.imu}, {"fixes", b.fixes}, {"no_fix", b.no_fix}, {"speed_samples", b.speed},
          {"late_dropped", b.late}, {"undecodable", b.undecodable}, {"notes", bag.notes()}};
}

// Closes the recordings, writes the files asked for and prints the metrics.
void Report(const ReplayArgs& a, const ReplayInput& in, const pipeline::AssembledRun& assembled,
            const pipeline::ReplayRun& run, ReplayOutputs& outputs, const std::string& cache_header, bool ended,
            double wall_s, const nlohmann::json& smoothing) {
  std::cerr << "\rframes " << run.poses() << " in " << wall_s << " s\n";
  nlohmann::json bag_json;
  if (in.bag && ended) bag_json = BagReport(*in.bag, a.bag_path);
  if (outputs.vo_computed) pipeline::WriteVoCache(a.vo_cache_path, cache_header, *outputs.vo_computed);
  if (outputs.mcap) {
    outputs.mcap->Close();
    std::cerr << "locaid-replay: " << outputs.mcap->poses() << " poses -> " << a.out_mcap << "\n";
  }
  if (outputs.bag) {
    outputs.bag->Close();
    std::cerr << "locaid-replay: " << outputs.bag->poses() << " poses -> " << a.out_bag << " (ROS 2 bag)\n";
  }
  if (!a.out_csv.empty()) run.WriteCsv(a.out_csv);
  if (!a.out_tum.empty()) run.WriteTum(a.out_tum);
  if (!a.out_fixes.empty()) run.WriteFixes(a.out_fixes);
  const auto metrics = run.Metrics();
  if (!a.json) {
    std::cout << "scenario " << assembled.scenario.name << (UsesImu(a, in.bag) ? "" : " (no IMU)") << ", frames/s "
              << static_cast<double>(run.poses()) / wall_s << "\n"
              << pipeline::DescribeMetrics(metrics);
    if (run.smoothed()) std::cout << "smoothed:\n" << pipeline::DescribeMetrics(run.SmoothedMetrics());
    return;
  }
  nlohmann::json j = run.Summary(metrics, wall_s);
  if (in.dataset) j["drive"] = a.drive_dir;
  if (in.bag) j["bag"] = bag_json;
  j["scenario"] = assembled.scenario.name;
  if (!smoothing.is_null()) j["smoothing"] = smoothing;
  j["use_imu"] = UsesImu(a, in.bag);
  j["vo_method"] = a.vo_method;
  j["vo_from_cache"] = !a.vo_cache_path.empty() && !outputs.vo_computed;
  j["warnings"] = assembled.notice.empty() ? nlohmann::json::array() : nlohmann::json::array({assembled.notice});
  std::cout << j.dump(2) << std::endl;
}

}  // namespace

// Parse, assemble (pipeline/run_assembly.hpp, as a server session), run, report.
int main(int argc, char** argv) {
  CLI::App app{"locaid-replay: VO + GPS/IMU fusion over a recorded drive, with outage metrics"};
  ReplayArgs args;
  AddOptions(app, args);
  CLI11_PARSE(app, argc, argv);
  args.scenario_given = app.count("--scenario") > 0;
  if (const std::string bad = CheckArgs(args); !bad.empty()) {
    std::cerr << "locaid-replay: " << bad << "\n";
    return 2;
  }
  try {
    if (args.inspect) return Inspect(args);
    ReplayInput input = OpenInput(args);
    const pipeline::RunOptions options = RunOptionsOf(args, input.bag);
    const std::string cache_header = pipeline::VoCacheHeader(
        std::filesystem::weakly_canonical(input.path).string(), args.vo_method, input.n_frames);
    std::optional<pipeline::VoResults> vo_cache;
    if (!args.vo_cache_path.empty() && !options.scenario.camera_faults.empty())
      throw std::runtime_error("--vo-cache: scenario " + options.scenario.name +
                               " has camera faults, which change what VO sees; a VO cache holds VO of the untouched "
                               "images (run without --vo-cache)");
    if (!args.vo_cache_path.empty()) vo_cache = pipeline::ReadVoCache(args.vo_cache_path, cache_header);
    pipeline::Localizer* localizer = nullptr;  // owned by the frame loop
    Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
    auto assembled = pipeline::AssembleRun(FramesOf(input, !vo_cache), options, [&](const pipeline::EstimatorInputs& in) {
      T_cam0_imu = in.T_cam0_imu;
      auto made = vo_cache ? std::make_unique<pipeline::Localizer>(in.T_cam0_imu, in.localizer,
                                                                   std::make_unique<pipeline::RecordedOdometry>(*vo_cache))
                           : std::make_unique<pipeline::Localizer>(in.camera, in.T_cam0_imu, in.localizer);
      localizer = made.get();
      return made;
    });
    if (!assembled.notice.empty()) std::cerr << "locaid-replay: warning: " << assembled.notice << "\n";

    pipeline::ReplayRun run(input.dataset, *localizer, assembled.scenario);
    ReplayOutputs outputs;
    if (!args.out_mcap.empty()) outputs.mcap.emplace(args.out_mcap);
    if (!args.out_bag.empty()) outputs.bag.emplace(args.out_bag, T_cam0_imu);
    if (!args.vo_cache_path.empty() && !vo_cache) outputs.vo_computed.emplace();
    std::optional<ReplaySmoothing> smoothing;
    if (args.smooth || args.lag_s > 0) {
      smoothing.emplace(args, *localizer);
      run.KeepPosesForSmoothing();
      outputs.defer = true;
    }
    const auto wall0 = std::chrono::steady_clock::now();
    const bool ended = RunToEnd(*assembled.loop, run, outputs, smoothing ? &*smoothing : nullptr,
                                static_cast<size_t>(args.max_frames), input.n_frames);
    if (smoothing) smoothing->Finish(*localizer, run, outputs);
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    Report(args, input, assembled, run, outputs, cache_header, ended, wall_s,
           smoothing ? smoothing->info : nlohmann::json());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "locaid-replay: " << e.what() << "\n";
    return 1;
  }
}
