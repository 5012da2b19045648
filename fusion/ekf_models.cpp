#include "fusion/ekf_models.hpp"

#include <cmath>

namespace locaid::fusion {

Mat3 Skew(const Vec3& v) {
  Mat3 S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Mat3 ExpSO3(const Vec3& phi) {
  const double angle = phi.norm();
  if (angle < 1e-12) return Mat3::Identity() + Skew(phi);
  return Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
}

Vec3 LogSO3(const Mat3& R) {
  Eigen::AngleAxisd aa(R);
  double angle = aa.angle();
  Vec3 axis = aa.axis();
  if (angle > M_PI) { angle = 2 * M_PI - angle; axis = -axis; }
  return axis * angle;
}

Mat3 RightJacobianSO3(const Vec3& phi) {
  const double a = phi.norm();
  const Mat3 S = Skew(phi);
  if (a < 1e-8) return Mat3::Identity() - 0.5 * S;
  return Mat3::Identity() - (1 - std::cos(a)) / (a * a) * S + (a - std::sin(a)) / (a * a * a) * S * S;
}

NominalState BoxPlus(const NominalState& x, const Eigen::Matrix<double, 15, 1>& dx) {
  NominalState y = x;
  y.p_enu_m += dx.segment<3>(0);
  y.v_enu_mps += dx.segment<3>(3);
  y.R_enu_body = ExpSO3(dx.segment<3>(6)) * x.R_enu_body;
  y.accel_bias_mps2 += dx.segment<3>(9);
  y.gyro_bias_radps += dx.segment<3>(12);
  return y;
}

Eigen::Matrix<double, 15, 1> BoxMinus(const NominalState& x, const NominalState& x_hat) {
  Eigen::Matrix<double, 15, 1> d;
  d.segment<3>(0) = x.p_enu_m - x_hat.p_enu_m;
  d.segment<3>(3) = x.v_enu_mps - x_hat.v_enu_mps;
  d.segment<3>(6) = LogSO3(x.R_enu_body * x_hat.R_enu_body.transpose());
  d.segment<3>(9) = x.accel_bias_mps2 - x_hat.accel_bias_mps2;
  d.segment<3>(12) = x.gyro_bias_radps - x_hat.gyro_bias_radps;
  return d;
}

NominalState IntegrateImuStep(const NominalState& x, const Vec3& f_body, const Vec3& w_body,
                          double dt, const Vec3& g_enu) {
  NominalState y = x;
  const Vec3 a_enu = x.R_enu_body * (f_body - x.accel_bias_mps2) + g_enu;
  y.p_enu_m = x.p_enu_m + x.v_enu_mps * dt + 0.5 * a_enu * dt * dt;
  y.v_enu_mps = x.v_enu_mps + a_enu * dt;
  y.R_enu_body = x.R_enu_body * ExpSO3((w_body - x.gyro_bias_radps) * dt);
  return y;
}

Mat15 ImuTransitionJacobian(const NominalState& x, const Vec3& f_body, const Vec3& w_body,
                            double dt) {
  const Mat3& R = x.R_enu_body;
  const Vec3 w = w_body - x.gyro_bias_radps;
  const Mat3 R_next = R * ExpSO3(w * dt);
  const Mat3 RaX = Skew(R * (f_body - x.accel_bias_mps2));
  Mat15 F = Mat15::Identity();
  const Mat3 I = Mat3::Identity();
  F.block<3, 3>(0, 3) = I * dt;
  F.block<3, 3>(0, 6) = -0.5 * RaX * dt * dt;
  F.block<3, 3>(0, 9) = -0.5 * R * dt * dt;
  F.block<3, 3>(3, 6) = -RaX * dt;
  F.block<3, 3>(3, 9) = -R * dt;
  F.block<3, 3>(6, 12) = -R_next * RightJacobianSO3(w * dt) * dt;
  return F;
}

Mat15 ImuProcessNoise(const NominalState& x, double dt, double sa, double sg, double sba,
                      double sbg) {
  (void)x;  // isotropic densities: rotation into ENU leaves them unchanged
  Mat15 Q = Mat15::Zero();
  const Mat3 I = Mat3::Identity();
  Q.block<3, 3>(0, 0) = I * sa * sa * dt * dt * dt / 3.0;
  Q.block<3, 3>(0, 3) = I * sa * sa * dt * dt / 2.0;
  Q.block<3, 3>(3, 0) = I * sa * sa * dt * dt / 2.0;
  Q.block<3, 3>(3, 3) = I * sa * sa * dt;
  Q.block<3, 3>(6, 6) = I * sg * sg * dt;
  Q.block<3, 3>(9, 9) = I * sba * sba * dt;
  Q.block<3, 3>(12, 12) = I * sbg * sbg * dt;
  return Q;
}

Vec6 VoResidual(const Vec3& p, const Mat3& R, const Vec3& p_c, const Mat3& R_c,
                const Eigen::Isometry3d& T_meas) {
  const Mat3 R_m = T_meas.linear();
  const Vec3 t_m = T_meas.translation();
  const Vec3 t_hat = R_c.transpose() * (p - p_c);
  const Mat3 R_hat = R_c.transpose() * R;
  Vec6 r;
  r.head<3>() = R_m.transpose() * (t_m - t_hat);
  r.tail<3>() = LogSO3(R_hat.transpose() * R_m);
  return r;
}

MatVoH VoJacobian(const Vec3& p, const Mat3& R, const Vec3& p_c, const Mat3& R_c,
                  const Eigen::Isometry3d& T_meas) {
  // r(x + dx) ~= r(x) - H dx with
  //   t_hat(x + dx) = t_hat + R_c^T (dp - dp_c) + R_c^T [p - p_c]x dtheta_c
  //   R_hat(x + dx) = R_hat Exp(R^T (dtheta - dtheta_c))
  //   r_theta = Log(Exp(-phi) R_hat^T R_m) ~= r_theta - Jr^-1(r_theta)... ~ r_theta - phi
  const Mat3 R_m = T_meas.linear();
  MatVoH H = MatVoH::Zero();
  H.block<3, 3>(0, 0) = R_m.transpose() * R_c.transpose();
  H.block<3, 3>(0, 6) = -R_m.transpose() * R_c.transpose();
  H.block<3, 3>(0, 9) = R_m.transpose() * R_c.transpose() * Skew(p - p_c);
  // Rotation residual: Log(Exp(-phi) E) with E = R_hat^T R_m; first order
  // Log(E) - Jr^{-1}... use the left Jacobian inverse of Log(E) for exactness.
  const Vec3 r_theta = LogSO3((R_c.transpose() * R).transpose() * R_m);
  // Log(Exp(-phi) Exp(r)) ~= r - Jl^{-1}(r) phi, Jl^{-1}(r) = Jr^{-1}(-r)
  const Mat3 Jl_inv = RightJacobianSO3(-r_theta).inverse();
  H.block<3, 3>(3, 3) = Jl_inv * R.transpose();
  H.block<3, 3>(3, 9) = -Jl_inv * R.transpose();
  return H;
}

Eigen::MatrixXd GpsJacobian(int n) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, n);
  H.block<3, 3>(0, 0).setIdentity();
  return H;
}

