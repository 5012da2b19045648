// What a session runs: "give me the next fused pose". Implementations adapt a
// frame source (KITTI dataset, synthetic drive, frames pushed by a client)
// and the Localizer (VO -> EKF). Tests and benchmarks plug in their own.
//
// Threading: every method is called from the session thread only, except
// Cancel(), which may be called from any thread to unblock Step().
#pragma once

#include "fusion/scenario.hpp"
#include "fusion/types.hpp"
#include "vo/stereo_odometry.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace locaid::server {

// Counters of a live session's typed input and GPS receiver (all zero for
// file sources).
struct LiveInputStats {
  uint64_t imu_samples = 0, gps_fixes_in = 0, gps_fixes_late = 0, gps_no_fix = 0;
  uint64_t sensor_rejected = 0;  // typed items refused (out of order); last_error says why
  std::string last_error;
  bool has_gpsd = false, gpsd_connected = false;
  uint64_t gpsd_connects = 0, gpsd_losses = 0;
  std::string gpsd_error;
  double fix_latency_median_ms = 0, fix_latency_max_ms = 0;
};

// A GPS fix the filter received, and what its gate did with it.
struct FixSeen {
  fusion::GpsFix fix;
  bool used = false, rejected_vertical = false;
  double nis = 0, gate = 0;
};

// Ground truth at a pose's time (dataset sources).
struct TruthPose {
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  std::optional<Eigen::Isometry3d> T_enu_body;  // once the filter's ENU origin is known
};

struct StepResult {
  enum class Kind {
    kPose,     // `pose` is valid
    kSkipped,  // frame without both images: skipped (error says which)
    kCorrupt,  // frame could not be decoded / wrong size: skipped
    kIdle,     // nothing available yet (live input): call again
    kEnd,      // input exhausted
    kFused,    // sensor data between frames fused (live input): no pose
  };
  Kind kind = Kind::kIdle;
  int64_t frame_index = -1;
  int64_t t_ns = 0;  // sensor time of the frame (also for skipped frames)
  fusion::FusedPose pose;
  int vo_inliers = 0;
  vo::Status vo_status = vo::Status::kLost;
  bool gps_outage_active = false;
  std::vector<FixSeen> gps_fixes;     // received since the previous pose
  std::optional<TruthPose> truth;
  int oxts_bad_lines = 0;  // bad OXTS records met while producing this result
  std::string error;       // kSkipped / kCorrupt / bad OXTS: file and reason
  // Wall time spent on this frame (decode, VO, EKF), ms. < 0: the session
  // measures the duration of Step() instead (right for file sources).
  double processing_ms = -1;
};

class SessionPipeline {
 public:
  virtual ~SessionPipeline() = default;
  virtual StepResult Step() = 0;
  // Unblocks a Step() waiting for input (live sessions); Step then returns
  // kEnd. Thread-safe.
  virtual void Cancel() {}
  // Makes a Step() that waits for input return kIdle soon, so commands
  // posted to the session apply before the next frame. Thread-safe.
  virtual void Wake() {}
  // Frames in the input, 0 when unknown (live).
  virtual int64_t total_frames() const { return 0; }
  // False while the input is still being prepared (a synthetic drive
  // rendering): the session is STARTING until then. Any thread.
  virtual bool ready() const { return true; }
  // The session's thread is done with the pipeline: free what it holds
  // (files, images). Called once, from the session thread, as it ends.
  virtual void Release() {}
  // GPS control, applied from the next frame on. Sensor times are relative to
  // the first frame of the session.
  virtual void StartOutageNow(double duration_s) = 0;  // 0 = until StopOutage
  virtual void StopOutage() = 0;
  virtual void AddOutageWindow(double start_s, double duration_s) = 0;
  // Throws std::invalid_argument when the scenario is invalid.
  virtual void SetScenario(const fusion::Scenario& scenario) = 0;
  // ENU origin once known.
  virtual bool origin(double* lat_deg, double* lon_deg, double* alt_m) const = 0;
  // Typed live input and GPS receiver counters. Any thread.
  virtual LiveInputStats input_stats() const { return {}; }
};

}  // namespace locaid::server
