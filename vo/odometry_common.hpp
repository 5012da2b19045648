// Helpers shared by the VO methods (internal to vo/).
#pragma once

#include "vo/stereo_odometry.hpp"

#include <opencv2/core.hpp>

#include <chrono>
#include <string>

namespace locaid::vo {

// Why a frame cannot be used; empty when it can.
// Checks: non-empty, CV_8UC1 (CV_8UC3 is accepted and converted by the caller),
// the camera's size, and an intensity standard deviation >= min_stddev (black,
// saturated and flat images fail it). Sampled on a sparse grid to stay cheap.
std::string ImageProblem(const cv::Mat& image, const kitti::StereoCamera& camera,
                         double min_stddev);

// Grey CV_8UC1 view of `image` (converts colour).
cv::Mat ToGrey(const cv::Mat& image);

// Identity motion with a large covariance and the given status.
RelativeMotion NoMotion(int64_t t_ns, Status status);

class StageTimer {
 public:
  explicit StageTimer(StageTimings& timings) : timings_(timings) { Restart(); }
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  // Records the time since the last Stop/Restart under `name`.
  void Stop(const char* name) {
    const auto now = std::chrono::steady_clock::now();
    timings_.emplace_back(name, std::chrono::duration<double, std::milli>(now - start_).count());
    start_ = now;
  }

 private:
  StageTimings& timings_;
  std::chrono::steady_clock::time_point start_;
};

double SumTimings(const StageTimings& timings);

}  // namespace locaid::vo