void OdometryPropagate(Vec3& p, Mat3& R, const Eigen::Isometry3d& T) {
  p = p + R * T.translation();
  R = R * T.linear();
}

Mat6 OdometryTransitionJacobian(const Mat3& R, const Eigen::Isometry3d& T) {
  Mat6 F = Mat6::Identity();
  F.block<3, 3>(0, 3) = -Skew(R * T.translation());
  return F;
}

Mat6 OdometryNoiseJacobian(const Mat3& R, const Eigen::Isometry3d& T) {
  // true motion t = t_m + R_m n_t, R = R_m Exp(n_theta)
  Mat6 G = Mat6::Zero();
  G.block<3, 3>(0, 0) = R * T.linear();
  G.block<3, 3>(3, 3) = R * T.linear();
  return G;
}

VoMeasurement CameraMotionToBody(const Eigen::Isometry3d& T_prev_curr_cam, const Mat6& cov_cam,
                                 const Eigen::Isometry3d& T_cam_body) {
  VoMeasurement m;
  m.T_prev_curr = T_cam_body.inverse() * T_prev_curr_cam * T_cam_body;
  // Perturbation convention: t_true = t + R n_t (n_t in curr axes), R_true = R Exp(n_theta).
  // Body motion: T_b = A^-1 T_c A with A = T_cam_body (R_A, t_A).
  //   R_b = R_A^T R_c R_A -> n_theta_b = R_A^T n_theta_c
  //   t_b = R_A^T (R_c t_A + t_c - t_A) -> dt_b = R_A^T (R_c dtheta_c x t_A ... )
  // Expressed in the body motion's own convention: n_t_b = R_b^T dt_b.
  const Mat3 R_A = T_cam_body.linear();
  const Vec3 t_A = T_cam_body.translation();
  const Mat3 R_c = T_prev_curr_cam.linear();
  const Mat3 R_b = m.T_prev_curr.linear();
  // dt_b = R_A^T (R_c n_t_c + R_c [n_theta_c]x t_A) = R_A^T R_c (n_t_c - [t_A]x n_theta_c)
  Mat6 J = Mat6::Zero();
  J.block<3, 3>(0, 0) = R_b.transpose() * R_A.transpose() * R_c;
  J.block<3, 3>(0, 3) = -R_b.transpose() * R_A.transpose() * R_c * Skew(t_A);
  J.block<3, 3>(3, 3) = R_A.transpose();
  m.covariance = J * cov_cam * J.transpose();
  m.covariance = 0.5 * (m.covariance + m.covariance.transpose()).eval();
  return m;
}

