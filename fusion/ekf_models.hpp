// EKF math as free functions with explicit inputs (tested against numeric
// Jacobians in tests/fusion/). Conventions:
//   nominal state  p_enu (m), v_enu (m/s), R_enu_body, accel bias (m/s^2),
//                  gyro bias (rad/s)
//   error state    dp, dv, dtheta (global: R = Exp(dtheta) * R_hat, ENU axes),
//                  dba, dbg   -> 15 states, plus a clone [dp_c, dtheta_c] of
//                  the pose at the previous VO frame, and 4 VO calibration
//                  states (boresight, scale): 25 states with IMU.
//   without IMU    [dp, dtheta] (6 states), propagated by the VO motion.
#pragma once

#include "fusion/types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace locaid::fusion {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat15 = Eigen::Matrix<double, 15, 15>;

inline constexpr int kImuStates = 15;  // p v theta ba bg
inline constexpr int kCloneStates = 6; // p_c theta_c
inline constexpr int kPoseStates = 6;  // p theta (no-IMU mode)

Mat3 Skew(const Vec3& v);
Mat3 ExpSO3(const Vec3& phi);
Vec3 LogSO3(const Mat3& R);
Mat3 RightJacobianSO3(const Vec3& phi);

struct NominalState {
  Vec3 p_enu_m = Vec3::Zero();
  Vec3 v_enu_mps = Vec3::Zero();
  Mat3 R_enu_body = Mat3::Identity();
  Vec3 accel_bias_mps2 = Vec3::Zero();
  Vec3 gyro_bias_radps = Vec3::Zero();
};

// x (+) dx for the 15 error states (global attitude error).
NominalState BoxPlus(const NominalState& x, const Eigen::Matrix<double, 15, 1>& dx);
// dx such that BoxPlus(x_hat, dx) == x (first order), for tests and NEES.
Eigen::Matrix<double, 15, 1> BoxMinus(const NominalState& x, const NominalState& x_hat);

// One IMU step over dt_s with specific force f (body) and angular rate w
// (body), both raw (biases removed inside), gravity g_enu (0, 0, -9.81):
//   p' = p + v dt + 1/2 (R a + g) dt^2,  v' = v + (R a + g) dt,  R' = R Exp(w dt)
NominalState IntegrateImuStep(const NominalState& x, const Vec3& f_body_mps2,
                          const Vec3& w_body_radps, double dt_s, const Vec3& g_enu_mps2);
// Exact Jacobian of IntegrateImuStep w.r.t. the 15 error states.
Mat15 ImuTransitionJacobian(const NominalState& x, const Vec3& f_body_mps2,
                            const Vec3& w_body_radps, double dt_s);
// Discrete process noise for that step (white accel/gyro noise densities,
// bias random walk densities).
Mat15 ImuProcessNoise(const NominalState& x, double dt_s, double accel_noise_mps2_sqrt_hz,
                      double gyro_noise_radps_sqrt_hz, double accel_bias_walk,
                      double gyro_bias_walk);

// VO relative-motion measurement between the clone pose (p_c, R_c) and the
// current pose (p, R). Residual (6) in measurement axes:
//   r_t = R_m^T (t_m - R_c^T (p - p_c)),  r_theta = Log((R_c^T R)^T R_m)
// and its Jacobian w.r.t. [dp, dtheta, dp_c, dtheta_c] (6 x 12), so that
// r(x (+) dx) ~= r(x) - H dx.
using Vec6 = Eigen::Matrix<double, 6, 1>;
using MatVoH = Eigen::Matrix<double, 6, 12>;
Vec6 VoResidual(const Vec3& p_enu, const Mat3& R_enu_body, const Vec3& p_c_enu,
                const Mat3& R_enu_clone, const Eigen::Isometry3d& T_prev_curr_meas);
MatVoH VoJacobian(const Vec3& p_enu, const Mat3& R_enu_body, const Vec3& p_c_enu,
                  const Mat3& R_enu_clone, const Eigen::Isometry3d& T_prev_curr_meas);

// VO calibration (IMU mode): the VO's translation is measured in axes rotated
// by a small boresight R_b from the body axes, and scaled by (1 + s):
//   t_m = (1 + s) R_b t_true.
// CorrectVoTranslation undoes the current estimate (t_c = R_b^T t_m / (1 + s));
// VoCalibrationJacobian gives d r / d [dphi (3), ds] of the VO residual computed
// with the corrected motion, in the residual convention r(x (+) dx) ~= r - H dx,
// with R_b = Exp(dphi) R_b_hat and s = s_hat + ds.
inline constexpr int kVoCalibStates = 4;  // boresight (3), scale (1)
Vec3 CorrectVoTranslation(const Vec3& t_measured, const Mat3& R_boresight, double scale_error);
Eigen::Matrix<double, 6, kVoCalibStates> VoCalibrationJacobian(const Mat3& R_measured,
                                                               const Vec3& t_measured,
                                                               const Mat3& R_boresight,
                                                               double scale_error);

