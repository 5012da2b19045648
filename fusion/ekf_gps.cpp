// The EKF's GPS update: split horizontal / vertical gates, the reset after a
// run of rejections, the antenna (lever arm, latency) model.
#include "fusion/ekf.hpp"

#include "fusion/ekf_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

namespace locaid::fusion {

using namespace detail;

// ------------------------------------------------------------------ GPS

Vec3 Ekf::GpsEnu(const GpsFix& fix) {
  if (!enu_.has_origin()) enu_.SetOrigin(fix.lat_deg, fix.lon_deg, fix.alt_m);
  return enu_.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m);
}

bool Ekf::UpdateGps(const GpsFix& fix) {
  // Non-finite fixes or sigmas are refused before they can set the ENU origin
  // or reach the covariance.
  if (!GpsFixUsable(fix)) {
    ++gps_rejected_;
    last_gps_rejected_ns_ = fix.t_ns;
    return false;
  }
  const Vec3 z = GpsEnu(fix);
  if (last_gps_received_ns_) {
    const double interval = Seconds(fix.t_ns, *last_gps_received_ns_);
    if (interval > 0) {
      if (gps_used_ + gps_rejected_ <= 1) gps_period_s_ = interval;
      else if (interval < 3 * gps_period_s_) gps_period_s_ = 0.8 * gps_period_s_ + 0.2 * interval;
    }
  }
  last_gps_received_ns_ = fix.t_ns;
  if (!s_.initialized) {
    // The start-up fit weighs fixes by their horizontal sigma.
    init_fixes_.push_back({fix.t_ns, z, fix.horizontal_sigma_m(), Eigen::Isometry3d::Identity()});
    init_fixes_.back().T_start_body.matrix()(0, 0) = std::numeric_limits<double>::quiet_NaN();
    return false;
  }
  model_->PropagateTo(s_, fix.t_ns);
  // The antenna, latency before the state time (lever arm and latency; both
  // 0 by default). A fix older than the state (it arrived after later IMU
  // data, as live fixes do) is compared with where the antenna was then.
  const double late_s = model_->GpsLateness(s_, fix.t_ns);
  // How late fixes arrive after their frames: the recent worst, slowly
  // forgotten (a receiver's latency jitters).
  gps_lag_s_ = std::max(0.95 * gps_lag_s_, std::max(0.0, Seconds(last_frame_ns_.value_or(fix.t_ns), fix.t_ns)));
  const double latency_s = config_.gps_latency_s + late_s;
  Vec3 predicted =
      GpsAntennaPrediction(s_.x.p_enu_m, s_.x.v_enu_mps, s_.x.R_enu_body, config_.gps_lever_arm_body_m, latency_s);
  Mat3 R = Mat3::Zero();
  if (fix.cov_enu_m2) {
    R = *fix.cov_enu_m2;
  } else {
    R.diagonal() << fix.sigma_h_m * fix.sigma_h_m, fix.sigma_h_m * fix.sigma_h_m,
        fix.sigma_v_m * fix.sigma_v_m;
  }
  model_->ExtrapolateGps(s_, fix.t_ns, predicted, R);
  const Vec3 y = z - predicted;
  const Eigen::MatrixXd H =
      model_->GpsJacobian(s_, GpsAntennaJacobian(s_.x.R_enu_body, config_.gps_lever_arm_body_m, latency_s));
  // Horizontal (E, N) and vertical (U) are gated on their own, so that a
  // vertical disagreement does not throw away the horizontal information.
  const GpsGateResult gate = GateGps(y, R, H);
  last_nis_ = gate.nis_h;
  last_nis_v_ = gate.nis_v;
  // A 2-D fix has no altitude to fuse (not a rejection either).
  const bool fuse_v = fix.has_altitude;
  bool use_h = gate.h_ok, use_v = gate.v_ok && fuse_v;
  // A run of rejections means the filter, not the GPS, is off (an open-sky
  // receiver does not fail 3 times in a row at the 0.1 % gate): reset the
  // rejected component's position covariance to cover the innovation, so the
  // fix is taken and the state snaps back to GPS. Counted on the pose.
  const int reset_after = std::max(1, config_.gps_reset_after_rejections);
  const bool reset_h = !use_h && std::isfinite(gate.nis_h) && ++rejections_h_ > reset_after;
  const bool reset_v = fuse_v && !use_v && std::isfinite(gate.nis_v) && ++rejections_v_ > reset_after;
  // The reset uses the fix for its component(s); a passing other component
  // gets the normal update (its innovation is unchanged by the reset).
  if (reset_h || reset_v) ResetPositionToGps(y, R, reset_h, reset_v);
  if ((use_h && !reset_h) || (use_v && !reset_v)) ApplyGpsUpdate(y, R, H, use_h && !reset_h, use_v && !reset_v);
  use_h = use_h || reset_h;
  use_v = use_v || reset_v;
  if (use_h) rejections_h_ = 0;
  if (use_v) rejections_v_ = 0;
  // A fix counts as used when its horizontal part is fused (a vertical-only
  // update is reported as a rejection); vertical rejections are counted apart.
  if (fuse_v && !use_v) ++gps_rejected_vertical_;
  if (!use_h || (fuse_v && !use_v)) last_gps_rejected_ns_ = fix.t_ns;  // GPS_DEGRADED for a while
  if (!use_h) {
    ++gps_rejected_;
    return false;
  }
  ++gps_used_;
  last_gps_accepted_ns_ = fix.t_ns;
  // The fix's velocity, where velocity is a state (IMU model).
  if (fix.v_enu_mps) {
    if (const std::optional<bool> used = model_->FuseGpsVelocity(s_, fix, late_s)) {
      if (*used) ++gps_velocity_used_;
      else ++gps_velocity_rejected_;
    }
  }
  return true;
}