Vec3 GpsAntennaPrediction(const Vec3& p_enu, const Vec3& v_enu, const Mat3& R_enu_body, const Vec3& lever_body_m,
                          double latency_s) {
  return p_enu + R_enu_body * lever_body_m - v_enu * latency_s;
}

Eigen::Matrix<double, 3, 9> GpsAntennaJacobian(const Mat3& R_enu_body, const Vec3& lever_body_m, double latency_s) {
  Eigen::Matrix<double, 3, 9> H;
  H.block<3, 3>(0, 0) = Mat3::Identity();
  H.block<3, 3>(0, 3) = -latency_s * Mat3::Identity();
  H.block<3, 3>(0, 6) = -Skew(R_enu_body * lever_body_m);  // Exp(dtheta) R l ~= R l - [R l]x dtheta
  return H;
}

Vec3 VehicleVelocity(const Vec3& v_enu, const Mat3& R_enu_body, const Mat3& R_vehicle_body) {
  return R_vehicle_body * R_enu_body.transpose() * v_enu;
}

Eigen::Matrix<double, 3, 6> VehicleVelocityJacobian(const Vec3& v_enu, const Mat3& R_enu_body,
                                                    const Mat3& R_vehicle_body) {
  // R = Exp(dtheta) R_hat: R^T v ~= R_hat^T (v - dtheta x v) = R_hat^T (v + [v]x dtheta).
  const Mat3 A = R_vehicle_body * R_enu_body.transpose();
  Eigen::Matrix<double, 3, 6> H;
  H.leftCols<3>() = A;
  H.rightCols<3>() = A * Skew(v_enu);
  return H;
}

Vec3 CorrectVoTranslation(const Vec3& t_measured, const Mat3& R_boresight, double scale_error) {
  return R_boresight.transpose() * t_measured / (1.0 + scale_error);
}

