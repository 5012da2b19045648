// locaid-score: scores a pose stream recorded with `locaid subscribe --format
// csv` against the untouched OXTS ground truth of the drive it came from, with
// the same metrics as locaid-replay, and writes the CSV that
// clients/plot_outage.py plots.
//
//   locaid-score --drive DIR --poses REC.csv --scenario NAME|FILE
//                [--out-csv PLOT.csv] [--json]
//
// Ground truth: the OXTS position (IMU/body origin) interpolated to each
// frame's image time, in an ENU frame at the first OXTS record; the recorded
// lat/lon/alt go into the same frame, so the filter's own ENU origin (its
// first degraded fix) does not enter the score.
#include "core/timed_pose.hpp"
#include "sim/scenario.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts_pose.hpp"
#include "pipeline/replay_metrics.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using locaid::fusion::Mode;

struct RecordedPose {
  double t_s = 0;
  long frame_index = 0;
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  double sigma_e_m = 0, sigma_n_m = 0, sigma_u_m = 0;
  Mode mode = Mode::kLost;
  bool gps_outage = false;
};

Mode ParseMode(const std::string& name, const std::string& where) {
  for (Mode m : {Mode::kGpsFused, Mode::kGpsDegraded, Mode::kVoOnly, Mode::kLost}) {
    if (name == locaid::fusion::ToString(m)) return m;
  }
  throw std::runtime_error(where + ": unknown mode '" + name + "'");
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

// Reads the columns it needs by name, so extra columns never break it.
std::vector<RecordedPose> ReadRecording(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(path + ": empty file, expected a CSV header");
  std::map<std::string, size_t> col;
  const auto header = SplitCsv(line);
  for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  for (const char* need : {"t_s", "frame_index", "lat_deg", "lon_deg", "alt_m", "sigma_e_m", "sigma_n_m",
                           "sigma_u_m", "mode", "gps_outage"}) {
    if (!col.count(need)) throw std::runtime_error(path + ":1: no column '" + std::string(need) + "'");
  }
  std::vector<RecordedPose> poses;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    const auto cells = SplitCsv(line);
    const std::string where = path + ":" + std::to_string(line_no);
    if (cells.size() < header.size()) {
      // A recorder killed mid-line leaves a short last line: stop there.
      std::cerr << "locaid-score: " << where << ": " << cells.size() << " fields, expected " << header.size()
                << "; ignoring the rest of the file\n";
      break;
    }
    auto num = [&](const char* name) {
      try {
        return std::stod(cells[col[name]]);
      } catch (const std::exception&) {
        throw std::runtime_error(where + ": column " + name + " is not a number: '" + cells[col[name]] + "'");
      }
    };
    RecordedPose p;
    p.t_s = num("t_s");
    p.frame_index = static_cast<long>(num("frame_index"));
    p.lat_deg = num("lat_deg");
    p.lon_deg = num("lon_deg");
    p.alt_m = num("alt_m");
    p.sigma_e_m = num("sigma_e_m");
    p.sigma_n_m = num("sigma_n_m");
    p.sigma_u_m = num("sigma_u_m");
    p.mode = ParseMode(cells[col["mode"]], where);
    p.gps_outage = num("gps_outage") != 0;
    poses.push_back(p);
  }
  if (poses.empty()) throw std::runtime_error(path + ": no poses recorded");
  return poses;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locaid-score: score a recorded pose stream against the drive's OXTS ground truth"};
  std::string drive_dir, poses_path, scenario_arg = "open-sky", out_csv;
  bool json = false;
  app.add_option("--drive", drive_dir, "drive the session ran on (raw sync/extract or synthetic)")->required();
  app.add_option("--poses", poses_path, "CSV written by `locaid subscribe --format csv`")->required();
  app.add_option("--scenario", scenario_arg, "scenario of the session (its GPS sigma sets the reconvergence bound)")
      ->capture_default_str();
  app.add_option("--out-csv", out_csv, "per-frame CSV for clients/plot_outage.py");
  app.add_flag("--json", json, "print the metrics as one JSON object");
  CLI11_PARSE(app, argc, argv);

  try {
    const auto dataset = locaid::kitti::OpenDataset(drive_dir);
    const auto& oxts = dataset->oxts();
    if (oxts.empty()) throw std::runtime_error(drive_dir + ": no OXTS records, nothing to score against");
    const auto scenario = locaid::pipeline::LoadScenario(scenario_arg);
    const auto recorded = ReadRecording(poses_path);

    const auto& first = oxts.front().record;
    const GeographicLib::LocalCartesian enu(first.lat_deg, first.lon_deg, first.alt_m);
    std::vector<locaid::TimedPose> gt_poses;
    gt_poses.reserve(oxts.size());
    for (const auto& s : oxts) gt_poses.push_back({s.t_ns, locaid::kitti::OxtsToEnuPose(s.record, enu)});

    std::vector<locaid::pipeline::ReplaySample> samples;
    int64_t t0_ns = dataset->time_ns(0);
    int skipped = 0;
    for (const auto& p : recorded) {
      if (p.frame_index < 0 || static_cast<size_t>(p.frame_index) >= dataset->size()) {
        ++skipped;
        continue;
      }
      const int64_t t_ns = dataset->time_ns(static_cast<size_t>(p.frame_index));
      const auto gt = locaid::kitti::InterpolatePose(gt_poses, t_ns, 500'000'000);
      if (!gt) {
        ++skipped;
        continue;
      }
      locaid::pipeline::ReplaySample s;
      s.t_s = (t_ns - t0_ns) * 1e-9;
      s.p_enu_gt_m = gt->translation();
      double x = 0, y = 0, z = 0;
      enu.Forward(p.lat_deg, p.lon_deg, p.alt_m, x, y, z);
      s.p_enu_est_m = {x, y, z};
      s.P_pos_m2 = Eigen::Vector3d(p.sigma_e_m * p.sigma_e_m, p.sigma_n_m * p.sigma_n_m, p.sigma_u_m * p.sigma_u_m)
                       .asDiagonal();
      s.mode = p.mode;
      s.in_outage = p.gps_outage;
      s.initialized = std::isfinite(p.lat_deg) && p.mode != Mode::kLost;
      samples.push_back(s);
    }
    if (samples.empty()) throw std::runtime_error(poses_path + ": no recorded pose matches a frame with ground truth");
    const auto metrics = locaid::pipeline::ComputeReplayMetrics(samples, scenario.gps_sigma_h_m);

    // GPS and VO-only tracks are not part of a recorded stream: left empty.
    if (!out_csv.empty()) locaid::pipeline::WritePlotCsv(out_csv, samples);

    nlohmann::ordered_json j;
    j["drive"] = drive_dir;
    j["poses"] = poses_path;
    j["scenario"] = scenario.name;
    j["frames"] = metrics.frames;
    j["skipped_poses"] = skipped;
    j["rmse_gps_m"] = metrics.rmse_gps_m;
    j["nees_mean_diag"] = metrics.nees_mean;  // from the recorded per-axis sigmas only
    j["outages"] = nlohmann::json::array();
    for (const auto& o : metrics.outages) {
      j["outages"].push_back({{"start_s", o.start_s},
                              {"duration_s", o.duration_s},
                              {"distance_m", o.distance_m},
                              {"end_error_m", o.end_error_m},
                              {"end_error_pct", o.end_error_pct},
                              {"max_error_m", o.max_error_m},
                              {"reconverge_s", o.reconverge_s},
                              {"max_jump_m", o.max_jump_m}});
    }
    if (json) {
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << locaid::pipeline::DescribeMetrics(metrics);
    }
  } catch (const std::exception& e) {
    std::cerr << "locaid-score: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