// GPS position measurement z = p_enu (+ noise): H = [I3 0 ...] (3 x n).
Eigen::MatrixXd GpsJacobian(int state_dim);

// GPS antenna position measurement with a lever arm and a latency: the fix
// is where the antenna (at lever_body_m in the body frame) was latency_s
// before the fix's time stamp, predicted from the state at that time stamp:
//   h = p + R lever - v latency
// and its Jacobian w.r.t. [dp, dv, dtheta] (3 x 9, global attitude error).
Vec3 GpsAntennaPrediction(const Vec3& p_enu, const Vec3& v_enu, const Mat3& R_enu_body, const Vec3& lever_body_m,
                          double latency_s);
Eigen::Matrix<double, 3, 9> GpsAntennaJacobian(const Mat3& R_enu_body, const Vec3& lever_body_m, double latency_s);

// Vehicle velocity (IMU mode): the body velocity in vehicle axes (x forward,
// y left, z up), v_veh = R_vb R^T v, for speed readings and the non-holonomic
// constraints; its Jacobian w.r.t. [dv, dtheta] (3 x 6, global attitude error)
// so that v_veh(x (+) dx) ~= v_veh(x) + H dx.
Vec3 VehicleVelocity(const Vec3& v_enu, const Mat3& R_enu_body, const Mat3& R_vehicle_body);
Eigen::Matrix<double, 3, 6> VehicleVelocityJacobian(const Vec3& v_enu, const Mat3& R_enu_body,
                                                    const Mat3& R_vehicle_body);

// No-IMU mode: pose propagated by the body motion (t_b, R_b) measured by VO:
//   p' = p + R t_b,  R' = R R_b.  F (6x6) w.r.t. [dp, dtheta], G (6x6) w.r.t.
// the VO noise [n_t, n_theta] (convention of VoMeasurement::covariance).
void OdometryPropagate(Vec3& p_enu, Mat3& R_enu_body, const Eigen::Isometry3d& T_prev_curr);
Mat6 OdometryTransitionJacobian(const Mat3& R_enu_body, const Eigen::Isometry3d& T_prev_curr);
Mat6 OdometryNoiseJacobian(const Mat3& R_enu_body, const Eigen::Isometry3d& T_prev_curr);

// Camera motion -> body motion: T_prev_curr_body = T_body_cam T_prev_curr_cam T_cam_body,
// covariance mapped by the adjoint of T_cam_body (first order, [dt, dtheta]).
VoMeasurement CameraMotionToBody(const Eigen::Isometry3d& T_prev_curr_cam,
                                 const Mat6& covariance_cam,
                                 const Eigen::Isometry3d& T_cam_body);

// Gravity direction in a fixed start frame while the car drives, for the
// filter's start-up. Per tracked frame k (body axes): specific force f_k (mean
// of the IMU samples of the frame), VO velocity v_k and angular rate w_k, and
// R_k (start <- body). The car's own acceleration in body axes is the
// centripetal w_k x v_k plus the change of speed along v_k, whose rate comes
// from a least-squares line through the speeds |v_k|: differencing per-frame
// VO velocities (2.6 m/s^2 of noise per frame on the real KITTI excerpt)
// tilted the start-up pitch by 1 deg. Then g * up = mean_k R_k (f_k - a_k).
// accel_sigma_mps2: 1-sigma of the speed-rate fit (from its residuals). ok is
// false with fewer than 5 frames or no time span.
struct GravitySample {
  double t_s = 0;
  Mat3 R_start_body = Mat3::Identity();
  Vec3 f_body_mps2 = Vec3::Zero();
  Vec3 v_body_mps = Vec3::Zero();
  Vec3 w_body_radps = Vec3::Zero();
};
struct GravityFit {
  Vec3 up_start = Vec3::UnitZ();  // unit vector
  double accel_sigma_mps2 = 0;
  bool ok = false;
};
GravityFit FitGravity(const std::vector<GravitySample>& samples);

// chi-square CDF (closed form for integer dof) and its quantile (bisection).
double ChiSquareCdf(double x, int dof);
double ChiSquareQuantile(double p, int dof);

}  // namespace locaid::fusion
