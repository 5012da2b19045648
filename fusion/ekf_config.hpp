// The EKF's settings, one struct per model: the IMU (and whether there is
// one), GPS fixes, VO motions, the vehicle (motion constraints, speed sensor)
// and start-up. A reader finds the settings of one measurement in one place;
// the defaults are the calibrated ones and their figures sit beside them.
//
// locaid-replay's `--ekf NAME=VALUE` sets a numeric setting by the name
// "model.field" (NumericEkfSettings); the flat names of earlier versions
// (e.g. vo_cov_scale for vo.cov_scale) are still accepted.
#pragma once

#include <Eigen/Core>

#include <string>
#include <string_view>
#include <vector>

namespace locaid::fusion {

struct EkfConfig {
  // The IMU and its noise. `enabled` chooses the process model once: IMU
  // propagation with VO updates (true), or VO-driven propagation without an
  // IMU (false; locaid-replay's --no-imu).
  struct Imu {
    bool enabled = true;
    double gravity_mps2 = 9.81;
    // Noise (continuous densities) and bias random walks; a sample that
    // states its own noise densities (ImuSample) is propagated with those.
    double accel_noise_mps2_sqrt_hz = 0.05;
    double gyro_noise_radps_sqrt_hz = 0.001;
    double accel_bias_walk_mps3_sqrt_hz = 0.001;
    double gyro_bias_walk_radps2_sqrt_hz = 1e-5;
    double max_gap_s = 0.5;  // longer IMU gaps: propagate with extra noise
  };

  // GPS fixes: gate, recovery, antenna, latency, learned noise, and the
  // modes that follow from the fixes' timing.
  struct Gps {
    // Horizontal (2 dof) and vertical (1 dof) innovations are gated
    // separately at this probability (each rejects a consistent fix with 1 - p).
    double gate_probability = 0.999;
    // After this many rejections in a row of a component, the next fix resets
    // that component of the position (covariance grown by the innovation) and
    // is fused: the gate never locks GPS out. Counted in FusedPose::gps_resets.
    int reset_after_rejections = 3;
    // Where the antenna sits in the body (IMU) frame, x forward / y left /
    // z up, metres: fixes are of the antenna, not of the IMU. A receiver 1.5 m
    // from the IMU otherwise biases the track by up to 1.5 m, turning with the
    // car (docs/benchmarks.md, "GPS lever arm").
    Eigen::Vector3d lever_arm_body_m = Eigen::Vector3d::Zero();
    // The fix is where the antenna was this long before the fix's time stamp
    // (receiver latency), s; 0 = the time stamp is the measurement time.
    double latency_s = 0.0;
    // Learned noise (fusion/noise_scale.hpp, covariance matching on the
    // filter's own innovations): the fixes' stated covariance is multiplied by
    // a scale learned per component (horizontal, vertical) from the
    // innovations of the fixes the gate passes, while the prediction is not
    // looser than 4x the fix. The stated covariance is the prior (scale 1,
    // worth noise_prior_fixes samples), then an exponential average over
    // about noise_window_fixes. false: the stated covariance (scale 1).
    bool learn_noise = true;
    double noise_prior_fixes = 5;
    double noise_window_fixes = 30;
    // The scale stays >= 1: the conservative VO model makes the filter's
    // predicted variance larger than its error, which biases the learned
    // scale low (0.95-0.98 for a receiver stating its true sigma); allowed
    // down to 0.25, the real excerpt's gate refused 8 + 5 of 4,700 fixes
    // (nominal 4.7) and the simulator's exactly modelled runs above their
    // NEES bound went from 12.8 to 14.7 %.
    double noise_scale_min = 1.0;
    double noise_scale_max = 100;
    double degraded_hold_s = 3.0;        // GPS_DEGRADED while a rejection is this recent
    double vo_only_after_periods = 1.5;  // VO_ONLY when no fix for this x GPS period
  };

