// Samples: the timed, typed data a source yields besides frames (IMU
// samples, GPS fixes, speed readings, the truth samples of a reference unit),
// the only kind that crosses the pipeline. A source (recorded drive, frames
// and samples a client pushes, gpsd) yields a SampleBatch with each frame or
// between frames; the scenario stage (scenario_stage.hpp) turns it into the
// Measurements the estimator fuses.
//
// A recorded drive's reference unit (KITTI's OXTS: the truth) is never
// fused as such: its IMU and pose go into the truth lists, from which the
// scenario makes the IMU and receiver the filter sees (oxts_adapter.hpp is the
// one place OXTS becomes typed).
#pragma once

#include "fusion/types.hpp"

#include <cstdint>
#include <optional>
#include <vector>

namespace locaid::pipeline {

// A fix with the steady-clock time it reached the server (gpsd), for the
// latency from arrival to use; 0 for pushed and recorded fixes.
struct ArrivedFix {
  fusion::GpsFix fix;
  int64_t arrival_steady_ns = 0;
};

// What the estimator fuses: each list in time order.
struct Measurements {
  std::vector<fusion::ImuSample> imu;
  std::vector<fusion::GpsFix> gps;
  std::vector<fusion::SpeedSample> speed;  // vehicle speed readings
  bool empty() const { return imu.empty() && gps.empty() && speed.empty(); }
};

// What a source delivers with one item, each list in time order.
struct SampleBatch {
  std::vector<fusion::ImuSample> imu;  // measured IMU: fused as it is
  std::vector<ArrivedFix> gps;         // measured fixes: scenario outages apply, its noise does not
  std::vector<fusion::SpeedSample> speed;  // measured vehicle speed: fused as it is
  // The truth: a reference unit's samples (recorded drives); the scenario degrades the
  // IMU to its grade and makes the receiver's fixes from the poses.
  std::vector<fusion::ImuSample> truth_imu;
  std::vector<fusion::TruthSample> truth_poses;
  // The receiver's newest state when it reported one: false after a no-fix
  // report (an outage until a fix comes), true after a fix.
  std::optional<bool> receiver_has_fix;

  bool empty() const {
    return imu.empty() && gps.empty() && speed.empty() && truth_imu.empty() && truth_poses.empty() &&
           !receiver_has_fix;
  }
  // Moves the samples with t_ns <= t_ns of every list into `out` (appended).
  void MoveUpTo(int64_t t_ns, SampleBatch& out);
};

}  // namespace locaid::pipeline
