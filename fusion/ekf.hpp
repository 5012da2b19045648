// Error-state EKF: GPS position updates with a chi-square gate over one of
// two process models (fusion/process_model.hpp), chosen once from
// EkfConfig imu.enabled: IMU propagation with VO relative-motion updates, vehicle
// speed readings and the car's motion constraints, or VO-driven propagation
// for cars without an IMU. Single-threaded, no I/O.
//
// Call order per camera frame (the pipeline does this):
//   for each IMU sample / GPS fix / speed reading since the last frame, in time order:
//     PropagateImu(sample)  |  UpdateGps(fix)  |  UpdateSpeed(reading)
//   ProcessVo(body_motion, vo_ok)    // VO update (IMU) or propagation (no IMU),
//                                    // then the vehicle constraints (IMU)
//   Output(t_ns, vo_ok)
// Before the filter is initialised, GPS fixes and VO motions are buffered:
// the pose is initialised from >= startup.min_fixes fixes spanning
// startup.min_baseline_m, heading from the motion between the fixes (aligned to
// the VO track), never from an external attitude.
#pragma once

#include "fusion/ekf_config.hpp"
#include "fusion/ekf_models.hpp"
#include "fusion/geodesy.hpp"
#include "fusion/imu_stillness.hpp"
#include "fusion/noise_scale.hpp"
#include "fusion/process_model.hpp"
#include "fusion/types.hpp"

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <vector>

namespace locaid::fusion {

// What UpdateGps did with one fix.
struct GpsUpdate {
  bool used = false;               // horizontal part fused (also by a reset)
  bool rejected = false;           // horizontal part refused: by the gate, or the fix is not usable
  bool rejected_vertical = false;  // vertical part refused by its gate (the horizontal may be used)
  bool buffered = false;           // kept for the start-up fit (filter not initialised yet)
  bool reset = false;              // position reset to this fix after a run of rejections
  double nis = 0, nis_vertical = 0;  // normalised innovations squared (2 dof, 1 dof); 0 when not gated
  double gate = 0;                   // the horizontal gate (2 dof); 0 before the filter runs
};

// What ProcessVo did with one motion.
struct VoUpdate {
  bool used = false;             // fused (IMU) or propagated on (no IMU)
  bool rejected = false;         // refused by the gate, or not finite
  bool anchor_mismatch = false;  // did not start at the filter's anchor: skipped
  double nis = 0;                // 0 when not gated
};

// What UpdateSpeed did with one reading.
struct SpeedUpdate {
  bool used = false;      // fused
  bool rejected = false;  // refused: gate, non-finite, or the filter has no velocity state
  bool zupt = false;      // a standstill reading: the whole velocity fused as 0
  double nis = 0;
};

// The filter's running counts, one struct.
struct EkfStats {
  int gps_used = 0, gps_rejected = 0;  // a fix counts as used when its horizontal part is fused
  int gps_rejected_vertical = 0;       // fixes whose vertical part the gate refused
  int gps_resets = 0;                  // position resets to GPS after a run of rejections
  int gps_velocity_used = 0, gps_velocity_rejected = 0;  // GPS velocities (3 dof, IMU mode only)
  int vo_rejected = 0;                 // gated out, or non-finite
  int imu_rejected = 0;                // non-finite samples refused
  // VO motions that did not start at the filter's anchor (VO restarted on a
  // frame it reported lost): skipped, the anchor moves on.
  int vo_anchor_mismatches = 0;
  int speed_used = 0, speed_rejected = 0;  // vehicle speed readings
  int zupt_updates = 0;                    // zero-velocity updates (speed 0 or IMU still)
  int nhc_updates = 0;                     // frames with the non-holonomic constraints fused
  double last_gps_nis = 0, last_gps_nis_vertical = 0, last_vo_nis = 0;
};

class Ekf {
 public:
  explicit Ekf(EkfConfig config = {});

  // The filter's VO noise (body axes, [dt, dtheta]) for one motion: the VO's
  // reported covariance scaled by vo.cov_scale, plus (vo.sigma_t_per_m * |t|)^2
  // on each translation axis (IMU mode), floored at vo.min_sigma_t_m /
  // vo.min_sigma_rot_rad. locaid-replay scores real VO errors against it
  // ("vo_error": nees6_mean_model).
  Mat6 VoNoise(const Mat6& reported, const Eigen::Isometry3d& motion) const;

