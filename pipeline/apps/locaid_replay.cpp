// locaid-replay: VO + degraded GPS (+ IMU) + EKF over a recorded drive, as fast
// as possible, with accuracy against the untouched OXTS ground truth.
//
// Threads (started and joined here): one loader thread decodes and rectifies
// the images into a bounded queue; the main thread runs VO and the filter.
#include "core/timed_pose.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts_pose.hpp"
#include "kitti/parse_number.hpp"
#include "pipeline/apps/replay_mcap.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/replay_metrics.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <GeographicLib/LocalCartesian.hpp>

#include <chrono>
#include <cstdlib>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <iomanip>
#include <iostream>
#include <mutex>
#include <optional>
#include <thread>

using namespace locaid;

namespace {

// Bounded single-producer / single-consumer queue of loaded frames.
struct LoadedFrame {
  size_t index = 0;
  vo::StereoFrame frame;
  std::string error;
};

class FrameQueue {
 public:
  explicit FrameQueue(size_t capacity) : capacity_(capacity) {}
  void Push(LoadedFrame f) {
    std::unique_lock lock(mutex_);
    not_full_.wait(lock, [&] { return q_.size() < capacity_ || stop_; });
    if (stop_) return;
    q_.push_back(std::move(f));
    not_empty_.notify_one();
  }
  std::optional<LoadedFrame> Pop() {
    std::unique_lock lock(mutex_);
    not_empty_.wait(lock, [&] { return !q_.empty() || done_; });
    if (q_.empty()) return std::nullopt;
    LoadedFrame f = std::move(q_.front());
    q_.pop_front();
    not_full_.notify_one();
    return f;
  }
  void Done() { std::lock_guard lock(mutex_); done_ = true; not_empty_.notify_all(); }
  void Stop() { std::lock_guard lock(mutex_); stop_ = true; not_full_.notify_all(); }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<LoadedFrame> q_;
  bool done_ = false, stop_ = false;
};

// VO results of a whole drive, so filter experiments can rerun without VO.
// Text, one frame per line: index t_ns status inliers, T_prev_curr (3x4 row
// major), covariance (6x6 upper triangle, row major). The header names the
// drive, method and frame count; a cache that does not match is an error.
struct VoCache {
  std::string header;
  std::vector<vo::RelativeMotion> motions;
};

std::string VoCacheHeader(const std::string& drive, const std::string& method, size_t frames) {
  return "locaid-vo-cache v2 method=" + method + " frames=" + std::to_string(frames) + " drive=" + drive;
}

std::optional<VoCache> ReadVoCache(const std::string& path, const std::string& expected_header) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  VoCache cache;
  std::getline(in, cache.header);
  if (cache.header != expected_header)
    throw std::runtime_error(path + ": VO cache written for another run (\"" + cache.header +
                             "\", expected \"" + expected_header + "\"); delete it or pick another file");
  std::string line;
  size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ls(line);
    size_t index = 0;
    int status = 0;
    vo::RelativeMotion m;
    ls >> index >> m.t_ns >> m.t_prev_ns >> status >> m.inliers;
    Eigen::Matrix<double, 3, 4> T;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) ls >> T(r, c);
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) {
        ls >> m.covariance(r, c);
        m.covariance(c, r) = m.covariance(r, c);
      }
    if (!ls || index != cache.motions.size() || status < 0 || status > 2)
      throw std::runtime_error(path + ":" + std::to_string(line_no) + ": malformed VO cache line");
    m.status = static_cast<vo::Status>(status);
    m.T_prev_curr.matrix().topRows<3>() = T;
    cache.motions.push_back(m);
  }
  return cache;
}

