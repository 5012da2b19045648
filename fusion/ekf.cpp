#include "fusion/ekf.hpp"

#include "fusion/ekf_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace locaid::fusion {
using namespace detail;

Ekf::Ekf(EkfConfig config)
    : config_(config),
      model_(MakeProcessModel(config_)),
      gps_noise_h_(1, {.prior_samples = 2 * config_.gps.noise_prior_fixes,  // E and N: 2 samples per fix
                       .window_samples = 2 * config_.gps.noise_window_fixes,
                       .min_scale = config_.gps.noise_scale_min,
                       .max_scale = config_.gps.noise_scale_max}),
      gps_noise_v_(1, {.prior_samples = config_.gps.noise_prior_fixes,
                       .window_samples = config_.gps.noise_window_fixes,
                       .min_scale = config_.gps.noise_scale_min,
                       .max_scale = config_.gps.noise_scale_max}) {
  gate_h_ = ChiSquareQuantile(config_.gps.gate_probability, 2);
  gate_v_ = ChiSquareQuantile(config_.gps.gate_probability, 1);
  zupt_gate_ = ChiSquareQuantile(config_.vehicle.speed_gate_probability, 3);
}

Mat6 Ekf::VoNoise(const Mat6& reported, const Eigen::Isometry3d& motion) const {
  return model_->VoNoise(reported, motion);
}

// ------------------------------------------------------------------ IMU

void Ekf::PropagateImu(const ImuSample& sample) {
  if (!model_->AddImu(s_, sample)) {
    ++stats_.imu_rejected;
    return;
  }
  last_imu_ns_ = sample.t_ns;
  stillness_.Add(sample, config_.vehicle.zupt_window_s);
}

// ------------------------------------------------------------------ VO

VoUpdate Ekf::ProcessVo(const VoMeasurement& measured, bool vo_ok) {
  // A non-finite motion or covariance is treated as VO lost (and counted);
  // only then is a cleaned copy made.
  VoUpdate out;
  const bool finite = measured.T_prev_curr.matrix().allFinite() && measured.covariance.allFinite();
  VoMeasurement cleaned;  // identity motion and covariance
  if (!finite) {
    out.rejected = vo_ok;
    if (vo_ok) ++stats_.vo_rejected;
    vo_ok = false;
    cleaned.t_prev_ns = measured.t_prev_ns;
    cleaned.t_ns = measured.t_ns;
  }
  const VoMeasurement& m = finite ? measured : cleaned;
  const VoPlan plan = PlanVo(m, vo_ok, out);
  if (!s_.initialized) {
    ChainStartup(m, plan);
    TryInitialize(m.t_ns);
    return out;
  }
  return ApplyVoUpdate(m, plan, out);
}

Ekf::VoPlan Ekf::PlanVo(const VoMeasurement& m, bool vo_ok, VoUpdate& out) {
  // The motion must start at the filter's VO anchor (the last frame VO measured
  // or restarted on). After missing frames it spans several frames; a motion
  // from anywhere else (VO restarted on a frame it reported as lost) cannot be
  // used: the anchor moves to this frame and the next motion starts there.
  VoPlan plan;
  plan.reanchor = vo_ok || !vo_anchor_ns_;
  if (vo_ok && vo_anchor_ns_ && m.t_prev_ns != *vo_anchor_ns_) {
    ++stats_.vo_anchor_mismatches;
    out.anchor_mismatch = true;
    vo_ok = false;
  }
  plan.vo_ok = vo_ok;
  plan.prev_frame_ns = last_frame_ns_.value_or(m.t_prev_ns);
  plan.frame_dt_s = std::max(1e-3, Seconds(m.t_ns, plan.prev_frame_ns));
  const double vo_dt = std::max(1e-3, Seconds(m.t_ns, m.t_prev_ns));
  last_frame_ns_ = m.t_ns;
  plan.motion = m.T_prev_curr;  // from the anchor (vo_ok) or the last frame (coasting)
  if (!vo_ok) {
    // Coast at the last VO velocity.
    plan.motion = Eigen::Isometry3d::Identity();
    plan.motion.translation() = last_vo_velocity_body_mps_ * plan.frame_dt_s;
  } else {
    last_vo_velocity_body_mps_ = plan.motion.translation() / vo_dt;
  }
  // Motion to apply from the last frame: the VO motion minus what was coasted
  // since the anchor (no-IMU propagation and the initialisation chain).
  plan.step = vo_ok ? T_coast_.inverse() * plan.motion : plan.motion;
  T_coast_ = vo_ok || plan.reanchor ? Eigen::Isometry3d::Identity() : T_coast_ * plan.motion;
  if (plan.reanchor) vo_anchor_ns_ = m.t_ns;
  plan.dt_s = vo_ok ? vo_dt : plan.frame_dt_s;
  return plan;
}

