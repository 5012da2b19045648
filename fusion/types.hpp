// Fusion data types: what goes into the EKF and what comes out of it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

namespace locaid::fusion {

// A (degraded) GPS position fix as the filter sees it.
struct GpsFix {
  int64_t t_ns = 0;
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  double sigma_h_m = 3.0;  // 1-sigma horizontal noise the receiver claims
  double sigma_v_m = 5.0;  // 1-sigma vertical noise
  // False for a 2-D fix: the altitude is not a measurement, only E/N are fused.
  bool has_altitude = true;
  // Full ENU position covariance (m^2); replaces the sigmas when set.
  std::optional<Eigen::Matrix3d> cov_enu_m2;
  // Velocity over ground in ENU (m/s) with a 1-sigma per axis; fused with IMU.
  std::optional<Eigen::Vector3d> v_enu_mps;
  double sigma_v_enu_mps = 0.5;
  // The 1-sigma the filter uses: from the covariance when set (its larger
  // horizontal axis), else the sigmas.
  double horizontal_sigma_m() const {
    return cov_enu_m2 ? std::sqrt(std::max((*cov_enu_m2)(0, 0), (*cov_enu_m2)(1, 1))) : sigma_h_m;
  }
  double vertical_sigma_m() const { return cov_enu_m2 ? std::sqrt((*cov_enu_m2)(2, 2)) : sigma_v_m; }
};

// IMU sample in the body frame (x forward, y left, z up), as OXTS reports it:
// specific force (gravity included, ~+9.81 m/s^2 on z at rest) and angular rate.
struct ImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  // Noise densities of this IMU when it states them; 0 = EkfConfig's.
  double accel_noise_mps2_sqrt_hz = 0;
  double gyro_noise_radps_sqrt_hz = 0;
};

// One vehicle speed reading (CAN bus speed, wheel ticks turned to speed):
// the forward speed of the vehicle (negative when reversing).
struct SpeedSample {
  int64_t t_ns = 0;
  double speed_mps = 0;
  double sigma_mps = 0;  // 1-sigma of this reading; 0 = EkfConfig vehicle.speed_sigma_mps
};

// Where a reference unit (a recorded drive's OXTS RT3003: ground truth) says
// the body was. Never fused: the scenario (sim/scenario.hpp) makes the
// receiver fixes the filter sees from it, and evaluation compares with it.
struct TruthSample {
  int64_t t_ns = 0;
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  Eigen::Matrix3d R_enu_body = Eigen::Matrix3d::Identity();  // attitude (places an antenna)
  // Velocity in body axes (x forward, y left, z up), m/s, when the unit
  // reports it: a simulated speed sensor reads its x.
  std::optional<Eigen::Vector3d> v_body_mps;
};

// Relative motion of the body between two VO frames: p_prev = T_prev_curr * p_curr,
// covariance of the right perturbation [dt, dtheta] in body (curr) axes.
struct VoMeasurement {
  int64_t t_prev_ns = 0, t_ns = 0;
  Eigen::Isometry3d T_prev_curr = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
};

// kDeadReckoning: no GPS and no usable VO, the IMU (with vehicle speed and
// the car's motion constraints) carries the estimate. kLost: not initialised,
// or nothing to stand on (no IMU, no VO, no GPS).
enum class Mode { kGpsFused, kGpsDegraded, kVoOnly, kLost, kDeadReckoning };
const char* ToString(Mode mode);

struct FusedPose {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_enu_body = Eigen::Isometry3d::Identity();
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  Eigen::Vector3d v_enu_mps = Eigen::Vector3d::Zero();
  // Covariance of [position ENU (m), attitude error (rad, ENU axes)].
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
  Mode mode = Mode::kLost;
  double seconds_since_gps = 0;  // since the last accepted fix; +inf before the first
  int gps_used = 0, gps_rejected = 0;  // cumulative counts (a fix used in part counts as used)
  int gps_resets = 0;  // cumulative: position resets to GPS after a run of gate rejections
  // Normalised innovation squared of the newest GPS fix's horizontal part and
  // the gate it was held against (2 dof); 0 before the first gated fix.
  double last_gps_nis = 0, gps_gate = 0;
  // Vehicle speed: the estimated scale error of the speed sensor (reads
  // (1 + error) x true speed) and the readings fused so far (cumulative).
  double speed_scale_error = 0;
  int speed_used = 0;
  // Learned noise (EkfConfig vo.learn_noise / gps.learn_noise): variance
  // multiples of the VO noise model per body axis [dt x, y, z, dtheta x, y, z]
  // and of the fixes' stated covariance (horizontal, vertical); 1 = the model.
  // vo_noise_learning: the VO noise is being learnt (GPS holds the state);
  // false: frozen (outage, no IMU, or the fixed model).
  Eigen::Matrix<double, 6, 1> vo_noise_scale = Eigen::Matrix<double, 6, 1>::Ones();
  double gps_noise_scale_h = 1, gps_noise_scale_v = 1;
  bool vo_noise_learning = false;
  // A smoothed estimate (fusion/rts_smoother.hpp): the pose at t_ns given
  // measurements after it too; false: the filter's (causal) estimate.
  bool smoothed = false;
};

}  // namespace locaid::fusion
