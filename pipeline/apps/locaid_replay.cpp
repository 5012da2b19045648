// locaid-replay: VO + degraded GPS (+ IMU) + EKF over a recorded drive, as fast
// as possible, with accuracy against the untouched OXTS ground truth. It runs
// the frame loop every server session runs (pipeline/frame_loop.hpp) over the
// drive's frames.
//
// Threads (started and joined here): PrefetchSource reads and rectifies the
// next frames on one thread; the main thread runs VO and the filter.
#include "kitti/dataset.hpp"
#include "kitti/parse_number.hpp"
#include "pipeline/apps/prefetch_source.hpp"
#include "pipeline/apps/replay_mcap.hpp"
#include "pipeline/apps/replay_run.hpp"
#include "pipeline/apps/vo_cache.hpp"
#include "pipeline/frame_loop.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

using namespace locaid;

namespace {

// "--ekf name=value": the numeric EkfConfig fields a filter experiment tunes.
void ApplyEkfSetting(fusion::EkfConfig& c, const std::string& setting) {
  const std::map<std::string, double*> fields = {
      {"accel_noise_mps2_sqrt_hz", &c.accel_noise_mps2_sqrt_hz},
      {"gyro_noise_radps_sqrt_hz", &c.gyro_noise_radps_sqrt_hz},
      {"accel_bias_walk_mps3_sqrt_hz", &c.accel_bias_walk_mps3_sqrt_hz},
      {"gyro_bias_walk_radps2_sqrt_hz", &c.gyro_bias_walk_radps2_sqrt_hz},
      {"vo_cov_scale", &c.vo_cov_scale},
      {"vo_sigma_t_per_m", &c.vo_sigma_t_per_m},
      {"vo_sigma_lateral_per_m", &c.vo_sigma_lateral_per_m},
      {"vo_sigma_vertical_per_m", &c.vo_sigma_vertical_per_m},
      {"vo_min_sigma_t_m", &c.vo_min_sigma_t_m},
      {"vo_min_sigma_rot_rad", &c.vo_min_sigma_rot_rad},
      {"vo_gate_probability", &c.vo_gate_probability},
      {"gps_gate_probability", &c.gps_gate_probability},
      {"init_cov_inflation", &c.init_cov_inflation},
      {"init_velocity_sigma_mps", &c.init_velocity_sigma_mps},
      {"init_roll_pitch_sigma_rad", &c.init_roll_pitch_sigma_rad},
      {"init_accel_bias_sigma_mps2", &c.init_accel_bias_sigma_mps2},
      {"init_gyro_bias_sigma_radps", &c.init_gyro_bias_sigma_radps},
      {"max_imu_gap_s", &c.max_imu_gap_s},
      {"gravity_mps2", &c.gravity_mps2},
      {"vo_boresight_sigma_rad", &c.vo_boresight_sigma_rad},
      {"vo_scale_sigma", &c.vo_scale_sigma},
      {"gps_lever_arm_x_m", &c.gps_lever_arm_body_m.x()},
      {"gps_lever_arm_y_m", &c.gps_lever_arm_body_m.y()},
      {"gps_lever_arm_z_m", &c.gps_lever_arm_body_m.z()},
      {"gps_latency_s", &c.gps_latency_s},
      {"adaptive_vo_rotation_noise_max_scale", &c.adaptive_vo_rotation_noise_max_scale},
      {"no_imu_lost_sigma_mps", &c.no_imu_lost_sigma_mps},
      {"degraded_hold_s", &c.degraded_hold_s},
      {"vo_only_after_periods", &c.vo_only_after_periods},
      {"nhc_sigma_lateral_mps", &c.nhc_sigma_lateral_mps},
      {"nhc_sigma_vertical_mps", &c.nhc_sigma_vertical_mps},
      {"zupt_speed_mps", &c.zupt_speed_mps},
      {"zupt_sigma_mps", &c.zupt_sigma_mps},
      {"zupt_max_estimated_speed_mps", &c.zupt_max_estimated_speed_mps},
      {"speed_sigma_mps", &c.speed_sigma_mps},
      {"speed_scale_sigma", &c.speed_scale_sigma},
  };
  const auto eq = setting.find('=');
  const std::string name = setting.substr(0, eq);
  const auto it = fields.find(name);
  if (eq == std::string::npos || it == fields.end()) {
    std::string known;
    for (const auto& [k, v] : fields) known += (known.empty() ? "" : ", ") + k;
    throw std::runtime_error("--ekf " + setting + ": expected NAME=VALUE with NAME one of " + known);
  }
  double value = 0;
  std::string why;
  if (!kitti::ParseFiniteDouble(std::string_view(setting).substr(eq + 1), value, why)) {
    throw std::runtime_error("--ekf " + setting + ": value must be a finite number >= 0 (it " + why + ")");
  }
  if (value < 0) throw std::runtime_error("--ekf " + setting + ": value must be a finite number >= 0");
  *it->second = value;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locaid-replay: VO + GPS/IMU fusion over a recorded drive, with outage metrics"};
  std::string drive_dir, scenario_arg = "open-sky", out_tum, out_csv, out_mcap, vo_method = "default";
  std::string out_bag;
  bool json = false, no_imu = false;
  std::string vehicle_constraints = "auto";
  int max_frames = 0;
  int64_t seed = -1;
  std::string vo_cache_path;
  std::vector<std::string> ekf_settings;
  app.add_option("--drive", drive_dir, "drive folder (raw sync/extract, or synthetic)")->required();
  app.add_option("--scenario", scenario_arg, "built-in scenario name or YAML file");
  app.add_option("--out-tum", out_tum, "fused poses T_enu_body as TUM");
  app.add_option("--out-csv", out_csv, "per-frame CSV for clients/plot_outage.py");
  app.add_option("--out-mcap", out_mcap,
                 "the poses as an MCAP recording (the Foxglove channels of `locaid subscribe --format mcap`)");
  app.add_option("--out-bag", out_bag,
                 "the poses as a ROS 2 bag (MCAP, ros2msg/CDR: odometry, fix, tf; see docs/api.md \"ROS 2 output\")");
  app.add_flag("--json", json, "print metrics as JSON on stdout");
  app.add_flag("--no-imu", no_imu, "VO + GPS only (no IMU)");
  app.add_option("--vehicle-constraints", vehicle_constraints,
                 "car motion constraints (non-holonomic, zero-velocity updates): auto (once a speed sensor "
                 "reports), on (always), off (a platform that slides)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  app.add_option("--vo-method", vo_method, "VO method (default, thesis)");
  app.add_option("--max-frames", max_frames, "stop after N frames (0: all)");
  app.add_option("--seed", seed, "override the scenario seed");
  app.add_option("--vo-cache", vo_cache_path,
                 "reuse the VO results in FILE (same drive, method and frame count) or write them there");
  app.add_option("--ekf", ekf_settings, "filter setting NAME=VALUE (repeatable), e.g. vo_sigma_t_per_m=0.01");
  CLI11_PARSE(app, argc, argv);

  try {
    auto dataset_owned = kitti::OpenDataset(drive_dir);
    const kitti::StereoDataset& dataset = *dataset_owned;
    if (dataset.oxts().empty())
      throw std::runtime_error(drive_dir + ": no OXTS records (needed for GPS/IMU and ground truth)");
    size_t n_frames = dataset.size();
    if (max_frames > 0) n_frames = std::min(n_frames, static_cast<size_t>(max_frames));
    if (n_frames < 2) throw std::runtime_error(drive_dir + ": fewer than 2 frames");

    fusion::Scenario scenario = pipeline::LoadScenario(scenario_arg);
    if (seed >= 0) scenario.seed = static_cast<uint64_t>(seed);
    const double duration_s = static_cast<double>(dataset.time_ns(n_frames - 1) - dataset.time_ns(0)) * 1e-9;
    scenario = fusion::PlaceOutagesForDrive(scenario, duration_s);
    const std::string coverage = fusion::OutageCoverageWarning(scenario, duration_s);
    if (!coverage.empty()) std::cerr << "locaid-replay: warning: " << coverage << "\n";

    pipeline::LocalizerOptions options;
    options.vo_method = vo_method;
    options.ekf.use_imu = !no_imu;
    options.ekf.vehicle_constraints = vehicle_constraints != "off";
    options.ekf.vehicle_constraints_need_speed = vehicle_constraints == "auto";
    for (const auto& setting : ekf_settings) ApplyEkfSetting(options.ekf, setting);
    options.ekf = pipeline::EkfConfigForScenario(options.ekf, scenario);
    const std::string cache_header =
        pipeline::VoCacheHeader(std::filesystem::weakly_canonical(drive_dir).string(), vo_method, n_frames);
    std::optional<pipeline::VoResults> vo_cache;
    if (!vo_cache_path.empty() && !scenario.camera_faults.empty())
      throw std::runtime_error("--vo-cache: scenario " + scenario.name +
                               " has camera faults, which change what VO sees; a VO cache holds VO of the untouched "
                               "images (run without --vo-cache)");
    if (!vo_cache_path.empty()) vo_cache = pipeline::ReadVoCache(vo_cache_path, cache_header);
    auto localizer = vo_cache ? std::make_unique<pipeline::Localizer>(
                                    dataset.T_cam0_imu(), options,
                                    std::make_unique<pipeline::RecordedOdometry>(*vo_cache))
                              : std::make_unique<pipeline::Localizer>(dataset.camera(), dataset.T_cam0_imu(), options);
    pipeline::ReplayRun run(dataset, *localizer, scenario);
    auto frames = std::make_unique<pipeline::DatasetFrameSource>(std::move(dataset_owned), 0,
                                                                 static_cast<int64_t>(n_frames) - 1, !vo_cache);
    pipeline::FrameLoop loop(std::make_unique<pipeline::PrefetchSource>(std::move(frames), 4),
                             pipeline::ScenarioStage(scenario), std::move(localizer));

    std::optional<pipeline::ReplayMcap> mcap;
    if (!out_mcap.empty()) mcap.emplace(out_mcap);
    std::optional<pipeline::ReplayBag> out_bag_recording;
    if (!out_bag.empty()) out_bag_recording.emplace(out_bag, dataset.T_cam0_imu());
    pipeline::VoResults vo_computed;
    const auto wall0 = std::chrono::steady_clock::now();
    for (;;) {
      const pipeline::StepResult step = loop.Step();
      if (step.kind == pipeline::StepResult::Kind::kEnd) break;
      if (!step.error.empty()) std::cerr << "\nwarning: " << step.error << "\n";
      if (step.kind != pipeline::StepResult::Kind::kPose) continue;
      run.Add(step);
      if (!vo_cache) vo_computed.emplace(step.frame_index, step.frame.vo);
      if (mcap) mcap->Add(step);
      if (out_bag_recording) out_bag_recording->Add(step);
      if (step.frame_index % 50 == 0)
        std::cerr << "\rframe " << step.frame_index << "/" << n_frames << " mode "
                  << fusion::ToString(step.frame.pose.mode) << "      " << std::flush;
    }
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    std::cerr << "\rframes " << run.poses() << " in " << wall_s << " s\n";

    if (!vo_cache_path.empty() && !vo_cache) pipeline::WriteVoCache(vo_cache_path, cache_header, vo_computed);
    if (mcap) {
      mcap->Close();
      std::cerr << "locaid-replay: " << mcap->poses() << " poses -> " << out_mcap << "\n";
    }
    if (out_bag_recording) {
      out_bag_recording->Close();
      std::cerr << "locaid-replay: " << out_bag_recording->poses() << " poses -> " << out_bag << " (ROS 2 bag)\n";
    }
    if (!out_csv.empty()) run.WriteCsv(out_csv);
    if (!out_tum.empty()) run.WriteTum(out_tum);

    const auto metrics = run.Metrics();
    if (json) {
      nlohmann::json j = run.Summary(metrics, wall_s);
      j["drive"] = drive_dir;
      j["scenario"] = scenario.name;
      j["use_imu"] = !no_imu;
      j["vo_method"] = vo_method;
      j["vo_from_cache"] = vo_cache.has_value();
      j["warnings"] = coverage.empty() ? nlohmann::json::array() : nlohmann::json::array({coverage});
      std::cout << j.dump(2) << std::endl;
    } else {
      std::cout << "scenario " << scenario.name << (no_imu ? " (no IMU)" : "") << ", frames/s "
                << static_cast<double>(run.poses()) / wall_s << "\n"
                << pipeline::DescribeMetrics(metrics);
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "locaid-replay: " << e.what() << "\n";
    return 1;
  }
}
