// What locaid-replay keeps of each pose the frame loop gives, and the
// outputs it writes at the end: metrics (JSON or text), the per-frame CSV of
// clients/plot_outage.py, and the fused poses as TUM.
#pragma once

#include "core/timed_pose.hpp"
#include "sim/scenario.hpp"
#include "kitti/dataset.hpp"
#include "pipeline/frame_loop.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/replay_metrics.hpp"

#include <GeographicLib/LocalCartesian.hpp>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace locaid::pipeline {

// The outages of a metrics object as locaid-replay --json prints them.
nlohmann::json OutagesJson(const std::vector<OutageStats>& outages);

class ReplayRun {
 public:
  // `dataset` (nullptr: a source without ground truth, e.g. a ROS 2 bag) and
  // `localizer` must outlive the run.
  ReplayRun(const kitti::StereoDataset* dataset, const Localizer& localizer, const sim::Scenario& scenario)
      : dataset_(dataset), localizer_(localizer), scenario_(scenario) {}

  // One pose of the frame loop (kind kPose).
  void Add(const StepResult& step);

  size_t poses() const { return samples_.size(); }
  ReplayMetrics Metrics() const { return ComputeReplayMetrics(samples_, scenario_.gps_sigma_h_m); }

  // Smoothing (--smooth): Add keeps every forward pose and its epoch; once
  // the smoother has run, ApplySmoothed takes its poses (one per Add), and
  // the files written afterwards (CSV, TUM) hold the smoothed trajectory.
  void KeepPosesForSmoothing() { keep_poses_ = true; }
  const std::vector<fusion::FusedPose>& forward_poses() const { return poses_; }
  const std::vector<int64_t>& epochs() const { return epochs_; }
  void ApplySmoothed(const std::vector<fusion::FusedPose>& smoothed);
  bool smoothed() const { return !smoothed_samples_.empty(); }
  ReplayMetrics SmoothedMetrics() const {
    return ComputeReplayMetrics(smoothed_samples_, scenario_.gps_sigma_h_m);
  }
  // The metrics and filter figures locaid-replay --json prints.
  nlohmann::json Summary(const ReplayMetrics& metrics, double wall_s) const;
  void WriteCsv(const std::string& path) const;
  // Initialised poses only; time = the frame's TUM time.
  void WriteTum(const std::string& path) const;
  // The fixes the filter saw (after the scenario), one per line:
  // t_ns,lat_deg,lon_deg,alt_m,sigma_h_m,sigma_v_m (the sigmas the filter used).
  void WriteFixes(const std::string& path) const;

 private:
  std::optional<Eigen::Isometry3d> TruthAt(int64_t t_ns) const;

  const kitti::StereoDataset* dataset_;
  std::optional<int64_t> t0_ns_;  // time of the first pose (no dataset)
  const Localizer& localizer_;
  const sim::Scenario scenario_;
  // Ground truth: every OXTS record in the filter's ENU frame, once it has one.
  std::optional<GeographicLib::LocalCartesian> gt_enu_;
  std::vector<TimedPose> gt_poses_;

  std::vector<ReplaySample> samples_;
  bool keep_poses_ = false;
  std::vector<fusion::FusedPose> poses_;  // forward, when kept for smoothing
  std::vector<int64_t> epochs_;
  std::vector<ReplaySample> smoothed_samples_;
  std::vector<Eigen::Isometry3d> T_enu_body_smoothed_;
  std::vector<fusion::GpsFix> fixes_;  // every fix fed to the filter
  std::vector<int64_t> frame_index_, t_ns_;
  std::vector<Eigen::Isometry3d> T_enu_body_;
  std::vector<Eigen::Isometry3d> vo_motion_;  // raw VO (body axes) per pose, identity when lost
  std::vector<PlotExtras> extras_;            // p_enu_vo_m filled at the end
  std::vector<VoErrorPair> vo_pairs_;         // VO vs ground truth (noise calibration)
  int lost_frames_ = 0;
  std::map<std::string, int> mode_counts_, vo_health_counts_;  // poses per mode / VO health
  int rejection_run_ = 0, rejection_run_v_ = 0, max_rejection_run_ = 0, max_rejection_run_v_ = 0;
  double vo_ms_total_ = 0;
  FrameResult last_;
};

}  // namespace locaid::pipeline
