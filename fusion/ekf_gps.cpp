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

GpsUpdate Ekf::UpdateGps(const GpsFix& fix) {
  // Non-finite fixes or sigmas are refused before they can set the ENU origin
  // or reach the covariance.
  if (!GpsFixUsable(fix)) return RefuseGps(fix);
  const Vec3 z = GpsEnu(fix);
  TrackGpsPeriod(fix.t_ns);
  if (!s_.initialized) {
    // The start-up fit weighs fixes by their horizontal sigma; the fix joins
    // the VO chain at the next frame (T_start_body NaN until then).
    const double sigma_v = fix.has_altitude ? fix.vertical_sigma_m() : std::numeric_limits<double>::quiet_NaN();
    init_fixes_.push_back({fix.t_ns, z, fix.horizontal_sigma_m(), sigma_v, Eigen::Isometry3d::Identity()});
    init_fixes_.back().T_start_body.matrix()(0, 0) = std::numeric_limits<double>::quiet_NaN();
    return {.buffered = true};
  }
  model_->PropagateTo(s_, fix.t_ns);
  TrackGpsLag(fix.t_ns);
  const GpsModel m = PredictGps(fix);
  GpsUpdate u = GateAndFuse(fix, z - m.predicted, m);
  if (u.used) FuseGpsVelocity(fix, m.late_s);
  return u;
}

GpsUpdate Ekf::RefuseGps(const GpsFix& fix) {
  ++stats_.gps_rejected;
  last_gps_rejected_ns_ = fix.t_ns;
  return {.rejected = true, .gate = s_.initialized ? gate_h_ : 0.0};
}

void Ekf::TrackGpsPeriod(int64_t t_ns) {
  if (last_gps_received_ns_) {
    const double interval = Seconds(t_ns, *last_gps_received_ns_);
    if (interval > 0) {
      if (stats_.gps_used + stats_.gps_rejected <= 1) gps_period_s_ = interval;
      else if (interval < 3 * gps_period_s_) gps_period_s_ = 0.8 * gps_period_s_ + 0.2 * interval;
    }
  }
  last_gps_received_ns_ = t_ns;
}

void Ekf::TrackGpsLag(int64_t t_ns) {
  // How late fixes arrive after their frames: the recent worst, slowly
  // forgotten (a receiver's latency jitters).
  gps_lag_s_ = std::max(0.95 * gps_lag_s_, std::max(0.0, Seconds(last_frame_ns_.value_or(t_ns), t_ns)));
}

Ekf::GpsModel Ekf::PredictGps(const GpsFix& fix) const {
  // The antenna, latency before the state time (lever arm and latency; both
  // 0 by default). A fix older than the state (it arrived after later IMU
  // data, as live fixes do) is compared with where the antenna was then.
  GpsModel m;
  m.late_s = model_->GpsLateness(s_, fix.t_ns);
  const double latency_s = config_.gps.latency_s + m.late_s;
  m.predicted =
      GpsAntennaPrediction(s_.x.p_enu_m, s_.x.v_enu_mps, s_.x.R_enu_body, config_.gps.lever_arm_body_m, latency_s);
  m.R = Mat3::Zero();
  if (fix.cov_enu_m2) {
    m.R = *fix.cov_enu_m2;
  } else {
    m.R.diagonal() << fix.sigma_h_m * fix.sigma_h_m, fix.sigma_h_m * fix.sigma_h_m, fix.sigma_v_m * fix.sigma_v_m;
  }
  model_->ExtrapolateGps(s_, fix.t_ns, m.predicted, m.R);
  m.R_stated = m.R;
  const double h = std::sqrt(gps_noise_h_.scale(0));
  const Vec3 d(h, h, std::sqrt(gps_noise_v_.scale(0)));
  m.R = d.asDiagonal() * m.R * d.asDiagonal();
  m.H = model_->GpsJacobian(s_, GpsAntennaJacobian(s_.x.R_enu_body, config_.gps.lever_arm_body_m, latency_s));
  return m;
}