bool Ekf::GpsFixUsable(const GpsFix& fix) {
  const bool position_ok = std::isfinite(fix.lat_deg) && std::isfinite(fix.lon_deg) && std::isfinite(fix.alt_m);
  if (!position_ok) return false;
  if (fix.cov_enu_m2) {
    const Mat3& C = *fix.cov_enu_m2;
    if (!C.allFinite() || !C.isApprox(C.transpose(), 1e-9)) return false;
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(C);
    if (eig.info() != Eigen::Success || eig.eigenvalues().minCoeff() <= 0) return false;
  } else if (!std::isfinite(fix.sigma_h_m) || !std::isfinite(fix.sigma_v_m) || fix.sigma_h_m <= 0 ||
             fix.sigma_v_m <= 0) {
    return false;
  }
  return !fix.v_enu_mps || (fix.v_enu_mps->allFinite() && std::isfinite(fix.sigma_v_enu_mps) && fix.sigma_v_enu_mps > 0);
}

Ekf::GpsGateResult Ekf::GateGps(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H) const {
  const Mat3 S = H * s_.P * H.transpose() + R;
  GpsGateResult g;
  const Eigen::Vector2d y_h = y.head<2>();
  g.nis_h = y_h.dot(S.topLeftCorner<2, 2>().ldlt().solve(y_h));
  g.nis_v = y.z() * y.z() / S(2, 2);
  g.h_ok = std::isfinite(g.nis_h) && g.nis_h <= gate_h_;
  g.v_ok = std::isfinite(g.nis_v) && g.nis_v <= gate_v_;
  return g;
}

void Ekf::ResetPositionToGps(const Vec3& y, const Mat3& R, bool horizontal, bool vertical) {
  // Hard reset of the rejected component(s) to the fix, as mature filters do
  // after a run of rejections: the position jumps by the innovation, and so
  // does the clone (a reset is not motion: the next VO update must not see
  // it), the position covariance of those axes becomes the fix's, and the
  // velocity (a state that drifted that far has a wrong velocity too) gets its
  // start-up uncertainty back plus the drift rate since the last used fix
  // (the clone and velocity parts: ProcessModel::ResetPosition).
  const Vec3 mask(horizontal ? 1.0 : 0.0, horizontal ? 1.0 : 0.0, vertical ? 1.0 : 0.0);
  const Vec3 jump = y.cwiseProduct(mask);
  s_.x.p_enu_m += jump;
  const double gap_s = last_gps_accepted_ns_ ? std::max(1.0, Seconds(s_.t_ns, *last_gps_accepted_ns_)) : 1.0;
  Eigen::MatrixXd& P = s_.P;
  for (int i = 0; i < 3; ++i) {
    if (mask[i] == 0.0) continue;
    P.row(i).setZero();
    P.col(i).setZero();
    P(i, i) = R(i, i);
  }
  model_->ResetPosition(s_, jump, mask, R, gap_s);
  Symmetrize(P);
  ++gps_resets_;
}

void Ekf::ApplyGpsUpdate(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H3, bool horizontal, bool vertical) {
  std::vector<int> rows;
  if (horizontal) rows = {0, 1};
  if (vertical) rows.push_back(2);
  const int m = static_cast<int>(rows.size());
  const int n = static_cast<int>(s_.P.rows());
  Eigen::MatrixXd H(m, n);
  Eigen::VectorXd ym(m);
  Eigen::MatrixXd Rm(m, m);
  for (int i = 0; i < m; ++i) {
    H.row(i) = H3.row(rows[static_cast<size_t>(i)]);
    ym(i) = y(rows[static_cast<size_t>(i)]);
    for (int j = 0; j < m; ++j) Rm(i, j) = R(rows[static_cast<size_t>(i)], rows[static_cast<size_t>(j)]);
  }
  const Eigen::MatrixXd PHt = s_.P * H.transpose();
  const Eigen::MatrixXd S = H * PHt + Rm;
  const Eigen::MatrixXd K = PHt * S.inverse();
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  s_.P = IKH * s_.P * IKH.transpose() + K * Rm * K.transpose();
  Symmetrize(s_.P);
  model_->Correct(s_, K * ym);
}

}  // namespace locaid::fusion