  void PropagateImu(const ImuSample& sample);
  // Fuses one fix (its horizontal and vertical parts gated apart) and says
  // what it did. Before initialisation fixes are buffered. A fix older than
  // the state (IMU mode) is compared with the antenna's position at the fix
  // time; its velocity, when given, is fused too (IMU mode). Non-finite values
  // or a covariance that is not positive definite: refused (rejected).
  GpsUpdate UpdateGps(const GpsFix& fix);
  // body_motion: VO relative motion in body axes (CameraMotionToBody).
  // vo_ok false (VO lost): skip the update (IMU) or coast (no IMU).
  VoUpdate ProcessVo(const VoMeasurement& body_motion, bool vo_ok);
  // Fuses one vehicle speed reading (IMU mode; the scale factor is estimated).
  // Before initialisation: ignored (neither used nor refused). Without IMU,
  // non-finite, or beyond the gate: refused. A reading below vehicle.zupt_speed_mps
  // is a standstill (vehicle.constraints): the whole velocity is fused as 0.
  SpeedUpdate UpdateSpeed(const SpeedSample& reading);
  FusedPose Output(int64_t t_ns, bool vo_ok) const;
  // Whether the vehicle surely moves faster than speed_mps at t_ns: a speed
  // reading at most 0.5 s old says so, or, without one, the filter's own
  // speed (IMU mode, initialised) exceeds it by 3 sigma along its direction.
  // What VO reporting a standstill is checked against (a frozen camera whose
  // repeated frames still differ).
  bool SurelyMovingFasterThan(int64_t t_ns, double speed_mps) const;

  const EkfConfig& config() const { return config_; }
  // Smoothing (fusion/epoch_log.hpp, rts_smoother.hpp): the log that records
  // this filter's epochs (nullptr: none, the default), the epoch that holds
  // the state now (call after Output; -1 before the filter runs or without a
  // log), and where the shown states sit in the error state.
  void set_epoch_log(EpochLog* log) { s_.log = log; }
  int64_t MarkEpoch() { return s_.log ? s_.log->Mark(s_) : -1; }
  ErrorLayout error_layout() const;
  bool initialized() const { return s_.initialized; }
  const EnuFrame& enu() const { return enu_; }
  const NominalState& state() const { return s_.x; }
  const Eigen::MatrixXd& covariance() const { return s_.P; }
  const EkfStats& stats() const { return stats_; }
  // Estimated VO calibration (IMU mode; identity / 0 otherwise).
  const Mat3& vo_boresight() const { return model_->vo_boresight(); }
  double vo_scale_error() const { return model_->vo_scale_error(); }
  // Estimated speed sensor scale error (IMU mode; 0 otherwise).
  double speed_scale_error() const { return model_->speed_scale_error(); }
  // Noise scales (vo.learn_noise / vo.adaptive_rotation_noise /
  // gps.learn_noise; 1 where fixed): VO per body axis [dt x, y, z, dtheta x,
  // y, z] (the rotation axes' from whichever model has them), GPS horizontal
  // / vertical.
  const Vec6& vo_noise_scale() const { return model_->vo_noise_scale(); }
  double gps_noise_scale_horizontal() const { return gps_noise_h_.scale(0); }
  double gps_noise_scale_vertical() const { return gps_noise_v_.scale(0); }
  // Whether the VO noise is being learnt now: GPS holds the state (else frozen).
  bool LearningVoNoise(int64_t t_ns) const;
  double gps_period_s() const { return gps_period_s_; }
  double gps_gate() const { return gate_h_; }  // horizontal (2 dof)
  double gps_gate_vertical() const { return gate_v_; }