GpsUpdate Ekf::GateAndFuse(const GpsFix& fix, const Vec3& y, const GpsModel& m) {
  // Horizontal (E, N) and vertical (U) are gated on their own, so that a
  // vertical disagreement does not throw away the horizontal information. A
  // 2-D fix has no altitude to fuse (not a rejection either).
  const GpsGateResult gate = GateGps(y, m.R, m.H);
  LearnGpsNoise(y, m, gate, fix.has_altitude);
  const bool fuse_v = fix.has_altitude;
  const bool use_h = gate.h_ok, use_v = gate.v_ok && fuse_v;
  // A run of rejections means the filter, not the GPS, is off (an open-sky
  // receiver does not fail 3 times in a row at the 0.1 % gate): reset the
  // rejected component's position covariance to cover the innovation, so the
  // fix is taken and the state snaps back to GPS. Counted on the pose.
  const int reset_after = std::max(1, config_.gps.reset_after_rejections);
  const bool reset_h = !use_h && std::isfinite(gate.nis_h) && ++rejections_h_ > reset_after;
  const bool reset_v = fuse_v && !use_v && std::isfinite(gate.nis_v) && ++rejections_v_ > reset_after;
  // The reset uses the fix for its component(s); a passing other component
  // gets the normal update (its innovation is unchanged by the reset).
  if (reset_h || reset_v) ResetPositionToGps(y, m.R, reset_h, reset_v);
  if ((use_h && !reset_h) || (use_v && !reset_v)) ApplyGpsUpdate(y, m.R, m.H, use_h && !reset_h, use_v && !reset_v);
  return CountGpsOutcome(fix, gate, use_h || reset_h, fuse_v ? use_v || reset_v : true, reset_h || reset_v);
}

void Ekf::LearnGpsNoise(const Vec3& y, const GpsModel& m, const GpsGateResult& gate, bool has_altitude) {
  // A component the gate passed teaches its scale (a multipath jump the gate
  // refuses is not the receiver's noise: urban-canyon's 3 % of 20 m jumps
  // took the horizontal scale to 1.21 and the RMSE from 1.34 to 1.38 m when
  // they did), while the prediction is at most 4x looser than the fix (else
  // the sample is mostly the filter's own uncertainty: after an outage, at
  // start-up). E and N are two samples of the horizontal scale. A receiver
  // that understates its noise still teaches it: the fixes it gets through
  // the gate grow the scale, which lets more through (3x: scale ~9).
  if (!config_.gps.learn_noise) return;
  const Vec3& hph = gate.predicted_var;
  for (int i = 0; i < 3; ++i) {
    if (!(i < 2 ? gate.h_ok : gate.v_ok && has_altitude)) continue;
    NoiseScaleEstimator& est = i < 2 ? gps_noise_h_ : gps_noise_v_;
    const double r0 = m.R_stated(i, i);
    if (hph[i] <= 4 * est.scale(0) * r0) est.Add(0, y[i], hph[i], r0);
  }
}

GpsUpdate Ekf::CountGpsOutcome(const GpsFix& fix, const GpsGateResult& gate, bool use_h, bool use_v, bool reset) {
  // use_v is true for a 2-D fix: nothing vertical to refuse. A fix counts as
  // used when its horizontal part is fused (a vertical-only update is
  // reported as a rejection); vertical rejections are counted apart.
  stats_.last_gps_nis = gate.nis_h;
  stats_.last_gps_nis_vertical = gate.nis_v;
  if (use_h) rejections_h_ = 0;
  if (use_v && fix.has_altitude) rejections_v_ = 0;
  if (!use_v) ++stats_.gps_rejected_vertical;
  if (!use_h || !use_v) last_gps_rejected_ns_ = fix.t_ns;  // GPS_DEGRADED for a while
  if (use_h) {
    ++stats_.gps_used;
    last_gps_accepted_ns_ = fix.t_ns;
  } else {
    ++stats_.gps_rejected;
  }
  return {.used = use_h, .rejected = !use_h, .rejected_vertical = !use_v, .reset = reset,
          .nis = gate.nis_h, .nis_vertical = gate.nis_v, .gate = gate_h_};
}

void Ekf::FuseGpsVelocity(const GpsFix& fix, double late_s) {
  // The fix's velocity, where velocity is a state (IMU model).
  if (!fix.v_enu_mps) return;
  if (const std::optional<bool> used = model_->FuseGpsVelocity(s_, fix, late_s)) {
    if (*used) ++stats_.gps_velocity_used;
    else ++stats_.gps_velocity_rejected;
  }
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
  const Mat3 HPHt = H * s_.P * H.transpose();
  const Mat3 S = HPHt + R;
  GpsGateResult g;
  g.predicted_var = HPHt.diagonal();
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
  ++stats_.gps_resets;
  if (s_.log) s_.log->Start(s_);  // not a linear-Gaussian step: a smoother's chain breaks here
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