void Ekf::ChainStartup(const VoMeasurement& m, const VoPlan& plan) {
  // Attach the buffered fixes of (t_prev, t] to the VO chain (interpolated).
  const Eigen::Isometry3d T_prev = T_start_body_;
  T_start_body_ = T_start_body_ * plan.step;
  for (auto& f : init_fixes_) {
    if (!std::isnan(f.T_start_body.matrix()(0, 0))) continue;
    const double a = std::clamp(Seconds(f.t_ns, plan.prev_frame_ns) / plan.frame_dt_s, 0.0, 1.0);
    f.T_start_body = T_start_body_;
    f.T_start_body.translation() = (1 - a) * T_prev.translation() + a * T_start_body_.translation();
  }
  model_->AddStartupFrame(m, T_start_body_, plan.motion, plan.dt_s, plan.vo_ok);
  s_.t_ns = m.t_ns;
}

VoUpdate Ekf::ApplyVoUpdate(const VoMeasurement& m, const VoPlan& plan, VoUpdate out) {
  VoStep vo;
  vo.t_ns = m.t_ns;
  vo.vo_ok = plan.vo_ok;
  vo.reanchor = plan.reanchor;
  vo.motion = plan.motion;
  vo.step = plan.step;
  vo.R_vo = model_->VoNoise(m.covariance, plan.motion);
  vo.dt_s = plan.dt_s;
  vo.vo_velocity_body_mps = last_vo_velocity_body_mps_;
  vo.learn_noise = LearningVoNoise(m.t_ns);
  if (const std::optional<VoGate> gate = model_->ApplyVo(s_, vo)) {
    stats_.last_vo_nis = out.nis = gate->nis;
    out.rejected = gate->rejected;
    if (gate->rejected) ++stats_.vo_rejected;
  }
  out.used = plan.vo_ok && !out.rejected;
  ApplyVehicleConstraints(m.t_ns, plan.vo_ok);
  return out;
}

bool Ekf::LearningVoNoise(int64_t t_ns) const {
  // GPS holds the state: the last accepted fix is no older than the mode's
  // VO_ONLY threshold (Output).
  return config_.vo.learn_noise && config_.imu.enabled && s_.initialized && last_gps_accepted_ns_ &&
         Seconds(t_ns, *last_gps_accepted_ns_) <= config_.gps.vo_only_after_periods * gps_period_s_ + 2 * gps_lag_s_;
}

// ------------------------------------------------------------------ output

ErrorLayout Ekf::error_layout() const {
  return {model_->StateSize(), model_->AttitudeIndex(), config_.imu.enabled ? kV : -1};
}

FusedPose Ekf::Output(int64_t t_ns, bool vo_ok) const {
  FusedPose out;
  out.t_ns = t_ns;
  out.gps_used = stats_.gps_used;
  out.gps_rejected = stats_.gps_rejected;
  out.gps_resets = stats_.gps_resets;
  out.last_gps_nis = stats_.last_gps_nis;
  out.gps_gate = gate_h_;
  out.seconds_since_gps = last_gps_accepted_ns_ ? Seconds(t_ns, *last_gps_accepted_ns_)
                                                : std::numeric_limits<double>::infinity();
  if (!s_.initialized) {
    out.mode = Mode::kLost;
    out.covariance = Mat6::Identity() * 1e6;
    if (enu_.has_origin()) enu_.ToGeodetic(Vec3::Zero(), out.lat_deg, out.lon_deg, out.alt_m);
    return out;
  }
  out.T_enu_body.linear() = s_.x.R_enu_body;
  out.T_enu_body.translation() = s_.x.p_enu_m;
  out.v_enu_mps = s_.x.v_enu_mps;
  enu_.ToGeodetic(s_.x.p_enu_m, out.lat_deg, out.lon_deg, out.alt_m);
  const int th = model_->AttitudeIndex();
  const Eigen::MatrixXd& P = s_.P;
  out.covariance.block<3, 3>(0, 0) = P.block<3, 3>(0, 0);
  out.covariance.block<3, 3>(0, 3) = P.block<3, 3>(0, th);
  out.covariance.block<3, 3>(3, 0) = P.block<3, 3>(th, 0);
  out.covariance.block<3, 3>(3, 3) = P.block<3, 3>(th, th);
  // Fixes that reach the filter late (a live receiver's latency) are not an
  // outage: twice their recent worst lag is added to the allowance (margin
  // for the jitter of that lag).
  out.speed_scale_error = model_->speed_scale_error();
  out.speed_used = stats_.speed_used;
  out.vo_noise_scale = model_->vo_noise_scale();
  out.gps_noise_scale_h = gps_noise_h_.scale(0);
  out.gps_noise_scale_v = gps_noise_v_.scale(0);
  out.vo_noise_learning = LearningVoNoise(t_ns);
  if (out.seconds_since_gps > config_.gps.vo_only_after_periods * gps_period_s_ + 2 * gps_lag_s_) {
    // Without GPS: VO, else the IMU while its samples keep coming.
    const bool imu_alive = config_.imu.enabled && last_imu_ns_ && Seconds(t_ns, *last_imu_ns_) <= config_.imu.max_gap_s;
    out.mode = vo_ok ? Mode::kVoOnly : imu_alive ? Mode::kDeadReckoning : Mode::kLost;
  } else if (last_gps_rejected_ns_ && Seconds(t_ns, *last_gps_rejected_ns_) < config_.gps.degraded_hold_s) {
    out.mode = Mode::kGpsDegraded;
  } else {
    out.mode = Mode::kGpsFused;
  }
  return out;
}

}  // namespace locaid::fusion