  // VO relative motions. The noise model per frame and axis (body axes x
  // forward, y left, z up; 1-sigma):
  //   sigma_i^2 = cov_scale * reported variance_i + (k_i * |t|)^2 (translation,
  //   IMU mode only; k = sigma_t_per_m along, _lateral_, _vertical_),
  //   then floored at min_sigma_t_m / min_sigma_rot_rad (Ekf::VoNoise).
  // Calibrated with locaid-replay's "vo_error" (VO vs ground truth, after the
  // missing-frame fix of RelativeMotion::t_prev_ns):
  //  - real extract 2011_09_26_drive_unknown_extract (195 frames, ~0.85 m/frame):
  //    RMS error x/y/z 26.2 / 8.3 / 15.1 mm (3.1 / 1.0 / 1.8 % of the motion),
  //    rot 0.64 / 0.73 / 0.32 mrad; reported 1.2 / 1.2 / 1.4 mm, 0.13 / 0.09 /
  //    0.07 mrad (6-dof NEES 3214): the per-metre terms come from here (part of
  //    it is error of the truth: the extract's OXTS records are sparse).
  //  - synthetic 2.2 km drive (locaid-synth --length-m 2200 --seed 3, 1642
  //    frames, 1.34 m/frame): RMS error 5.1 / 5.3 / 3.2 mm, 0.14 / 0.11 / 0.14
  //    mrad; reported 1.8 / 1.5 / 1.9 mm (NEES 24): about 3x the reported sigma,
  //    hence cov_scale 9. Synthetic images are cleaner than the real camera,
  //    so the model is conservative there (NEES 0.3).
  //  6-dof NEES with this model: real 7.2, synthetic 0.3 (an isotropic 3 %/m
  //  model with scale 5: 5.8 / 0.2; its lateral and vertical sigmas were 3x
  //  and 1.7x the real errors). It is the prior of learn_noise.
  struct Vo {
    double cov_scale = 9.0;
    double sigma_t_per_m = 0.03;
    double sigma_lateral_per_m = 0.01;
    double sigma_vertical_per_m = 0.018;
    double min_sigma_t_m = 0.006;
    double min_sigma_rot_rad = 0.0005;
    double gate_probability = 0.9999;  // IMU mode: VO updates beyond are skipped
    // IMU mode: the VO's systematic errors are estimated as random constants
    // (t_m = (1 + s) R_b t_true, fusion/ekf_models.hpp): a boresight R_b of
    // the camera against the body axes (1-sigma per axis) and a scale error s.
    // Real cameras have both (a constant 0.15 deg yaw / 0.30 deg pitch was
    // fitted on the real excerpt, docs/benchmarks.md); while GPS is used they
    // are learnt, during an outage their remaining uncertainty grows the
    // position covariance with the distance driven, as their error grows the
    // position error. 0 pins them (the filter then trusts the VO geometry as
    // exact). The scale state is off by default: on the synthetic
    // urban-canyon drive (1 Hz fixes with multipath jumps) it raised the RMSE
    // from 1.32 to 1.44 m.
    double boresight_sigma_rad = 0.0087;  // 0.5 deg
    double scale_sigma = 0.0;
    double lost_sigma_no_imu_mps = 1.0;  // no-IMU mode: extra velocity noise when VO is lost
    // Learned noise: the model above is multiplied per axis ([dt x, y, z,
    // dtheta x, y, z], body axes) by a scale learned from the VO innovations
    // against the IMU (IMU mode), only while GPS holds the state (in an outage
    // it would learn its own drift). The model is the prior (scale 1, worth
    // noise_prior_frames samples), then an exponential average over about
    // noise_window_frames. false: the fixed model (scale 1).
    // The scale does not go below noise_scale_min = 1 by default: VO's
    // frame-to-frame errors are correlated in time (synthetic 2.2 km drive:
    // the along-track error summed over 200 frames is 3.9x what white errors
    // of the same per-frame size give), so noise matched to single frames
    // (scale 0.01 to 0.05 there) makes the fused track overconfident:
    // open-sky RMSE 0.29 -> 0.76 m, NEES 2.2 -> 29
    // (docs/experiments/fusion-learned-noise.md). Upwards it takes a camera
    // worse than the model; the rotation axes only up to
    // noise_rotation_scale_max (below).
    bool learn_noise = true;
    double noise_prior_frames = 5;
    double noise_window_frames = 300;
    double noise_scale_min = 1.0;
    double noise_scale_max = 400;
    // The learner's scale on the rotation axes while the adaptation below
    // takes them: at most noise_rotation_scale_max. 1 (the default): the
    // learner scales the translation axes (a camera worse than the model),
    // the rotation axes are the adaptation's. On real drives the learner's
    // rotation scale is the mean square of bursty, heavy-tailed roll / pitch
    // innovations (real excerpt: x10 / x20 where the adaptation settles at
    // x5.5 / x8.4; a longer real drive: x9.4 / 16.2 / 5.5) and stays so
    // through outages. Taking the larger of the two (noise_rotation_scale_max
    // = noise_scale_max, the default from 63529b3 to 2026-11-29) cost that
    // longer drive's centred 10 s outage (30 seeds) 0.764 -> 1.015 % median
    // end error and 0.403 -> 0.427 m RMSE while GPS, its 20 s dark tunnel
    // (MEMS IMU, 5 seeds) 1.09 -> 1.48 % worst seed with speed and 1.08 ->
    // 1.37 % without. On the real excerpt the two are within a few
    // hundredths (outage-10s-middle, 50 seeds: 2.01 / 4.65 / 8.32 % median /
    // p90 / max against 2.06 / 4.53 / 8.10); on a synthetic 2 km KITTI route
    // (locaid-synth --route, 10 Hz IMU) the larger scale did better in a 60 s
    // outage (0.69 against 0.89 %), as did a cap of 2 (0.70). Figures and
    // commands: docs/experiments/vo-rotation-noise.md (2026-11-29). With the
    // adaptation off (`--vo-rotation-noise learned`) the learner takes the
    // rotation axes up to noise_scale_max.
    double noise_rotation_scale_max = 1.0;
    // Innovation-adaptive rotation noise (IMU mode), on top of the learner:
    // when the VO's frame-to-frame rotation disagrees with the IMU's more than
    // their covariances say (running mean of the normalised squared rotation
    // innovation per body axis above 1, from every VO update, outages
    // included), that axis' rotation variance is scaled up, at most
    // adaptive_rotation_noise_max_scale times, never below the model; each
    // rotation axis then uses the larger of this scale and the learner's
    // (which is at most noise_rotation_scale_max, by default 1). On
    // real drives the OXTS records predict the roll / pitch over a frame 2-7
    // mrad away from the VO; the adaptation follows that faster than the
    // learner's window and keeps following it in outages, where the learner
    // is frozen. Without it the median end-of-outage error of a 10 s outage
    // 20 s into a longer real drive rose from 0.76 to 1.03 %
    // (docs/experiments/vo-rotation-noise.md). false (`locaid-replay
    // --vo-rotation-noise learned`): the learner's scale alone; a max_scale of
    // 1 leaves the rotation axes at the model (or, with noise_rotation_scale_max
    // raised, to the learner). It is part of the learned noise: the fixed model
    // (learn_noise false: `--fixed-vo-noise`, NoiseOptions.fixed_vo_noise) has
    // neither; the adaptation alone is noise_scale_max = 1.
    bool adaptive_rotation_noise = true;
    double adaptive_rotation_noise_max_scale = 400.0;
  };