 private:
  // GPS (ekf_gps.cpp).
  struct GpsModel {   // the antenna's predicted position and the update's matrices
    Vec3 predicted;
    Mat3 R;       // the fix's covariance with the learned scale
    Mat3 R_stated;  // as the fix states it
    Eigen::MatrixXd H;
    double late_s = 0;  // how much older than the state the fix is
  };
  struct GpsGateResult {
    double nis_h = 0, nis_v = 0;
    bool h_ok = false, v_ok = false;
    Vec3 predicted_var = Vec3::Zero();  // diagonal of H P H' (the prediction's part of S)
  };
  static bool GpsFixUsable(const GpsFix& fix);
  GpsUpdate RefuseGps(const GpsFix& fix);
  Vec3 GpsEnu(const GpsFix& fix);
  void TrackGpsPeriod(int64_t t_ns);
  void TrackGpsLag(int64_t t_ns);
  GpsModel PredictGps(const GpsFix& fix) const;
  GpsGateResult GateGps(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H) const;
  GpsUpdate GateAndFuse(const GpsFix& fix, const Vec3& y, const GpsModel& m);
  void LearnGpsNoise(const Vec3& y, const GpsModel& m, const GpsGateResult& gate, bool has_altitude);
  GpsUpdate CountGpsOutcome(const GpsFix& fix, const GpsGateResult& gate, bool use_h, bool use_v, bool reset);
  void FuseGpsVelocity(const GpsFix& fix, double late_s);
  void ResetPositionToGps(const Vec3& y, const Mat3& R, bool horizontal, bool vertical);
  void ApplyGpsUpdate(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H, bool horizontal, bool vertical);
  // VO (ekf.cpp).
  struct VoPlan {  // one motion, relative to the filter's anchor
    bool vo_ok = false, reanchor = false;
    Eigen::Isometry3d motion, step;  // from the anchor (or coasted), and from the last frame
    double dt_s = 0, frame_dt_s = 0;
    int64_t prev_frame_ns = 0;
  };
  VoPlan PlanVo(const VoMeasurement& m, bool vo_ok, VoUpdate& out);
  void ChainStartup(const VoMeasurement& m, const VoPlan& plan);
  VoUpdate ApplyVoUpdate(const VoMeasurement& m, const VoPlan& plan, VoUpdate out);
  // Vehicle (ekf_vehicle.cpp): the constraints at a frame, and whether the car stands still.
  void ApplyVehicleConstraints(int64_t t_ns, bool vo_ok);
  bool VehicleConstraintsActive(bool vo_ok) const;
  bool Standstill(int64_t t_ns) const;
  // The newest speed reading when it is at most max_age_s older than t_ns.
  std::optional<double> FreshSpeedReading(int64_t t_ns, double max_age_s) const;
  // Start-up (ekf_init.cpp).
  struct InitFix { int64_t t_ns; Vec3 p_enu; double sigma_h, sigma_v; Eigen::Isometry3d T_start_body; };
  struct HeadingFit {
    double psi = 0;
    Eigen::Vector2d p_mean, q_mean;
    double z_off = 0, spread2 = 0;
    int used = 0;
    double residual_var = 0, residual_var_v = 0;  // horizontal per axis, vertical, of the fixes used (m^2)
  };
  void TryInitialize(int64_t t_ns);
  std::vector<const InitFix*> ChainedInitFixes() const;
  bool InitBaselineReached(const std::vector<const InitFix*>& fixes, double min_baseline) const;
  static HeadingFit FitHeading(const std::vector<const InitFix*>& fixes, const Mat3& R_level_start, double sigma_h);
  void InitializeState(const HeadingFit& fit, const Mat3& R_level_start, double tilt_var, double sigma_h);

  EkfConfig config_;
  std::unique_ptr<ProcessModel> model_;  // chosen once from config_.imu.enabled
  EnuFrame enu_;
  FilterState s_;
  EkfStats stats_;
  Vec3 last_vo_velocity_body_mps_ = Vec3::Zero();
  // VO anchor: the frame the next VO motion starts from (the clone's time with
  // IMU), and the motion coasted since it while VO was lost.
  std::optional<int64_t> vo_anchor_ns_, last_frame_ns_;
  Eigen::Isometry3d T_coast_ = Eigen::Isometry3d::Identity();
  // Initialisation buffers: VO-chained body poses and fixes.
  std::vector<InitFix> init_fixes_;
  Eigen::Isometry3d T_start_body_ = Eigen::Isometry3d::Identity();
  // GPS bookkeeping.
  double gate_h_ = 0, gate_v_ = 0;
  int rejections_h_ = 0, rejections_v_ = 0;  // in a row, per component
  std::optional<int64_t> last_gps_accepted_ns_, last_gps_rejected_ns_, last_gps_received_ns_;
  std::optional<int64_t> last_imu_ns_;  // newest IMU sample the model took
  ImuStillness stillness_;
  double zupt_gate_ = 0;                  // chi-square (3 dof) of a standstill speed reading
  std::optional<int64_t> last_speed_ns_;  // newest speed reading taken
  double last_speed_mps_ = 0;             // and its value
  // gps.learn_noise: horizontal (E and N: two samples per fix), vertical.
  NoiseScaleEstimator gps_noise_h_, gps_noise_v_;
  double gps_period_s_ = 1.0;
  double gps_lag_s_ = 0;  // how late fixes reach the filter after their frames (recent worst), s
};

}  // namespace locaid::fusion
