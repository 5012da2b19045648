// Helpers shared by the VO methods (internal to vo/).
#pragma once

#include "core/stereo_camera.hpp"
#include "vo/stereo_odometry.hpp"

#include <opencv2/core.hpp>

#include <chrono>
#include <string>

namespace locaid::vo {

// Why a frame cannot be used; empty when it can.
// Checks: non-empty, CV_8UC1 (CV_8UC3 is accepted and converted by the caller),
// the camera's size, and an intensity standard deviation >= min_stddev (black,
// saturated and flat images fail it). Sampled on a sparse grid to stay cheap.
std::string ImageProblem(const cv::Mat& image, const StereoCamera& camera,
                         double min_stddev);

// Grey CV_8UC1 view of `image` (converts colour).
cv::Mat ToGrey(const cv::Mat& image);

// Identity motion with a large covariance and the given status.
RelativeMotion NoMotion(int64_t t_ns, Status status);

// Both images present, of the camera's size and not blank/saturated
// (ImageProblem empty for left and right).
bool FrameUsable(const StereoFrame& frame, const StereoCamera& camera, double min_stddev);

// Milliseconds on the given clock (arbitrary origin).
double NowMs(TimingClock clock);

class StageTimer {
 public:
  StageTimer(StageTimings& timings, TimingClock clock) : timings_(timings), clock_(clock) {
    Restart();
  }
  void Restart() { start_ms_ = NowMs(clock_); }
  // Records the time since the last Stop/Restart under `name`.
  void Stop(const char* name) {
    const double now = NowMs(clock_);
    timings_.emplace_back(name, now - start_ms_);
    start_ms_ = now;
  }

 private:
  StageTimings& timings_;
  TimingClock clock_;
  double start_ms_ = 0;
};

double SumTimings(const StageTimings& timings);

}  // namespace locaid::vo