Eigen::Matrix<double, 6, kVoCalibStates> VoCalibrationJacobian(const Mat3& R_measured,
                                                               const Vec3& t_measured,
                                                               const Mat3& R_boresight,
                                                               double scale_error) {
  Eigen::Matrix<double, 6, kVoCalibStates> H = Eigen::Matrix<double, 6, kVoCalibStates>::Zero();
  const double k = 1.0 / (1.0 + scale_error);
  const Vec3 t_c = CorrectVoTranslation(t_measured, R_boresight, scale_error);
  // r_t = R_m^T (t_c - v): d t_c / d dphi = k R_b^T [t_m]x, d t_c / d ds = -k t_c.
  H.block<3, 3>(0, 0) = -R_measured.transpose() * (k * R_boresight.transpose() * Skew(t_measured));
  H.block<3, 1>(0, 3) = R_measured.transpose() * (k * t_c);
  return H;
}

GravityFit FitGravity(const std::vector<GravitySample>& samples) {
  GravityFit fit;
  const size_t n = samples.size();
  if (n < 5) return fit;
  double t_mean = 0, s_mean = 0;
  for (const auto& k : samples) { t_mean += k.t_s; s_mean += k.v_body_mps.norm(); }
  t_mean /= static_cast<double>(n);
  s_mean /= static_cast<double>(n);
  double stt = 0, sts = 0;
  for (const auto& k : samples) {
    stt += (k.t_s - t_mean) * (k.t_s - t_mean);
    sts += (k.t_s - t_mean) * (k.v_body_mps.norm() - s_mean);
  }
  if (!(stt > 0)) return fit;
  const double speed_rate = sts / stt;  // m/s^2 along the motion
  double res2 = 0;
  Vec3 g_up = Vec3::Zero();
  for (const auto& k : samples) {
    const double speed = k.v_body_mps.norm();
    const double r = speed - (s_mean + speed_rate * (k.t_s - t_mean));
    res2 += r * r;
    const Vec3 along = speed > 1e-3 ? Vec3(k.v_body_mps / speed) : Vec3::Zero();
    const Vec3 a_body = k.w_body_radps.cross(k.v_body_mps) + speed_rate * along;
    g_up += k.R_start_body * (k.f_body_mps2 - a_body);
  }
  if (!g_up.allFinite() || g_up.norm() < 1e-6) return fit;
  fit.up_start = g_up.normalized();
  fit.accel_sigma_mps2 = std::sqrt(res2 / std::max(1.0, static_cast<double>(n) - 2.0) / stt);
  fit.ok = std::isfinite(fit.accel_sigma_mps2);
  return fit;
}

double ChiSquareCdf(double x, int dof) {
  if (x <= 0) return 0.0;
  if (dof % 2 == 0) {
    // 1 - exp(-x/2) sum_{i < k/2} (x/2)^i / i!
    double term = 1, sum = 1;
    for (int i = 1; i < dof / 2; ++i) { term *= x / 2 / i; sum += term; }
    return 1 - std::exp(-x / 2) * sum;
  }
  // Odd: Q = 2 Q_N(sqrt x) + 2 phi(sqrt x) sum_{r=1}^{(k-1)/2} x^{(2r-1)/2} / (1 3 ... (2r-1))
  const double sx = std::sqrt(x);
  const double phi = std::exp(-x / 2) / std::sqrt(2 * M_PI);
  double q = std::erfc(sx / std::sqrt(2.0));
  double term = sx;
  for (int r = 1; r <= (dof - 1) / 2; ++r) {
    if (r > 1) term *= x / (2 * r - 1);
    q += 2 * phi * term;
  }
  return 1 - q;
}

double ChiSquareQuantile(double p, int dof) {
  double lo = 0, hi = dof + 10 * std::sqrt(2.0 * dof) + 50;
  while (ChiSquareCdf(hi, dof) < p) hi *= 2;
  for (int i = 0; i < 200 && hi - lo > 1e-10 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (ChiSquareCdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace locaid::fusion
