// Per-frame localizer: stereo VO + typed measurements (IMU, GPS fixes) -> EKF
// -> FusedPose. The estimator the frame loop (frame_loop.hpp) runs for
// locaid-replay and for every session of the gRPC server, after the scenario
// stage (scenario_stage.hpp) has made the measurements: it knows nothing of
// recorded drives, scenarios or outages.
//
// Threading: one thread (the frame loop's stepping thread).
#pragma once

#include "core/stereo_camera.hpp"
#include "fusion/ekf.hpp"
#include "sim/scenario.hpp"
#include "fusion/types.hpp"
#include "pipeline/samples.hpp"
#include "vo/stereo_odometry.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace locaid::pipeline {

struct LocalizerOptions {
  std::string vo_method = "default";  // vo::MakeStereoOdometry method; "none": no VO
  fusion::EkfConfig ekf;               // ekf.imu.enabled false: VO + GPS only (the filter ignores IMU)
};

// The filter's noise for a scenario that simulates a worse IMU than the
// recorded one (ImuGrade::kMems): the filter must know the IMU is worse.
fusion::EkfConfig EkfConfigForScenario(fusion::EkfConfig config, const sim::Scenario& scenario);

// One fix fed to the filter, and what the filter did with it.
struct GpsFeed {
  fusion::GpsFix fix;
  Eigen::Vector3d p_enu_m = Eigen::Vector3d::Zero();  // fix in the filter's ENU (valid once it has an origin)
  fusion::GpsUpdate update;
};

struct FrameResult {
  fusion::FusedPose pose;             // fused pose at the frame time
  vo::RelativeMotion vo;              // raw VO output (cam0 axes)
  fusion::VoMeasurement vo_body;      // VO converted to body (imu) axes
  fusion::VoUpdate vo_update;         // what the filter did with it
  std::vector<GpsFeed> gps_feeds;     // every fix fused since the previous pose
  bool in_outage = false;             // GPS out at the frame time (the frame loop sets it)
  double vo_ms = 0, fusion_ms = 0;    // wall time of VO, and of fusion since the previous pose
  // The filter epoch that holds this pose (fusion/epoch_log.hpp) when the
  // estimator records epochs for a smoother; -1 otherwise.
  int64_t epoch = -1;
};

// What the frame loop drives. Localizer is the one the service and
// locaid-replay run; tests and benchmarks plug in their own.
class Estimator {
 public:
  virtual ~Estimator() = default;
  // Fuses measurements now: IMU samples and fixes merged in time order (at
  // equal times the IMU sample first, so a fix meets the state propagated to
  // its time). What happened to each fix comes with the next pose.
  virtual void Fuse(const Measurements& measurements) = 0;
  // VO on the frame and the fused pose at its time.
  virtual FrameResult Process(const vo::StereoFrame& frame) = 0;
  // The filter's ENU frame: origin at the first fix once it has one.
  virtual const fusion::EnuFrame& enu() const = 0;
};

class Localizer final : public Estimator {
 public:
  // T_cam0_imu: cam0 <- imu extrinsic (the source's). Throws
  // std::invalid_argument for an unknown VO method.
  Localizer(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu, LocalizerOptions options = {});
  // With the given odometry instead of options.vo_method's (e.g. recorded
  // VO results replayed; nullptr: no VO).
  Localizer(const Eigen::Isometry3d& T_cam0_imu, LocalizerOptions options,
            std::unique_ptr<vo::StereoOdometry> odometry);
  ~Localizer() override;

  void Fuse(const Measurements& measurements) override;
  FrameResult Process(const vo::StereoFrame& frame) override;
  const fusion::EnuFrame& enu() const override { return ekf_.enu(); }
  const fusion::Ekf& ekf() const { return ekf_; }
  // Records the filter's epochs into `log` (nullptr: stop); each result then
  // names its epoch (FrameResult::epoch). `log` must outlive the steps.
  void set_epoch_log(fusion::EpochLog* log) { ekf_.set_epoch_log(log); }

 private:
  vo::RelativeMotion TrackVo(const vo::StereoFrame& frame);
  // VO says the car stands still while the filter (speed reading or IMU)
  // knows it moves: the frame is taken as frozen, not as a standstill.
  bool VoContradictsVehicle(const vo::RelativeMotion& m) const;
  void FeedGps(const fusion::GpsFix& fix);

  Eigen::Isometry3d T_cam0_imu_;
  std::unique_ptr<vo::StereoOdometry> vo_;
  fusion::Ekf ekf_;
  std::optional<int64_t> last_frame_ns_;
  std::vector<GpsFeed> feeds_;  // since the last pose
  double fusion_ms_ = 0;        // since the last pose
};

}  // namespace locaid::pipeline