  // The vehicle (IMU mode; fusion/ekf_vehicle.cpp). A car's wheels neither
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
  struct Vehicle {
    // constraints false: never. true: once a vehicle speed reading has been
    // fused (a car that reports its speed), and without one at every frame VO
    // cannot use (blind, frozen or lost cameras: the IMU alone would let the
    // velocity run); from the start when constraints_need_speed is false.
    // Without a speed sensor the constraints are a mixed blessing while VO
    // tracks (real excerpt, outage-10s-middle, 50 seeds: end error p90 4.65
    // -> 4.77 %, runs over their NEES bound 15 -> 19) and a large gain when it
    // cannot (until 2026-11-29 they waited for a speed reading then too: real
    // excerpt blind tunnel + MEMS, 20 seeds, median 7.33 -> 3.26 %; frozen
    // 6.99 -> 2.66 %; synthetic 30 s blind tunnel + MEMS, 8 seeds, 4.01 ->
    // 1.62 %; docs/experiments/tunnel-experiments.md).
    bool constraints = true;
    bool constraints_need_speed = true;
    Eigen::Matrix3d R_vehicle_body = Eigen::Matrix3d::Identity();  // IMU mounting: vehicle <- body axes
    double nhc_sigma_lateral_mps = 0.5;
    double nhc_sigma_vertical_mps = 0.5;
    double zupt_speed_mps = 0.05;
    double zupt_sigma_mps = 0.02;
    // IMU stillness over the last zupt_window_s: gyro within zupt_gyro_radps
    // of its mean and specific force within zupt_accel_mps2 of its mean, at
    // least zupt_min_samples samples. A car cruising straight at constant
    // speed on a smooth road looks still to an IMU too, hence the bound on the
    // estimated speed: stillness only holds a car the filter already believes
    // stopped.
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
  };

  // Start-up: the filter is declared initialised only once >= min_fixes
  // fixes span max(min_baseline_m, min_baseline_sigmas * sigma_h) (3 fixes
  // over 15 m gave a heading error of ~0.1 rad on 3 m / 1 Hz GPS and a 6 m
  // error lasting 20 s); the initial position / yaw covariance from the
  // Procrustes fit is multiplied by cov_inflation (it ignores GPS jumps and
  // the VO drift over the baseline). Then the initial uncertainty of the rest.
  struct Startup {
    int min_fixes = 6;
    double min_baseline_m = 15.0;
    double min_baseline_sigmas = 10.0;
    double cov_inflation = 4.0;
    double velocity_sigma_mps = 0.5;
    double roll_pitch_sigma_rad = 0.03;
    double accel_bias_sigma_mps2 = 0.1;
    double gyro_bias_sigma_radps = 0.002;
  };

  Imu imu;
  Gps gps;
  Vo vo;
  Vehicle vehicle;
  Startup startup;
};

// One numeric setting `--ekf NAME=VALUE` can set: its name ("model.field"),
// the flat name it had before the settings were grouped by model (still
// accepted), and where it lives in `config`.
struct EkfSetting {
  std::string name, flat_name;
  double* value;
};
std::vector<EkfSetting> NumericEkfSettings(EkfConfig& config);

// The setting called `name` (either name) in `config`, or nullptr.
double* FindEkfSetting(EkfConfig& config, std::string_view name);

}  // namespace locaid::fusion
