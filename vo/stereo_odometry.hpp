// Stereo visual odometry: one rectified stereo pair in, relative motion out.
#pragma once

#include "kitti/types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace locaid::vo {

enum class Status { kOk, kDegraded, kLost };
const char* ToString(Status status);

struct StereoFrame {
  int64_t t_ns = 0;
  cv::Mat left, right;  // rectified CV_8UC1; an empty Mat means "frame missing"
};

// Wall time of each pipeline stage for one frame, in milliseconds, in the
// order the stages ran (e.g. {"detect", 2.1}, {"track", 1.3}, ...).
using StageTimings = std::vector<std::pair<std::string, double>>;

struct RelativeMotion {
  int64_t t_ns = 0;
  // Motion of cam0 between the previous and this frame: p_prev = T_prev_curr * p_curr.
  Eigen::Isometry3d T_prev_curr = Eigen::Isometry3d::Identity();
  // Covariance of the minimal perturbation [dt (m), dtheta (rad)] of
  // T_prev_curr, applied on the right (T * Exp(delta)); in cam0 (curr) axes.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
  int inliers = 0;
  Status status = Status::kLost;
  StageTimings timings;
  double total_ms = 0;  // sum of timings
};

class StereoOdometry {
 public:
  virtual ~StereoOdometry() = default;
  // Never returns NaN; never throws on black, saturated, repeated or missing
  // frames (they come back DEGRADED or LOST with identity motion and a large
  // covariance).
  virtual RelativeMotion Track(const StereoFrame& frame) = 0;
  virtual void Reset() = 0;
};

// Methods: "default" (locaid's design) and "thesis" (baseline). Throws
// std::invalid_argument for an unknown name.
std::unique_ptr<StereoOdometry> MakeStereoOdometry(const std::string& method,
                                                   const kitti::StereoCamera& camera);
std::vector<std::string> StereoOdometryMethods();

}  // namespace locaid::vo
