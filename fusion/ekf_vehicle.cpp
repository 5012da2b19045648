// The EKF's vehicle measurements (IMU mode): speed readings with their scale
// factor, and the car's motion constraints at every frame (non-holonomic:
// no sideways or vertical velocity; zero velocity at a standstill).
#include "fusion/ekf.hpp"
#include "fusion/ekf_internal.hpp"
#include "fusion/imu_stillness.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace locaid::fusion {
namespace detail {

GatedCorrection GatedKalmanUpdate(Eigen::MatrixXd& P, const Eigen::MatrixXd& H, const Eigen::MatrixXd& R,
                                  const Eigen::VectorXd& r, double gate) {
  GatedCorrection out;
  const Eigen::MatrixXd S = H * P * H.transpose() + R;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
  out.nis = r.dot(ldlt.solve(r));
  if (!std::isfinite(out.nis) || (gate > 0 && out.nis > gate)) return out;
  const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
  const Eigen::Index n = P.rows();
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  P = IKH * P * IKH.transpose() + K * R * K.transpose();
  Symmetrize(P);
  out.dx = K * r;
  out.accepted = true;
  return out;
}

}  // namespace detail

using namespace detail;

void ImuStillness::Add(const ImuSample& sample, double window_s) {
  if (!window_.empty() && sample.t_ns <= window_.back().t_ns) return;
  window_.push_back(sample);
  const auto window_ns = static_cast<int64_t>(window_s * kNsPerS);
  while (window_.size() > kMaxSamples || (window_.size() > 1 && window_.back().t_ns - window_.front().t_ns > window_ns))
    window_.pop_front();
}

bool ImuStillness::Still(const StillnessThresholds& t) const {
  if (static_cast<int>(window_.size()) < std::max(2, t.min_samples)) return false;
  Vec3 f_mean = Vec3::Zero(), w_mean = Vec3::Zero();
  for (const ImuSample& s : window_) {
    f_mean += s.accel_mps2;
    w_mean += s.gyro_radps;
  }
  f_mean /= static_cast<double>(window_.size());
  w_mean /= static_cast<double>(window_.size());
  for (const ImuSample& s : window_)
    if ((s.accel_mps2 - f_mean).norm() > t.accel_mps2 || (s.gyro_radps - w_mean).norm() > t.gyro_radps) return false;
  return true;
}

SpeedUpdate Ekf::UpdateSpeed(const SpeedSample& reading) {
  SpeedUpdate out;
  const double sigma = reading.sigma_mps > 0 ? reading.sigma_mps : config_.vehicle.speed_sigma_mps;
  if (!s_.initialized) return out;  // nothing to measure yet: neither used nor refused
  if (!std::isfinite(reading.speed_mps) || !std::isfinite(sigma) || !(sigma > 0)) {
    out.rejected = true;
    ++stats_.speed_rejected;
    return out;
  }
  model_->PropagateTo(s_, reading.t_ns);
  last_speed_ns_ = reading.t_ns;
  last_speed_mps_ = reading.speed_mps;
  std::optional<VehicleGate> gate;
  if (config_.vehicle.constraints && std::abs(reading.speed_mps) < config_.vehicle.zupt_speed_mps) {
    // Gated: a sensor stuck at 0 must not stop a car the filter knows is moving.
    gate = model_->FuseZeroVelocity(s_, config_.vehicle.zupt_sigma_mps, zupt_gate_);
    out.zupt = gate && !gate->rejected;
    if (out.zupt) ++stats_.zupt_updates;
  } else {
    gate = model_->FuseSpeed(s_, reading.speed_mps, sigma, config_.vehicle.R_vehicle_body);
  }
  if (!gate) {
    out.rejected = true;
    ++stats_.speed_rejected;
    return out;
  }
  out.nis = gate->nis;
  out.rejected = gate->rejected;
  out.used = !gate->rejected;
  ++(out.used ? stats_.speed_used : stats_.speed_rejected);
  return out;
}

bool Ekf::Standstill(int64_t t_ns) const {
  // A fresh speed reading decides (it fused its own gated ZUPT when ~0);
  // without one, the IMU still while the filter already believes the car
  // (nearly) stopped.
  constexpr double kSpeedReadingFreshS = 0.2;
  if (FreshSpeedReading(t_ns, kSpeedReadingFreshS)) return false;
  const StillnessThresholds thresholds{config_.vehicle.zupt_window_s, config_.vehicle.zupt_gyro_radps, config_.vehicle.zupt_accel_mps2,
                                       config_.vehicle.zupt_min_samples};
  return s_.x.v_enu_mps.norm() < config_.vehicle.zupt_max_estimated_speed_mps && stillness_.Still(thresholds);
}

std::optional<double> Ekf::FreshSpeedReading(int64_t t_ns, double max_age_s) const {
  if (!last_speed_ns_ || Seconds(t_ns, *last_speed_ns_) > max_age_s) return std::nullopt;
  return last_speed_mps_;
}

bool Ekf::SurelyMovingFasterThan(int64_t t_ns, double speed_mps) const {
  constexpr double kSpeedReadingFreshS = 0.5;  // a few readings of a CAN speed sensor
  if (const std::optional<double> reading = FreshSpeedReading(t_ns, kSpeedReadingFreshS))
    return std::abs(*reading) > speed_mps;
  if (!config_.imu.enabled || !s_.initialized) return false;
  const double v = s_.x.v_enu_mps.norm();
  if (!(v > speed_mps)) return false;
  const Vec3 along = s_.x.v_enu_mps / v;
  const double sigma = std::sqrt(std::max(0.0, along.dot(s_.P.block<3, 3>(kV, kV) * along)));
  return v - 3 * sigma > speed_mps;
}

bool Ekf::VehicleConstraintsActive(bool vo_ok) const {
  return config_.vehicle.constraints &&
         (!config_.vehicle.constraints_need_speed || stats_.speed_used > 0 || !vo_ok);
}

void Ekf::ApplyVehicleConstraints(int64_t t_ns, bool vo_ok) {
  if (!VehicleConstraintsActive(vo_ok) || !s_.initialized) return;
  if (Standstill(t_ns)) {
    // Stillness only holds a car already believed stopped: no gate.
    if (const auto g = model_->FuseZeroVelocity(s_, config_.vehicle.zupt_sigma_mps, 0); g && !g->rejected)
      ++stats_.zupt_updates;
    return;
  }
  const auto g = model_->FuseNonHolonomic(s_, config_.vehicle.R_vehicle_body,
                                          {config_.vehicle.nhc_sigma_lateral_mps, config_.vehicle.nhc_sigma_vertical_mps});
  if (g && !g->rejected) ++stats_.nhc_updates;
}

}  // namespace locaid::fusion
