// The EKF's start-up: heading from fitting the VO track to the first fixes,
// tilt from the gravity fit, and the initial covariance.
#include "fusion/ekf.hpp"

#include "fusion/ekf_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace locaid::fusion {

using namespace detail;

// ------------------------------------------------------------------ init

void Ekf::TryInitialize(int64_t t_ns) {
  const std::vector<const InitFix*> fixes = ChainedInitFixes();
  const int min_fixes = std::max(2, config_.startup.min_fixes);
  if (static_cast<int>(fixes.size()) < min_fixes) return;
  const double sigma_h = fixes.back()->sigma_h;
  const double min_baseline = std::max(config_.startup.min_baseline_m, config_.startup.min_baseline_sigmas * sigma_h);
  if (!InitBaselineReached(fixes, min_baseline)) return;
  // Roll / pitch of the start frame from gravity (IMU), else level.
  Mat3 R_level_start = Mat3::Identity();
  double tilt_var = std::pow(config_.startup.roll_pitch_sigma_rad, 2);
  model_->LevelStart(R_level_start, tilt_var);
  const HeadingFit fit = FitHeading(fixes, R_level_start, sigma_h);
  if (fit.used < min_fixes || fit.spread2 < min_baseline * min_baseline / 4) return;
  // Fixes that scatter more than they state (a receiver that claims 1 m and
  // delivers 3 m) would give a heading fit trusted far beyond its error (0.9
  // rad off with a 0.06 rad sigma, in a test): the start-up then uses the
  // fit's residual sigma, and waits for the baseline that one needs. Only a
  // scatter beyond twice the stated sigma counts: a receiver stating its true sigma gets there with probability
  // ~1e-5 over the fit's 9 degrees of freedom, while a chance scatter above
  // it would only delay and weaken its start-up.
  const double scatter = std::sqrt(fit.residual_var);
  const double sigma_eff = scatter > 2 * sigma_h ? scatter : sigma_h;
  if (sigma_eff > sigma_h &&
      !InitBaselineReached(fixes, std::max(config_.startup.min_baseline_m, config_.startup.min_baseline_sigmas * sigma_eff)))
    return;
  if (config_.gps.learn_noise && sigma_h > 0) {
    // The fit's residuals teach the GPS scales too (one sample per fix and
    // axis; the prediction is the fit itself).
    const double sigma_v = fixes.back()->sigma_v;  // NaN for a 2-D fix
    const bool heights = std::all_of(fixes.begin(), fixes.end(), [](const InitFix* f) { return std::isfinite(f->sigma_v); });
    for (int i = 0; i < 2 * fit.used; ++i) gps_noise_h_.Add(0, std::sqrt(fit.residual_var), 0.0, sigma_h * sigma_h);
    if (heights && sigma_v > 0) {
      for (int i = 0; i < fit.used; ++i) gps_noise_v_.Add(0, std::sqrt(fit.residual_var_v), 0.0, sigma_v * sigma_v);
    }
  }
  InitializeState(fit, R_level_start, tilt_var, sigma_eff);
  s_.t_ns = t_ns;
  s_.initialized = true;
  if (s_.log) s_.log->Start(s_);  // a smoother's chain starts with the filter
  stats_.gps_used += fit.used;
  stats_.gps_rejected += static_cast<int>(fixes.size()) - fit.used;
  last_gps_accepted_ns_ = fixes.back()->t_ns;
  init_fixes_.clear();
}

std::vector<const Ekf::InitFix*> Ekf::ChainedInitFixes() const {
  // Fixes already attached to the VO chain.
  std::vector<const InitFix*> fixes;
  for (const auto& f : init_fixes_)
    if (!std::isnan(f.T_start_body.matrix()(0, 0))) fixes.push_back(&f);
  return fixes;
}

bool Ekf::InitBaselineReached(const std::vector<const InitFix*>& fixes, double min_baseline) const {
  double gps_span = 0, vo_span = 0;
  for (const auto* f : fixes) {
    gps_span = std::max(gps_span, (f->p_enu.head<2>() - fixes.front()->p_enu.head<2>()).norm());
    vo_span = std::max(vo_span, (f->T_start_body.translation() - fixes.front()->T_start_body.translation()).norm());
  }
  return gps_span >= min_baseline && vo_span >= 0.5 * min_baseline;
}

