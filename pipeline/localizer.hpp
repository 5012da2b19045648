// Per-frame localizer: stereo VO + scenario-degraded GPS (+ IMU) -> EKF ->
// FusedPose. The estimator the frame loop (frame_loop.hpp) runs for
// locaid-replay and for every session of the gRPC server.
//
// What reaches the filter: OXTS accelerations / angular rates (as IMU,
// optionally degraded to MEMS grade) and the GPS fix degraded by the scenario.
// OXTS attitude, velocity and the raw position never do.
//
// Threading: Process / FuseSensors / Reset must be called from one thread
// (the session's). The outage controls and SetScenario may be called from any
// thread; they take effect at the next Process / Fuse.
#pragma once

#include "core/stereo_camera.hpp"
#include "fusion/ekf.hpp"
#include "fusion/scenario.hpp"
#include "fusion/types.hpp"
#include "kitti/types.hpp"
#include "vo/stereo_odometry.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace locaid::pipeline {

struct LocalizerOptions {
  std::string vo_method = "default";  // vo::MakeStereoOdometry method
  fusion::EkfConfig ekf;               // ekf.use_imu false: VO + GPS only (the filter ignores IMU)
};

// One degraded fix produced during a frame, and what the gate did with it.
struct GpsFeed {
  fusion::GpsFix fix;
  Eigen::Vector3d p_enu_m = Eigen::Vector3d::Zero();  // fix in the filter's ENU (valid once has_origin)
  bool accepted = false;   // used by the filter
  bool rejected = false;   // horizontal part refused by the chi-square gate (false while buffered for init)
  bool rejected_vertical = false;  // vertical part refused by its gate
  double nis = 0, gate = 0;        // horizontal NIS (2 dof) and its gate; 0 before the filter runs
};

// Sensor data that arrived since the previous call, each list in time order.
struct SensorBatch {
  std::vector<kitti::OxtsSample> oxts;  // IMU part used as IMU, position degraded by the scenario
  std::vector<fusion::ImuSample> imu;   // measured IMU samples (typed input): used as they are
  std::vector<fusion::GpsFix> gps;      // measured fixes: scenario outages apply, its noise does not
  // The receiver's latest state when it reported one: false after a no-fix
  // report (an outage until a fix comes), true after a fix.
  std::optional<bool> receiver_has_fix;
  bool empty() const { return oxts.empty() && imu.empty() && gps.empty() && !receiver_has_fix; }
};

struct FrameResult {
  fusion::FusedPose pose;             // fused pose at the frame time
  vo::RelativeMotion vo;              // raw VO output (cam0 axes)
  fusion::VoMeasurement vo_body;      // VO converted to body (imu) axes
  std::vector<GpsFeed> gps_feeds;     // every fix fed this frame
  bool in_outage = false;             // GPS outage (scheduled or run-time) at the frame time
  double vo_ms = 0, fusion_ms = 0;    // wall time of the two stages
};

// What the frame loop drives, one frame (or batch of sensor data) at a time.
// Localizer is the one the service and locaid-replay run; tests and
// benchmarks plug in their own.
class Estimator {
 public:
  virtual ~Estimator() = default;
  // VO + fusion of one frame. oxts_since_last_frame: the OXTS samples with
  // t_prev_frame < t_ns <= frame.t_ns, in time order (may be empty).
  virtual FrameResult Process(const vo::StereoFrame& frame,
                              std::span<const kitti::OxtsSample> oxts_since_last_frame) = 0;
  // Sensor data between frames (live input), fused now in time order; the
  // result has no pose, only the GPS feeds and IMU count.
  virtual FrameResult FuseSensors(const SensorBatch& batch) = 0;
  // Run-time outages, absolute times on the frame clock.
  virtual void ScheduleOutage(int64_t start_ns, int64_t end_ns) = 0;
  virtual void StartOutageNow() = 0;
  virtual void StopOutage() = 0;
  // Replaces the degradation scenario (new seed/noise; keeps the filter state
  // and the run-time outages). Throws std::invalid_argument if invalid.
  virtual void SetScenario(fusion::Scenario scenario) = 0;
  // The filter's ENU frame: origin at the first degraded fix once it has one.
  virtual const fusion::EnuFrame& enu() const = 0;
};

class Localizer final : public Estimator {
 public:
  // T_cam0_imu: cam0 <- imu extrinsic (StereoDataset::T_cam0_imu()).
  // Throws std::invalid_argument for an unknown VO method or a bad scenario.
  Localizer(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu,
            fusion::Scenario scenario, LocalizerOptions options = {});
  // With the given odometry instead of options.vo_method's (e.g. recorded
  // VO results replayed).
  Localizer(const Eigen::Isometry3d& T_cam0_imu, fusion::Scenario scenario, LocalizerOptions options,
            std::unique_ptr<vo::StereoOdometry> odometry);
  ~Localizer() override;

  FrameResult Process(const vo::StereoFrame& frame,
                      std::span<const kitti::OxtsSample> oxts_since_last_frame) override;
  FrameResult FuseSensors(const SensorBatch& batch) override;
  void ScheduleOutage(int64_t start_ns, int64_t end_ns) override;
  void StartOutageNow() override;
  void StopOutage() override;
  void SetScenario(fusion::Scenario scenario) override;
  const fusion::EnuFrame& enu() const override { return ekf_->enu(); }
  const fusion::Ekf& ekf() const { return *ekf_; }

 private:
  // Starts the filter, VO and degradation afresh (run-time outages kept).
  void Reset();
  vo::RelativeMotion TrackVo(const vo::StereoFrame& frame);
  FrameResult Fuse(const vo::RelativeMotion& vo_cam, const SensorBatch& since_last_frame);
  void ApplyPendingControls();
  void FeedSensors(const SensorBatch& batch, FrameResult& r);
  void FeedGps(const fusion::GpsFix& fix, FrameResult& r);
  bool receiver_has_fix_ = true;

  Eigen::Isometry3d T_cam0_imu_;
  LocalizerOptions options_;
  std::unique_ptr<vo::StereoOdometry> vo_;
  std::unique_ptr<fusion::Ekf> ekf_;
  std::unique_ptr<fusion::GpsScenario> gps_;
  std::unique_ptr<fusion::ImuDegrader> imu_;
  std::optional<int64_t> last_frame_ns_;

  // Controls written from other threads, applied at the next frame.
  mutable std::mutex control_mutex_;
  fusion::Scenario scenario_;
  std::optional<fusion::Scenario> pending_scenario_;
  std::vector<std::pair<int64_t, int64_t>> pending_outages_;
  std::vector<std::pair<int64_t, int64_t>> all_outages_;
  std::optional<bool> pending_forced_;
  bool forced_ = false;
};

}  // namespace locaid::pipeline
