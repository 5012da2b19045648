// Is the IMU still? Over a sliding window of its samples, the angular rate and
// the specific force stay within a band around their means (a standing car:
// only sensor noise and engine vibration). Bounded: the window holds at most
// kMaxSamples samples.
#pragma once

#include "fusion/types.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <deque>

namespace locaid::fusion {

struct StillnessThresholds {
  double window_s = 0.5;
  double gyro_radps = 0.01;   // max |w - mean w| in the window
  double accel_mps2 = 0.1;    // max |f - mean f| in the window
  int min_samples = 10;
};

class ImuStillness {
 public:
  static constexpr size_t kMaxSamples = 4096;

  // Samples in time order; older ones than the window are dropped.
  void Add(const ImuSample& sample, double window_s);
  // Whether the samples of the window ending at the newest one are still.
  bool Still(const StillnessThresholds& t) const;

 private:
  std::deque<ImuSample> window_;
};

}  // namespace locaid::fusion
