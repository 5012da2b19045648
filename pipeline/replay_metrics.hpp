// Accuracy metrics of a replay against the untouched OXTS ground truth.
#pragma once

#include "fusion/types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace locaid::pipeline {

struct ReplaySample {
  double t_s = 0;                                      // since the first frame
  Eigen::Vector3d p_enu_gt_m = Eigen::Vector3d::Zero();  // body (imu) position, ground truth
  Eigen::Vector3d p_enu_est_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P_pos_m2 = Eigen::Matrix3d::Identity();  // position covariance
  fusion::Mode mode = fusion::Mode::kLost;
  bool initialized = false;  // filter initialised (pose valid)
  bool has_gt = true;        // p_enu_gt_m known (false: frame left out of every metric)
  bool in_outage = false;
};

struct OutageStats {
  double start_s = 0, duration_s = 0;
  double distance_m = 0;     // ground-truth path length inside the outage
  double end_error_m = 0;    // horizontal error at the last frame of the outage
  double end_error_pct = 0;  // end_error_m / distance_m * 100
  // The horizontal error when GPS went (last frame before the outage), and
  // what the outage added: |error vector at its end - error vector at its
  // start| (NaN when either frame has no ground truth).
  double start_error_m = std::nan(""), added_error_m = std::nan(""), added_error_pct = std::nan("");
  double max_error_m = 0;    // max horizontal error inside the outage
  double rmse_m = 0;         // horizontal RMSE over the outage's frames (NaN without ground truth)
  double reconverge_s = -1;  // after the outage until the error <= 2 sigma_h GPS (-1: never)
  double max_jump_m = 0;     // largest frame-to-frame pose correction in the 10 s after it
};

struct ReplayMetrics {
  int frames = 0;
  double rmse_gps_m = 0;    // horizontal RMSE over frames with GPS in use (not in outage)
  double nees_mean = 0;     // mean 3-dof position NEES over initialised frames
  int nees_frames = 0;
  // 99 % bound of nees_mean for a consistent filter with independent errors:
  // chi2_0.99(3 n) / n over the n NEES frames.
  double nees_bound_99 = 0;
  // The same from 30 s after the first initialised frame on (a filter that
  // learns its noise has had time to), and its bound; NaN / 0 without frames.
  double nees_mean_after_30s = 0, nees_bound_99_after_30s = 0;
  int nees_frames_after_30s = 0;
  double max_vertical_error_m = 0;  // over initialised frames with ground truth
  std::vector<OutageStats> outages;
};

// VO relative-motion error against ground truth, used to calibrate the filter's
// VO noise model (EkfConfig vo.cov_scale / vo.min_sigma_*). Error of a frame:
// E = T_gt^-1 * T_vo (right perturbation in body axes of the current frame),
// d = [E.translation(), Log(E.rotation())].
struct VoErrorPair {
  Eigen::Isometry3d T_prev_curr_vo = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_prev_curr_gt = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();  // as reported
  // fusion::Ekf::VoNoise: the noise the filter used (model x learned scale).
  Eigen::Matrix<double, 6, 6> model_covariance = Eigen::Matrix<double, 6, 6>::Identity();
  bool in_outage = false;  // a GPS outage frame (the learned scale is frozen)
};

struct VoErrorStats {
  int frames = 0;
  Eigen::Matrix<double, 6, 1> rms_error = Eigen::Matrix<double, 6, 1>::Zero();   // per axis (m, rad)
  Eigen::Matrix<double, 6, 1> rms_sigma = Eigen::Matrix<double, 6, 1>::Zero();   // reported, per axis
  double nees_mean = 0;         // mean d^T C^-1 d with the reported C (6 dof: 6 if consistent)
  double nees_median = 0;
  double nees_mean_model = 0;   // the same with the filter's noise model (model_covariance)
  double nees_median_model = 0;
  // nees_mean_model apart for GPS outage frames (in_outage) and the others
  // (GPS good: the learned scale is learning); 0 without such frames.
  int frames_in_outage = 0;
  double nees_mean_model_in_outage = 0, nees_mean_model_gps_good = 0;
  Eigen::Matrix<double, 6, 1> rms_model_sigma = Eigen::Matrix<double, 6, 1>::Zero();
};

VoErrorStats ComputeVoErrorStats(const std::vector<VoErrorPair>& pairs);

// gps_sigma_h_m: the scenario's horizontal noise (reconvergence threshold 2 sigma).
ReplayMetrics ComputeReplayMetrics(const std::vector<ReplaySample>& samples, double gps_sigma_h_m);

// The metrics as lines a person reads (locaid-replay, locaid-score): a value
// that could not be computed says why instead of "nan" / "-1", e.g.
// "horizontal RMSE while GPS used: n/a (no frame had GPS in use with the
// filter initialised)", "did not reconverge before the drive ended".
std::string DescribeMetrics(const ReplayMetrics& m);

// Per-frame columns that locaid-replay knows and a recorded pose stream does
// not (they stay empty in the CSV when absent).
struct PlotExtras {
  std::optional<Eigen::Vector3d> p_enu_gps_m;  // degraded fix fed this frame
  bool gps_rejected = false;
  std::optional<Eigen::Vector3d> p_enu_vo_m;   // raw VO chained in ENU
  std::optional<Eigen::Vector3d> p_enu_gt_at_gps_m;  // ground truth at the fix's own time
  std::string vo_health;                             // vo::ToString(Health) of the frame
};

// Writes the per-frame CSV that clients/plot_outage.py reads. `extras` is
// either empty or one entry per sample. Throws std::runtime_error when the
// file cannot be written.
void WritePlotCsv(const std::string& path, const std::vector<ReplaySample>& samples,
                  const std::vector<PlotExtras>& extras = {});

}  // namespace locaid::pipeline
