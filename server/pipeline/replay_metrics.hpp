// Accuracy metrics of a replay against the untouched OXTS ground truth.
#pragma once

#include "fusion/types.hpp"

#include <Eigen/Core>

#include <vector>

namespace locaid::pipeline {

struct ReplaySample {
  double t_s = 0;                                      // since the first frame
  Eigen::Vector3d p_enu_gt_m = Eigen::Vector3d::Zero();  // body (imu) position, ground truth
  Eigen::Vector3d p_enu_est_m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P_pos_m2 = Eigen::Matrix3d::Identity();  // position covariance
  fusion::Mode mode = fusion::Mode::kLost;
  bool initialized = false;  // filter initialised (pose valid)
  bool in_outage = false;
};

struct OutageStats {
  double start_s = 0, duration_s = 0;
  double distance_m = 0;     // ground-truth path length inside the outage
  double end_error_m = 0;    // horizontal error at the last frame of the outage
  double end_error_pct = 0;  // end_error_m / distance_m * 100
  double max_error_m = 0;    // max horizontal error inside the outage
  double reconverge_s = -1;  // after the outage until the error <= 2 sigma_h GPS (-1: never)
  double max_jump_m = 0;     // largest frame-to-frame pose correction in the 10 s after it
};

struct ReplayMetrics {
  int frames = 0;
  double rmse_gps_m = 0;    // horizontal RMSE over frames with GPS in use (not in outage)
  double nees_mean = 0;     // mean 3-dof position NEES over initialised frames
  int nees_frames = 0;
  std::vector<OutageStats> outages;
};

// gps_sigma_h_m: the scenario's horizontal noise (reconvergence threshold 2 sigma).
ReplayMetrics ComputeReplayMetrics(const std::vector<ReplaySample>& samples, double gps_sigma_h_m);

}  // namespace locaid::pipeline
