// locaid-replay: VO + degraded GPS (+ IMU) + EKF over a recorded drive, as fast
// as possible, with accuracy against the untouched OXTS ground truth. It runs
// the frame loop every server session runs (pipeline/frame_loop.hpp) over the
// drive's frames.
//
// Threads (started and joined here): PrefetchSource reads and rectifies the
// next frames on one thread; the main thread runs VO and the filter.
#include "kitti/dataset.hpp"
#include "kitti/parse_number.hpp"
#include "bag/bag_topics.hpp"
#include "pipeline/apps/prefetch_source.hpp"
#include "pipeline/apps/replay_mcap.hpp"
#include "pipeline/apps/replay_run.hpp"
#include "pipeline/apps/vo_cache.hpp"
#include "pipeline/bag_frame_source.hpp"
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
      {"vo_noise_prior_frames", &c.vo_noise_prior_frames},
      {"adaptive_vo_rotation_noise_max_scale", &c.adaptive_vo_rotation_noise_max_scale},
      {"vo_noise_window_frames", &c.vo_noise_window_frames},
      {"vo_noise_scale_min", &c.vo_noise_scale_min},
      {"vo_noise_scale_max", &c.vo_noise_scale_max},
      {"gps_noise_prior_fixes", &c.gps_noise_prior_fixes},
      {"gps_noise_window_fixes", &c.gps_noise_window_fixes},
      {"gps_noise_scale_min", &c.gps_noise_scale_min},
      {"gps_noise_scale_max", &c.gps_noise_scale_max},
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
  bool json = false, no_imu = false, fixed_vo_noise = false, fixed_gps_noise = false;
  std::string vehicle_constraints = "auto", vo_rotation_noise = "adaptive";
  int max_frames = 0;
  int64_t seed = -1;
  std::string vo_cache_path;
  std::vector<std::string> ekf_settings;
  std::string bag_path, bag_topics_path;
  bool inspect = false;
  double stereo_tolerance_ms = 10, reorder_window_ms = 500;
  auto* drive_opt = app.add_option("--drive", drive_dir, "drive folder (raw sync/extract, or synthetic)");
  auto* bag_opt = app.add_option("--bag", bag_path, "a ROS 2 bag instead of a drive: a .mcap file or a rosbag2 "
                                                    "directory (docs/ros2-bags.md)");
  drive_opt->excludes(bag_opt);
  app.add_option("--bag-topics", bag_topics_path, "YAML naming the bag's topics (left_image, left_info, right_image, "
                                                  "right_info, imu, gps, speed); unnamed ones are picked by type")
      ->check(CLI::ExistingFile);
  app.add_flag("--inspect", inspect, "with --bag: print the bag's topics and the choice, then exit");
  app.add_option("--stereo-tolerance-ms", stereo_tolerance_ms,
                 "with --bag: left/right image stamps further apart than this are no stereo pair")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--reorder-window-ms", reorder_window_ms,
                 "with --bag: messages are merged by header stamp within this window")
      ->check(CLI::Range(0.0, 60000.0));
  app.add_option("--scenario", scenario_arg, "built-in scenario name or YAML file");
  app.add_option("--out-tum", out_tum, "fused poses T_enu_body as TUM");
  app.add_option("--out-csv", out_csv, "per-frame CSV for clients/plot_outage.py");
  std::string out_fixes;
  app.add_option("--out-fixes", out_fixes,
                 "the GPS fixes the filter saw as CSV (t_ns,lat_deg,lon_deg,alt_m,sigma_h_m,sigma_v_m)");
  app.add_option("--out-mcap", out_mcap,
                 "the poses as an MCAP recording (the Foxglove channels of `locaid subscribe --format mcap`)");
  app.add_option("--out-bag", out_bag,
                 "the poses as a ROS 2 bag (MCAP, ros2msg/CDR: odometry, fix, tf; see docs/api.md \"ROS 2 output\")");
  app.add_flag("--json", json, "print metrics as JSON on stdout");
  app.add_flag("--no-imu", no_imu, "VO + GPS only (no IMU)");
  app.add_flag("--fixed-vo-noise", fixed_vo_noise,
               "the fixed VO noise model: neither learnt nor adapted from the innovations (docs/api.md \"Learned noise\")");
  app.add_flag("--fixed-gps-noise", fixed_gps_noise, "the fixes' stated sigmas as they are, not a learnt multiple");
  app.add_option("--vo-rotation-noise", vo_rotation_noise,
                 "the VO rotation axes' noise: adaptive (default: each axis takes the larger of the learnt "
                 "scale and one adapted from the rotation innovations at every update, outages included) or "
                 "learned (the learnt scale only); --fixed-vo-noise: the fixed model, neither")
      ->check(CLI::IsMember({"adaptive", "learned"}));
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
  if (drive_dir.empty() == bag_path.empty()) {
    std::cerr << "locaid-replay: give --drive DIR or --bag PATH\n";
    return 2;
  }
  if (bag_path.empty() && (inspect || !bag_topics_path.empty())) {
    std::cerr << "locaid-replay: --inspect and --bag-topics need --bag\n";
    return 2;
  }

  try {
    if (inspect) {
      pipeline::BagSourceOptions bag_options;
      if (!bag_topics_path.empty()) bag_options.topics = bag::LoadBagTopics(bag_topics_path);
      std::cout << bag::InspectBag(bag_path, bag_options.topics, [](double f) {
        std::cerr << "\rscanning " << static_cast<int>(100 * f) << " %" << std::flush;
      }) << std::flush;
      std::cerr << "\r              \r";
      return 0;
    }
    fusion::Scenario scenario = pipeline::LoadScenario(scenario_arg);
    if (seed >= 0) scenario.seed = static_cast<uint64_t>(seed);

    // The input: a drive folder (with ground truth) or a ROS 2 bag.
    std::unique_ptr<kitti::StereoDataset> dataset_owned;
    std::unique_ptr<pipeline::BagFrameSource> bag_owned;
    pipeline::BagFrameSource* bag_source = nullptr;  // owned by the frame loop once it runs
    size_t n_frames = 0;
    double duration_s = 0;
    if (!bag_path.empty()) {
      pipeline::BagSourceOptions bag_options;
      if (!bag_topics_path.empty()) bag_options.topics = bag::LoadBagTopics(bag_topics_path);
      bag_options.stereo_tolerance_s = stereo_tolerance_ms * 1e-3;
      bag_options.reorder_window_s = reorder_window_ms * 1e-3;
      // A scenario's outages are placed over the whole drive: scan it all for its length.
      if (app.count("--scenario") > 0) bag_options.preview_s = 0;
      bag_owned = std::make_unique<pipeline::BagFrameSource>(bag_path, bag_options);
      bag_source = bag_owned.get();
      for (const auto& note : bag_source->notes()) std::cerr << "locaid-replay: " << note << "\n";
      n_frames = static_cast<size_t>(bag_source->total_frames());
      if (max_frames > 0 && (n_frames == 0 || n_frames > static_cast<size_t>(max_frames)))
        n_frames = static_cast<size_t>(max_frames);
      duration_s = bag_source->duration_s();
    } else {
      dataset_owned = kitti::OpenDataset(drive_dir);
      if (dataset_owned->oxts().empty())
        throw std::runtime_error(drive_dir + ": no OXTS records (needed for GPS/IMU and ground truth)");
      n_frames = dataset_owned->size();
      if (max_frames > 0) n_frames = std::min(n_frames, static_cast<size_t>(max_frames));
      if (n_frames < 2) throw std::runtime_error(drive_dir + ": fewer than 2 frames");
      duration_s = static_cast<double>(dataset_owned->time_ns(n_frames - 1) - dataset_owned->time_ns(0)) * 1e-9;
    }
    const kitti::StereoDataset* dataset = dataset_owned.get();  // nullptr for a bag
    const StereoCamera camera = dataset ? dataset->camera() : bag_source->camera();
    const Eigen::Isometry3d T_cam0_imu = dataset ? dataset->T_cam0_imu() : bag_source->T_cam0_imu();
    scenario = fusion::PlaceOutagesForDrive(scenario, duration_s);
    const std::string coverage = fusion::OutageCoverageWarning(scenario, duration_s);
    if (!coverage.empty()) std::cerr << "locaid-replay: warning: " << coverage << "\n";

    pipeline::LocalizerOptions options;
    options.vo_method = vo_method;
    options.ekf.use_imu = !no_imu;
    options.ekf.learn_vo_noise = !fixed_vo_noise;
    options.ekf.learn_gps_noise = !fixed_gps_noise;
    options.ekf.adaptive_vo_rotation_noise = vo_rotation_noise == "adaptive";
    options.ekf.vehicle_constraints = vehicle_constraints != "off";
    options.ekf.vehicle_constraints_need_speed = vehicle_constraints == "auto";
    if (bag_source) options.ekf.gps_lever_arm_body_m = bag_source->gps_lever_arm_body_m();
    for (const auto& setting : ekf_settings) ApplyEkfSetting(options.ekf, setting);
    options.ekf = pipeline::EkfConfigForScenario(options.ekf, scenario);
    const std::string cache_header =
        pipeline::VoCacheHeader(std::filesystem::weakly_canonical(dataset ? drive_dir : bag_path).string(), vo_method,
                                n_frames);
    std::optional<pipeline::VoResults> vo_cache;
    if (!vo_cache_path.empty() && !scenario.camera_faults.empty())
      throw std::runtime_error("--vo-cache: scenario " + scenario.name +
                               " has camera faults, which change what VO sees; a VO cache holds VO of the untouched "
                               "images (run without --vo-cache)");
    if (!vo_cache_path.empty()) vo_cache = pipeline::ReadVoCache(vo_cache_path, cache_header);
    auto localizer = vo_cache ? std::make_unique<pipeline::Localizer>(
                                    T_cam0_imu, options, std::make_unique<pipeline::RecordedOdometry>(*vo_cache))
                              : std::make_unique<pipeline::Localizer>(camera, T_cam0_imu, options);
    pipeline::ReplayRun run(dataset, *localizer, scenario);
    std::unique_ptr<pipeline::FrameSource> frames;
    if (dataset) {
      frames = std::make_unique<pipeline::DatasetFrameSource>(std::move(dataset_owned), 0,
                                                              static_cast<int64_t>(n_frames) - 1, !vo_cache);
    } else {
      frames = std::move(bag_owned);
    }
    pipeline::FrameLoop loop(std::make_unique<pipeline::PrefetchSource>(std::move(frames), 4),
                             pipeline::ScenarioStage(scenario), std::move(localizer));

    std::optional<pipeline::ReplayMcap> mcap;
    if (!out_mcap.empty()) mcap.emplace(out_mcap);
    std::optional<pipeline::ReplayBag> out_bag_recording;
    if (!out_bag.empty()) out_bag_recording.emplace(out_bag, T_cam0_imu);
    pipeline::VoResults vo_computed;
    const auto wall0 = std::chrono::steady_clock::now();
    bool ended = false;  // the source said kEnd (its counters are final)
    for (;;) {
      if (max_frames > 0 && run.poses() >= static_cast<size_t>(max_frames)) break;  // a bag: no frame count
      const pipeline::StepResult step = loop.Step();
      if (step.kind == pipeline::StepResult::Kind::kEnd) {
        ended = true;
        break;
      }
      if (!step.error.empty()) std::cerr << "\nwarning: " << step.error << "\n";
      if (step.kind != pipeline::StepResult::Kind::kPose) continue;
      run.Add(step);
      if (!vo_cache) vo_computed.emplace(step.frame_index, step.frame.vo);
      if (mcap) mcap->Add(step);
      if (out_bag_recording) out_bag_recording->Add(step);
      if (step.frame_index % 50 == 0)
        std::cerr << "\rframe " << step.frame_index << (n_frames > 0 ? "/" + std::to_string(n_frames) : "") << " mode "
                  << fusion::ToString(step.frame.pose.mode) << "      " << std::flush;
    }
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    std::cerr << "\rframes " << run.poses() << " in " << wall_s << " s\n";
    nlohmann::json bag_json;
    if (bag_source && ended) {
      const pipeline::BagSourceStats& b = bag_source->stats();
      bag_json = {{"path", bag_path},
                  {"topics", {{"left_image", bag_source->topics().left_image},
                              {"right_image", bag_source->topics().right_image},
                              {"imu", bag_source->topics().imu},
                              {"gps", bag_source->topics().gps},
                              {"speed", bag_source->topics().speed}}},
                  {"frames", b.frames}, {"unpaired_images", b.unpaired_images}, {"bad_images", b.bad_images},
                  {"imu_samples", b.imu}, {"fixes", b.fixes}, {"no_fix", b.no_fix}, {"speed_samples", b.speed},
                  {"late_dropped", b.late}, {"undecodable", b.undecodable}, {"notes", bag_source->notes()}};
      std::cerr << "locaid-replay: bag: " << b.frames << " frames, " << b.unpaired_images << " unpaired images, "
                << b.bad_images << " bad images, " << b.imu << " IMU, " << b.fixes << " fixes (" << b.no_fix
                << " no fix), " << b.speed << " speed, " << b.late << " late and " << b.undecodable
                << " undecodable messages dropped\n";
    }

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
    if (!out_fixes.empty()) run.WriteFixes(out_fixes);

    const auto metrics = run.Metrics();
    if (json) {
      nlohmann::json j = run.Summary(metrics, wall_s);
      if (dataset) j["drive"] = drive_dir;
      if (bag_source) j["bag"] = bag_json;
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