void WriteVoCache(const std::string& path, const std::string& header, const std::vector<vo::RelativeMotion>& motions) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw std::runtime_error(tmp + ": cannot write");
    out << header << '\n' << std::setprecision(17);
    for (size_t i = 0; i < motions.size(); ++i) {
      const auto& m = motions[i];
      out << i << ' ' << m.t_ns << ' ' << m.t_prev_ns << ' ' << static_cast<int>(m.status) << ' ' << m.inliers;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) out << ' ' << m.T_prev_curr.matrix()(r, c);
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) out << ' ' << m.covariance(r, c);
      out << '\n';
    }
    if (!out.flush()) throw std::runtime_error(tmp + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

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
  bool json = false, no_imu = false;
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
  app.add_flag("--json", json, "print metrics as JSON on stdout");
  app.add_flag("--no-imu", no_imu, "VO + GPS only (no IMU)");
  app.add_option("--vo-method", vo_method, "VO method (default, thesis)");
  app.add_option("--max-frames", max_frames, "stop after N frames (0: all)");
  app.add_option("--seed", seed, "override the scenario seed");
  app.add_option("--vo-cache", vo_cache_path,
                 "reuse the VO results in FILE (same drive, method and frame count) or write them there");
  app.add_option("--ekf", ekf_settings, "filter setting NAME=VALUE (repeatable), e.g. vo_sigma_t_per_m=0.01");
  CLI11_PARSE(app, argc, argv);

  try {
    const auto dataset = kitti::OpenDataset(drive_dir);
    const auto& oxts = dataset->oxts();
    if (oxts.empty()) throw std::runtime_error(drive_dir + ": no OXTS records (needed for GPS/IMU and ground truth)");
    size_t n_frames = dataset->size();
    if (max_frames > 0) n_frames = std::min(n_frames, static_cast<size_t>(max_frames));
    if (n_frames < 2) throw std::runtime_error(drive_dir + ": fewer than 2 frames");

    fusion::Scenario scenario = pipeline::LoadScenario(scenario_arg);
    if (seed >= 0) scenario.seed = static_cast<uint64_t>(seed);
    const double duration_s = static_cast<double>(dataset->time_ns(n_frames - 1) - dataset->time_ns(0)) * 1e-9;
    scenario = fusion::PlaceOutagesForDrive(scenario, duration_s);

    pipeline::LocalizerOptions options;
    options.vo_method = vo_method;
    options.ekf.use_imu = !no_imu;
    for (const auto& setting : ekf_settings) ApplyEkfSetting(options.ekf, setting);
    const std::string cache_header =
        VoCacheHeader(std::filesystem::weakly_canonical(drive_dir).string(), vo_method, n_frames);
    std::optional<VoCache> vo_cache;
    if (!vo_cache_path.empty()) vo_cache = ReadVoCache(vo_cache_path, cache_header);
    if (vo_cache && vo_cache->motions.size() != n_frames)
      throw std::runtime_error(vo_cache_path + ": VO cache has " + std::to_string(vo_cache->motions.size()) +
                               " frames, expected " + std::to_string(n_frames));
    std::vector<vo::RelativeMotion> vo_computed;
    pipeline::Localizer localizer(dataset->camera(), dataset->T_cam0_imu(), scenario, options);

    // Loader thread.
    FrameQueue queue(4);
    std::thread loader([&] {
      for (size_t i = 0; i < n_frames; ++i) {
        LoadedFrame f;
        f.index = i;
        f.frame.t_ns = dataset->time_ns(i);
        if (dataset->has_stereo(i) && !vo_cache) {
          try {
            auto images = dataset->Load(i);
            f.frame.left = std::move(images.left);
            f.frame.right = std::move(images.right);
          } catch (const std::exception& e) {
            f.error = e.what();
          }
        }
        queue.Push(std::move(f));
      }
      queue.Done();
    });

    std::optional<pipeline::ReplayMcap> mcap;
    if (!out_mcap.empty()) mcap.emplace(out_mcap);
    std::vector<pipeline::ReplaySample> samples;
    std::vector<pipeline::FrameResult> results;
    std::vector<Eigen::Isometry3d> vo_motion;  // raw VO (body axes) per frame
    std::vector<std::optional<Eigen::Vector3d>> gps_enu, gps_gt;
    std::vector<int> gps_rej;
    size_t next_oxts = 0;
    const auto wall0 = std::chrono::steady_clock::now();
    std::optional<GeographicLib::LocalCartesian> gt_enu;
    std::vector<TimedPose> gt_poses;
    auto gt_at = [&](int64_t t_ns) -> std::optional<Eigen::Isometry3d> {
      return kitti::InterpolatePose(gt_poses, t_ns, static_cast<int64_t>(0.5e9));
    };
    int lost_frames = 0;
    int rejection_run = 0, rejection_run_v = 0, max_rejection_run = 0, max_rejection_run_v = 0;
    double vo_ms_total = 0;
    std::vector<pipeline::VoErrorPair> vo_pairs;  // VO vs ground truth (noise calibration)
    while (auto lf = queue.Pop()) {
      const size_t i = lf->index;
      if (!lf->error.empty()) std::cerr << "warning: " << lf->error << "\n";
      if (!lf->frame.left.empty()) lf->frame.t_ns = dataset->time_ns(i);
      const int64_t t_ns = dataset->time_ns(i);
      size_t end = next_oxts;
      while (end < oxts.size() && oxts[end].t_ns <= t_ns) ++end;
      const std::span<const kitti::OxtsSample> new_oxts(oxts.data() + next_oxts, end - next_oxts);
      auto r = vo_cache ? localizer.Fuse(vo_cache->motions[i], new_oxts) : localizer.Process(lf->frame, new_oxts);
      if (!vo_cache) vo_computed.push_back(r.vo);
      next_oxts = end;
      vo_ms_total += r.vo_ms;
      if (r.vo.status == vo::Status::kLost) ++lost_frames;

      if (!gt_enu && localizer.has_enu_origin()) {
        const auto& e = localizer.ekf().enu();
        gt_enu.emplace(e.origin_lat_deg(), e.origin_lon_deg(), e.origin_alt_m());
        for (const auto& s : oxts) gt_poses.push_back({s.t_ns, kitti::OxtsToEnuPose(s.record, *gt_enu)});
      }
      if (r.vo.status != vo::Status::kLost && gt_enu && i > 0) {
        const auto g0 = gt_at(r.vo_body.t_prev_ns), g1 = gt_at(r.vo_body.t_ns);
        if (g0 && g1)
          vo_pairs.push_back({r.vo_body.T_prev_curr, g0->inverse() * *g1, r.vo_body.covariance,
                              localizer.ekf().VoNoise(r.vo_body.covariance, r.vo_body.T_prev_curr)});
      }
      vo_motion.push_back(r.vo.status == vo::Status::kLost ? Eigen::Isometry3d::Identity()
                                                           : r.vo_body.T_prev_curr);

      pipeline::ReplaySample s;
      s.t_s = static_cast<double>(t_ns - dataset->time_ns(0)) * 1e-9;
      s.initialized = localizer.ekf().initialized();
      s.mode = r.pose.mode;
      s.in_outage = r.in_outage;
      s.p_enu_est_m = r.pose.T_enu_body.translation();
      s.P_pos_m2 = r.pose.covariance.topLeftCorner<3, 3>();
      s.has_gt = false;  // no ground truth here: left out of the metrics
      if (gt_enu) {
        if (auto gt = gt_at(t_ns)) {
          s.p_enu_gt_m = gt->translation();
          s.has_gt = true;
        }
      }
      samples.push_back(s);
      std::optional<Eigen::Vector3d> g, g_gt;
      int rej = 0;
      for (const auto& f : r.gps_feeds) {
        g = f.p_enu_m;
        rej = rej || f.rejected;
        if (!f.accepted && !f.rejected) continue;  // buffered before initialisation
        rejection_run = f.rejected ? rejection_run + 1 : 0;
        rejection_run_v = f.rejected_vertical ? rejection_run_v + 1 : 0;
        max_rejection_run = std::max(max_rejection_run, rejection_run);
        max_rejection_run_v = std::max(max_rejection_run_v, rejection_run_v);
      }
      // Ground truth at the time of the fix the CSV shows (the last one fed).
      if (gt_enu && !r.gps_feeds.empty()) {
        if (auto gt = gt_at(r.gps_feeds.back().fix.t_ns)) g_gt = gt->translation();
      }
      gps_enu.push_back(g);
      gps_gt.push_back(g_gt);
      gps_rej.push_back(rej);
      if (mcap) {
        std::optional<Eigen::Isometry3d> truth = gt_enu ? gt_at(t_ns) : std::nullopt;
        double lat = 0, lon = 0, alt = 0;
        if (truth) gt_enu->Reverse(truth->translation().x(), truth->translation().y(), truth->translation().z(), lat,
                                   lon, alt);
        mcap->Add(static_cast<int64_t>(i), r, truth, lat, lon, alt);
      }
      results.push_back(std::move(r));
      if (i % 50 == 0)
        std::cerr << "\rframe " << i << "/" << n_frames << " mode " << fusion::ToString(results.back().pose.mode)
                  << "      " << std::flush;
    }
    queue.Stop();
    loader.join();
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    std::cerr << "\rframes " << samples.size() << " in " << wall_s << " s\n";

    if (!vo_cache_path.empty() && !vo_cache) WriteVoCache(vo_cache_path, cache_header, vo_computed);
    const auto metrics = pipeline::ComputeReplayMetrics(samples, scenario.gps_sigma_h_m);
    // VO-only track: the raw VO chained in ENU from the ground-truth pose of frame 0.
    std::vector<Eigen::Isometry3d> vo_only;
    {
      Eigen::Isometry3d T = gt_enu ? gt_at(std::max(dataset->time_ns(0), oxts.front().t_ns))
                                         .value_or(Eigen::Isometry3d::Identity())
                                   : Eigen::Isometry3d::Identity();
      for (size_t k = 0; k < vo_motion.size(); ++k) {
        if (k > 0) T = T * vo_motion[k];
        vo_only.push_back(T);
      }
    }

    if (mcap) {
      mcap->Close();
      std::cerr << "locaid-replay: " << mcap->poses() << " poses -> " << out_mcap << "\n";
    }
    if (!out_csv.empty()) {
      std::vector<pipeline::PlotExtras> extras(samples.size());
      for (size_t k = 0; k < samples.size(); ++k) {
        extras[k] = {gps_enu[k], gps_rej[k] != 0, vo_only[k].translation(), gps_gt[k]};
      }
      pipeline::WritePlotCsv(out_csv, samples, extras);
    }
    if (!out_tum.empty()) {
      std::ofstream tum(out_tum);
      if (!tum) throw std::runtime_error(out_tum + ": cannot write");
      tum << std::fixed << std::setprecision(6);
      for (size_t k = 0; k < results.size(); ++k) {
        if (!samples[k].initialized) continue;  // a pose without ground truth is still written
        const auto& T = results[k].pose.T_enu_body;
        const Eigen::Quaterniond q(T.linear());
        tum << dataset->tum_time_s(k) << ' ' << T.translation().x() << ' ' << T.translation().y() << ' '
            << T.translation().z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
      }
    }

    nlohmann::json j;
    j["drive"] = drive_dir;
    j["scenario"] = scenario.name;
    j["use_imu"] = !no_imu;
    j["vo_method"] = vo_method;
    j["frames"] = samples.size();
    j["rmse_gps_m"] = metrics.rmse_gps_m;
    j["nees_mean"] = metrics.nees_mean;
    j["nees_bound_99"] = metrics.nees_bound_99;
    j["max_vertical_error_m"] = metrics.max_vertical_error_m;
    j["frames_per_s"] = samples.size() / wall_s;
    j["vo_ms_mean"] = vo_ms_total / std::max<size_t>(1, samples.size());
    j["vo_lost_frames"] = lost_frames;
    j["vo_rejected_by_gate"] = localizer.ekf().vo_rejected();
    j["gps_used"] = results.back().pose.gps_used;
    j["gps_rejected"] = results.back().pose.gps_rejected;
    j["gps_rejected_vertical"] = localizer.ekf().gps_rejected_vertical();
    j["gps_resets"] = results.back().pose.gps_resets;
    const Eigen::Vector3d& rot_scale = localizer.ekf().vo_rotation_noise_scale();
    j["vo_rotation_noise_scale"] = {rot_scale.x(), rot_scale.y(), rot_scale.z()};
    j["max_gps_rejection_run"] = max_rejection_run;
    j["max_gps_rejection_run_vertical"] = max_rejection_run_v;
    const auto vo_err = pipeline::ComputeVoErrorStats(vo_pairs);
    auto vec6 = [](const Eigen::Matrix<double, 6, 1>& v) { return std::vector<double>(v.data(), v.data() + 6); };
    j["vo_error"] = {{"frames", vo_err.frames},
                     {"rms_error_t_m_r_rad", vec6(vo_err.rms_error)},
                     {"rms_reported_sigma", vec6(vo_err.rms_sigma)},
                     {"nees6_mean_reported_cov", vo_err.nees_mean},
                     {"nees6_median_reported_cov", vo_err.nees_median},
                     {"rms_model_sigma", vec6(vo_err.rms_model_sigma)},
                     {"nees6_mean_model", vo_err.nees_mean_model},
                     {"nees6_median_model", vo_err.nees_median_model}};
    j["outages"] = nlohmann::json::array();
    for (const auto& o : metrics.outages) {
      j["outages"].push_back({{"start_s", o.start_s}, {"duration_s", o.duration_s},
                              {"distance_m", o.distance_m}, {"end_error_m", o.end_error_m},
                              {"end_error_pct", o.end_error_pct}, {"max_error_m", o.max_error_m},
                              {"reconverge_s", o.reconverge_s}, {"max_jump_m", o.max_jump_m}});
    }
    if (json) {
      std::cout << j.dump(2) << std::endl;
    } else {
      std::cout << "scenario " << scenario.name << (no_imu ? " (no IMU)" : "") << ": frames "
                << samples.size() << ", rmse_gps_m " << metrics.rmse_gps_m << ", nees_mean "
                << metrics.nees_mean << ", frames/s " << samples.size() / wall_s << "\n";
      for (const auto& o : metrics.outages)
        std::cout << "  outage at " << o.start_s << " s for " << o.duration_s << " s: "
                  << o.distance_m << " m driven, end error " << o.end_error_m << " m ("
                  << o.end_error_pct << " %), max " << o.max_error_m << " m, reconverged after "
                  << o.reconverge_s << " s\n";
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "locaid-replay: " << e.what() << "\n";
    return 1;
  }
}
