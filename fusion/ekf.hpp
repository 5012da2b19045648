// Error-state EKF: GPS position updates with a chi-square gate over one of
// two process models (fusion/process_model.hpp), chosen once from
// EkfConfig::use_imu: IMU propagation with VO relative-motion updates, vehicle
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
// the pose is initialised from >= init_min_fixes fixes spanning
// init_min_baseline_m, heading from the motion between the fixes (aligned to
// the VO track), never from an external attitude.
#pragma once

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

struct EkfConfig {
  // The process model: IMU propagation with VO updates (true), or VO-driven
  // propagation without an IMU (false). The one switch between the two;
  // locaid-replay's --no-imu sets it.
  bool use_imu = true;
  double gravity_mps2 = 9.81;
  // IMU noise (continuous densities) and bias random walks.
  double accel_noise_mps2_sqrt_hz = 0.05;
  double gyro_noise_radps_sqrt_hz = 0.001;
  double accel_bias_walk_mps3_sqrt_hz = 0.001;
  double gyro_bias_walk_radps2_sqrt_hz = 1e-5;
  double max_imu_gap_s = 0.5;  // longer IMU gaps: propagate with extra noise
  // Learned measurement noise (fusion/noise_scale.hpp, covariance matching on
  // the filter's own innovations): the VO noise model below is multiplied per
  // axis ([dt x, y, z, dtheta x, y, z], body axes) by a scale learned from the
  // VO innovations against the IMU (IMU mode), only while GPS holds the state
  // (in an outage it would learn its own drift); the fixes' stated covariance
  // by a scale learned per component (horizontal, vertical) from the GPS
  // innovations of the fixes the gate passes, while the prediction is not
  // looser than 4x the fix. The model is the prior (scale 1, worth
  // *_prior_* samples); then an exponential average over about *_window_*
  // samples. false: the fixed model (scale 1).
  // The VO scale does not go below vo_noise_scale_min = 1 by default: VO's
  // frame-to-frame errors are correlated in time (synthetic 2.2 km drive: the
  // along-track error summed over 200 frames is 3.9x what white errors of the
  // same per-frame size give), so noise matched to single frames (scale 0.01
  // to 0.05 there) makes the fused track overconfident: open-sky RMSE 0.29 ->
  // 0.76 m, NEES 2.2 -> 29 (docs/experiments/fusion-learned-noise.md). Upwards it
  // takes a camera worse than the model, and the sparse OXTS records of the
  // real excerpt, whose roll / pitch over a frame the model under-states.
  bool learn_vo_noise = true;
  // Innovation-adaptive VO rotation noise (IMU mode), on top of the learner:
  // when the VO's frame-to-frame rotation disagrees with the IMU's more than
  // their covariances say (running mean of the normalised squared rotation
  // innovation per body axis above 1, from every VO update, outages
  // included), that axis' VO rotation variance is scaled up, at most
  // adaptive_vo_rotation_noise_max_scale times, never below the model; each
  // rotation axis then uses the larger of this scale and the learner's. On
  // real drives the OXTS records predict the roll / pitch over a frame 2-7
  // mrad away from the VO; the adaptation follows that faster than the
  // learner's window and keeps following it in outages, where the learner
  // is frozen. Without it (e3f3fcd to e9b6d2a) the median end-of-outage error
  // of a 10 s outage 20 s into a longer real drive rose from 0.76 to 1.03 %
  // (docs/experiments/vo-rotation-noise.md). false (`locaid-replay
  // --vo-rotation-noise learned`): the learner's scale alone; a max_scale of 1
  // has the same effect. It is part of the learned VO noise: the fixed model
  // (learn_vo_noise false: `--fixed-vo-noise`, NoiseOptions.fixed_vo_noise)
  // has neither; the adaptation alone is vo_noise_scale_max = 1.
  bool adaptive_vo_rotation_noise = true;
  double adaptive_vo_rotation_noise_max_scale = 400.0;
  double vo_noise_prior_frames = 5;
  double vo_noise_window_frames = 300;
  double vo_noise_scale_min = 1.0;
  double vo_noise_scale_max = 400;
  bool learn_gps_noise = true;
  double gps_noise_prior_fixes = 5;
  double gps_noise_window_fixes = 30;
  // The GPS scale stays >= 1 as well: the conservative VO model makes the
  // filter's predicted variance larger than its error, which biases the
  // learned scale low (0.95-0.98 for a receiver stating its true sigma);
  // allowed down to 0.25, the real excerpt's gate refused 8 + 5 of 4,700
  // fixes (nominal 4.7) and the simulator's exactly modelled runs above their
  // NEES bound went from 12.8 to 14.7 %.
  double gps_noise_scale_min = 1.0;
  double gps_noise_scale_max = 100;
  // Initial uncertainty.
  double init_velocity_sigma_mps = 0.5;
  double init_roll_pitch_sigma_rad = 0.03;
  double init_accel_bias_sigma_mps2 = 0.1;
  double init_gyro_bias_sigma_radps = 0.002;
  // Start-up: the filter is declared initialised only once >= init_min_fixes
  // fixes span max(init_min_baseline_m, init_min_baseline_sigmas * sigma_h)
  // (3 fixes over 15 m gave a heading error of ~0.1 rad on 3 m / 1 Hz GPS and a
  // 6 m error lasting 20 s); the initial position / yaw covariance from the
  // Procrustes fit is multiplied by init_cov_inflation (it ignores GPS jumps
  // and the VO drift over the baseline).
  int init_min_fixes = 6;
  double init_min_baseline_m = 15.0;
  double init_min_baseline_sigmas = 10.0;
  double init_cov_inflation = 4.0;
  // VO noise model per frame and axis (body axes x forward, y left, z up; 1-sigma):
  //   sigma_i^2 = vo_cov_scale * reported variance_i + (k_i * |t|)^2 (translation,
  //   IMU mode only; k = vo_sigma_t_per_m along, _lateral_, _vertical_),
  //   then floored at vo_min_sigma_t_m / vo_min_sigma_rot_rad (Ekf::VoNoise).
  // Calibrated with locaid-replay's "vo_error" (VO vs ground truth, after the
  // missing-frame fix of RelativeMotion::t_prev_ns):
  //  - real extract 2011_09_26_drive_unknown_extract (195 frames, ~0.85 m/frame):
  //    RMS error x/y/z 26.2 / 8.3 / 15.1 mm (3.1 / 1.0 / 1.8 % of the motion),
  //    rot 0.64 / 0.73 / 0.32 mrad; reported 1.2 / 1.2 / 1.4 mm, 0.13 / 0.09 /
  //    0.07 mrad (6-dof NEES 3214): the per-metre terms come from here (part of
  //    it is reference error: the extract's OXTS records are sparse).
  //  - synthetic 2.2 km drive (locaid-synth --length-m 2200 --seed 3, 1642
  //    frames, 1.34 m/frame): RMS error 5.1 / 5.3 / 3.2 mm, 0.14 / 0.11 / 0.14
  //    mrad; reported 1.8 / 1.5 / 1.9 mm (NEES 24): about 3x the reported sigma,
  //    hence vo_cov_scale 9. Synthetic images are cleaner than the real camera,
  //    so the model is conservative there (NEES 0.3).
  //  6-dof NEES with this model: real 7.2, synthetic 0.3 (session 14's
  //  isotropic 3 %/m, scale 5: 5.8 / 0.2; its lateral and vertical sigmas were
  //  3x and 1.7x the real errors). It is the prior of learn_vo_noise.
  double vo_cov_scale = 9.0;
  double vo_sigma_t_per_m = 0.03;
  double vo_sigma_lateral_per_m = 0.01;
  double vo_sigma_vertical_per_m = 0.018;
  double vo_min_sigma_t_m = 0.006;
  double vo_min_sigma_rot_rad = 0.0005;
  double vo_gate_probability = 0.9999;  // IMU mode: VO updates beyond are skipped
  // IMU mode: the VO's systematic errors are estimated as random constants
  // (t_m = (1 + s) R_b t_true, fusion/ekf_models.hpp): a boresight R_b of the
  // camera against the body axes (1-sigma per axis) and a scale error s. Real
  // cameras have both (a constant 0.15 deg yaw / 0.30 deg pitch was fitted on
  // the real excerpt, docs/benchmarks.md); while GPS is used they are learnt,
  // during an outage their remaining uncertainty grows the position covariance
  // with the distance driven, as their error grows the position error.
  // 0 pins them (the filter then trusts the VO geometry as exact). The scale
  // state is off by default: on the synthetic urban-canyon drive (1 Hz fixes
  // with multipath jumps) it raised the RMSE from 1.32 to 1.44 m.
  double vo_boresight_sigma_rad = 0.0087;  // 0.5 deg
  double vo_scale_sigma = 0.0;
  double no_imu_lost_sigma_mps = 1.0;   // no-IMU mode: extra velocity noise when VO is lost
  // GPS.
  // Horizontal (2 dof) and vertical (1 dof) innovations are gated separately
  // at this probability (each rejects a consistent fix with 1 - p).
  double gps_gate_probability = 0.999;
  // After this many rejections in a row of a component, the next fix resets
  // that component of the position (covariance grown by the innovation) and is
  // fused: the gate never locks GPS out. Counted in FusedPose::gps_resets.
  int gps_reset_after_rejections = 3;
  // Where the GPS antenna sits in the body (IMU) frame, x forward / y left /
  // z up, metres: fixes are of the antenna, not of the IMU. A receiver 1.5 m
  // from the IMU otherwise biases the track by up to 1.5 m, turning with the
  // car (docs/benchmarks.md, "GPS lever arm").
  Vec3 gps_lever_arm_body_m = Vec3::Zero();
  // The fix is where the antenna was this long before the fix's time stamp
  // (receiver latency), s; 0 = the time stamp is the measurement time.
  double gps_latency_s = 0.0;
  // Vehicle (IMU mode; fusion/ekf_vehicle.cpp). A car's wheels neither
  // slide sideways nor lift: at every frame the vehicle-frame lateral and
  // vertical velocities are measured as 0 (non-holonomic constraints, NHC),
  // with a sigma that covers the IMU sitting off the rear axle (lateral speed
  // omega_z x lever in turns) and suspension motion. At a standstill (a speed
  // reading below zupt_speed_mps, or the IMU still while the estimated speed
  // is below zupt_max_estimated_speed_mps) the whole velocity is measured as 0
  // (zero-velocity update, ZUPT). Off for platforms that slide (robots, boats).
  // The NHC sigmas are wide on purpose: a tight constraint turns the velocity
  // to the filter's heading, and in an outage the heading is the weaker
  // estimate. Real excerpt, 10 s outage with VO blind, 6 seeds, end error
  // mean: frozen camera + recorded IMU 4.6 % (no NHC) / 4.3 (0.2 m/s) / 2.95
  // (0.5) / 2.8 (1.0); dark + MEMS IMU 5.9 / 5.8 / 4.6 / 4.4; 0.05 m/s: 14 %.
  // Synthetic 2 km, 30 s dark tunnel, MEMS IMU, seed 1: no speed sensor 1.44 %
  // without / 2.45 % with (0.2 m/s); with a speed sensor 0.15 / 0.12 %, max
  // error in the outage 2.76 / 0.53 m.
  // vehicle_constraints false: never. true: once a vehicle speed reading has
  // been fused (a car that reports its speed), or from the start when
  // vehicle_constraints_need_speed is false. Without a speed sensor the
  // constraints are a mixed blessing (figures below), hence the default.
  bool vehicle_constraints = true;
  bool vehicle_constraints_need_speed = true;
  Mat3 R_vehicle_body = Mat3::Identity();  // IMU mounting: vehicle <- body axes
  double nhc_sigma_lateral_mps = 0.5;
  double nhc_sigma_vertical_mps = 0.5;
  double zupt_speed_mps = 0.05;
  double zupt_sigma_mps = 0.02;
  // IMU stillness over the last zupt_window_s: gyro within zupt_gyro_radps of
  // its mean and specific force within zupt_accel_mps2 of its mean, at least
  // zupt_min_samples samples. A car cruising straight at constant speed on a
  // smooth road looks still to an IMU too, hence the bound on the estimated
  // speed: stillness only holds a car the filter already believes stopped.
  double zupt_window_s = 0.5;
  double zupt_gyro_radps = 0.01;
  double zupt_accel_mps2 = 0.1;
  int zupt_min_samples = 10;
  double zupt_max_estimated_speed_mps = 0.5;
  // Vehicle speed readings: 1-sigma when a reading states none, the scale
  // factor's prior 1-sigma (estimated while GPS is good: a worn tyre reads
  // 0.5 % high), the chi-square gate (1 dof).
  double speed_sigma_mps = 0.05;
  double speed_scale_sigma = 0.01;
  double speed_gate_probability = 0.9999;
  double degraded_hold_s = 3.0;       // GPS_DEGRADED while a rejection is this recent
  double vo_only_after_periods = 1.5; // VO_ONLY when no fix for this x GPS period
};

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
  // reported covariance scaled by vo_cov_scale, plus (vo_sigma_t_per_m * |t|)^2
  // on each translation axis (IMU mode), floored at vo_min_sigma_t_m /
  // vo_min_sigma_rot_rad. locaid-replay scores real VO errors against it
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
  // non-finite, or beyond the gate: refused. A reading below zupt_speed_mps
  // is a standstill (vehicle_constraints): the whole velocity is fused as 0.
  SpeedUpdate UpdateSpeed(const SpeedSample& reading);
  FusedPose Output(int64_t t_ns, bool vo_ok) const;
  // Whether the vehicle surely moves faster than speed_mps at t_ns: a speed
  // reading at most 0.5 s old says so, or, without one, the filter's own
  // speed (IMU mode, initialised) exceeds it by 3 sigma along its direction.
  // What VO reporting a standstill is checked against (a frozen camera whose
  // repeated frames still differ).
  bool SurelyMovingFasterThan(int64_t t_ns, double speed_mps) const;

  const EkfConfig& config() const { return config_; }
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
  // Noise scales (learn_vo_noise / adaptive_vo_rotation_noise /
  // learn_gps_noise; 1 where fixed): VO per body axis [dt x, y, z, dtheta x,
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
  void ApplyVehicleConstraints(int64_t t_ns);
  bool VehicleConstraintsActive() const;
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
  std::unique_ptr<ProcessModel> model_;  // chosen once from config_.use_imu
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
  // learn_gps_noise: horizontal (E and N: two samples per fix), vertical.
  NoiseScaleEstimator gps_noise_h_, gps_noise_v_;
  double gps_period_s_ = 1.0;
  double gps_lag_s_ = 0;  // how late fixes reach the filter after their frames (recent worst), s
};

}  // namespace locaid::fusion