Ekf::HeadingFit Ekf::FitHeading(const std::vector<const InitFix*>& fixes, const Mat3& R_level_start,
                                double sigma_h) {
  // 2D Procrustes: p_i ~= Rz(psi) q_i + t, robust (drop > 3.5 sigma, twice).
  std::vector<char> use(fixes.size(), 1);
  auto q_of = [&](size_t i) -> Vec3 { return R_level_start * fixes[i]->T_start_body.translation(); };
  HeadingFit fit;
  for (int iter = 0; iter < 3; ++iter) {
    fit.p_mean.setZero(); fit.q_mean.setZero(); fit.z_off = 0; fit.used = 0;
    for (size_t i = 0; i < fixes.size(); ++i) {
      if (!use[i]) continue;
      const Vec3 q = q_of(i);
      fit.p_mean += fixes[i]->p_enu.head<2>(); fit.q_mean += q.head<2>();
      fit.z_off += fixes[i]->p_enu.z() - q.z();
      ++fit.used;
    }
    if (fit.used < 2) return fit;
    fit.p_mean /= fit.used; fit.q_mean /= fit.used; fit.z_off /= fit.used;
    double sxx = 0, sxy = 0;
    fit.spread2 = 0;
    for (size_t i = 0; i < fixes.size(); ++i) {
      if (!use[i]) continue;
      const Eigen::Vector2d q = q_of(i).head<2>() - fit.q_mean;
      const Eigen::Vector2d p = fixes[i]->p_enu.head<2>() - fit.p_mean;
      sxx += q.dot(p);
      sxy += q.x() * p.y() - q.y() * p.x();
      fit.spread2 += q.squaredNorm();
    }
    fit.psi = std::atan2(sxy, sxx);
    const Eigen::Rotation2Dd Rz(fit.psi);
    bool changed = false;
    for (size_t i = 0; i < fixes.size(); ++i) {
      const double res = (fixes[i]->p_enu.head<2>() - (Rz * (q_of(i).head<2>() - fit.q_mean) + fit.p_mean)).norm();
      const char keep = res < 3.5 * sigma_h + 1.0;
      if (keep != use[i]) { use[i] = keep; changed = true; }
    }
    if (!changed) break;
  }
  // Residual variance per axis of the fixes used: 2 values each, 3 fitted
  // (translation, heading).
  double sum2 = 0;
  const Eigen::Rotation2Dd Rz(fit.psi);
  for (size_t i = 0; i < fixes.size(); ++i) {
    if (use[i]) sum2 += (fixes[i]->p_enu.head<2>() - (Rz * (q_of(i).head<2>() - fit.q_mean) + fit.p_mean)).squaredNorm();
  }
  fit.residual_var = fit.used >= 2 ? sum2 / std::max(1, 2 * fit.used - 3) : 0.0;
  // Vertical: the fixes' heights about the VO track's, one offset fitted.
  double sum2_v = 0;
  for (size_t i = 0; i < fixes.size(); ++i) {
    if (use[i]) sum2_v += std::pow(fixes[i]->p_enu.z() - (q_of(i).z() + fit.z_off), 2);
  }
  fit.residual_var_v = fit.used >= 2 ? sum2_v / (fit.used - 1) : 0.0;
  return fit;
}

void Ekf::InitializeState(const HeadingFit& fit, const Mat3& R_level_start, double tilt_var, double sigma_h) {
  const Mat3 R_enu_start = Eigen::AngleAxisd(fit.psi, Vec3::UnitZ()).toRotationMatrix() * R_level_start;
  const Vec3 q_now = R_level_start * T_start_body_.translation();
  const Eigen::Vector2d p_now_xy = Eigen::Rotation2Dd(fit.psi) * (q_now.head<2>() - fit.q_mean) + fit.p_mean;
  s_.x = NominalState{};
  s_.x.p_enu_m = Vec3(p_now_xy.x(), p_now_xy.y(), q_now.z() + fit.z_off);
  s_.x.R_enu_body = R_enu_start * T_start_body_.linear();
  s_.x.v_enu_mps = s_.x.R_enu_body * last_vo_velocity_body_mps_;
  // Covariance: centroid noise + yaw lever arm.
  const double k = std::max(1.0, config_.startup.cov_inflation);
  const double var_c = k * sigma_h * sigma_h / fit.used;
  const double sigma_psi = std::sqrt(k) * sigma_h / std::sqrt(fit.spread2);
  const Vec3 lever(p_now_xy.x() - fit.p_mean.x(), p_now_xy.y() - fit.p_mean.y(), 0);
  const Vec3 J_psi = Vec3::UnitZ().cross(lever);
  const int n = model_->StateSize();
  const int th = model_->AttitudeIndex();
  Eigen::MatrixXd& P = s_.P;
  P = Eigen::MatrixXd::Zero(n, n);
  const double sigma_v = std::max(3.0, 1.5 * sigma_h);
  P.block<3, 3>(0, 0).diagonal() << var_c, var_c, sigma_v * sigma_v / fit.used;
  P.block<3, 3>(0, 0) += J_psi * J_psi.transpose() * sigma_psi * sigma_psi;
  P.block<3, 3>(th, th).diagonal() << tilt_var, tilt_var, sigma_psi * sigma_psi;
  P.block<3, 1>(0, th + 2) = J_psi * sigma_psi * sigma_psi;
  P.block<1, 3>(th + 2, 0) = (J_psi * sigma_psi * sigma_psi).transpose();
  model_->Initialize(s_);
}

}  // namespace locaid::fusion
