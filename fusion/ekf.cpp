#include "fusion/ekf.hpp"

#include "fusion/ekf_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace locaid::fusion {
namespace {

using namespace detail;
constexpr double kMaxImuStepS = 0.01;

}  // namespace

Mat6 VoNoiseModel(const EkfConfig& config, const Mat6& reported, const Eigen::Isometry3d& motion) {
  Mat6 Rvo = reported * config.vo_cov_scale;
  // Relative term only where VO is a measurement checked against the IMU; in
  // no-IMU mode it would only inflate the propagation noise (sim: worse GPS smoothing).
  const Vec3 per_m(config.vo_sigma_t_per_m, config.vo_sigma_lateral_per_m, config.vo_sigma_vertical_per_m);
  const Vec3 sigma_rel = config.use_imu ? Vec3(per_m * motion.translation().norm()) : Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    Rvo(i, i) += sigma_rel[i] * sigma_rel[i];
    Rvo(i, i) = std::max(Rvo(i, i), std::pow(config.vo_min_sigma_t_m, 2));
    Rvo(i + 3, i + 3) = std::max(Rvo(i + 3, i + 3), std::pow(config.vo_min_sigma_rot_rad, 2));
  }
  return Rvo;
}

Ekf::Ekf(EkfConfig config) : config_(config) {
  gate_h_ = ChiSquareQuantile(config_.gps_gate_probability, 2);
  gate_v_ = ChiSquareQuantile(config_.gps_gate_probability, 1);
  gate_vel_ = ChiSquareQuantile(config_.gps_gate_probability, 3);
  vo_gate_ = ChiSquareQuantile(config_.vo_gate_probability, 6);
}

// ------------------------------------------------------------------ IMU

void Ekf::PropagateImu(const ImuSample& sample) {
  if (!config_.use_imu) return;
  // A non-finite sample would poison the state: refuse and count it.
  if (!sample.accel_mps2.allFinite() || !sample.gyro_radps.allFinite()) {
    ++imu_rejected_;
    return;
  }
  if (!initialized_) {
    init_accel_.push_back(sample.accel_mps2);
    last_imu_ = sample;
    return;
  }
  if (sample.t_ns > t_ns_ && last_imu_) {
    // Interval [t_ns_, sample.t_ns]: mean of the two samples bounding it.
    ImuSample mid = *last_imu_;
    mid.accel_mps2 = 0.5 * (last_imu_->accel_mps2 + sample.accel_mps2);
    mid.gyro_radps = 0.5 * (last_imu_->gyro_radps + sample.gyro_radps);
    last_imu_ = mid;
    PropagateTo(sample.t_ns);
  }
  last_imu_ = sample;
}

void Ekf::PropagateTo(int64_t t_ns) {
  if (!config_.use_imu || !initialized_ || t_ns <= t_ns_) return;
  const double total = Seconds(t_ns, t_ns_);
  const Vec3 f = last_imu_ ? last_imu_->accel_mps2 : Vec3(0, 0, config_.gravity_mps2);
  const Vec3 w = last_imu_ ? last_imu_->gyro_radps : Vec3::Zero();
  const Vec3 g(0, 0, -config_.gravity_mps2);
  // Long gaps: the held sample is stale; inflate the noise accordingly.
  const double gap_scale = total > config_.max_imu_gap_s ? total / config_.max_imu_gap_s : 1.0;
  // The IMU's own noise densities when its samples state them.
  const double accel_noise = last_imu_ && last_imu_->accel_noise_mps2_sqrt_hz > 0
                                 ? last_imu_->accel_noise_mps2_sqrt_hz
                                 : config_.accel_noise_mps2_sqrt_hz;
  const double gyro_noise = last_imu_ && last_imu_->gyro_noise_radps_sqrt_hz > 0
                                ? last_imu_->gyro_noise_radps_sqrt_hz
                                : config_.gyro_noise_radps_sqrt_hz;
  const int steps = std::max(1, static_cast<int>(std::ceil(total / kMaxImuStepS)));
  const double dt = total / steps;
  for (int i = 0; i < steps; ++i) {
    const Mat15 F = ImuTransitionJacobian(x_, f, w, dt);
    const Mat15 Q = ImuProcessNoise(x_, dt, accel_noise * gap_scale, gyro_noise * gap_scale,
                                    config_.accel_bias_walk_mps3_sqrt_hz,
                                    config_.gyro_bias_walk_radps2_sqrt_hz);
    x_ = fusion::PropagateImu(x_, f, w, dt, g);
    const Eigen::MatrixXd P15 = P_.topLeftCorner<15, 15>();
    const Eigen::Index rest = P_.cols() - 15;  // clone and VO calibration
    P_.topLeftCorner<15, 15>() = F * P15 * F.transpose() + Q;
    P_.topRightCorner(15, rest) = F * P_.topRightCorner(15, rest);
    P_.bottomLeftCorner(rest, 15) = P_.topRightCorner(15, rest).transpose();
  }
  Symmetrize(P_);
  t_ns_ = t_ns;
}

// ------------------------------------------------------------------ VO

void Ekf::ProcessVo(const VoMeasurement& measured, bool vo_ok) {
  // A non-finite motion or covariance is treated as VO lost (and counted);
  // only then is a cleaned copy made.
  const bool finite = measured.T_prev_curr.matrix().allFinite() && measured.covariance.allFinite();
  VoMeasurement cleaned;  // identity motion and covariance
  if (!finite) {
    if (vo_ok) ++vo_rejected_;
    vo_ok = false;
    cleaned.t_prev_ns = measured.t_prev_ns;
    cleaned.t_ns = measured.t_ns;
  }
  const VoMeasurement& m = finite ? measured : cleaned;
  // The motion must start at the filter's VO anchor (the last frame VO measured
  // or restarted on). After missing frames it spans several frames; a motion
  // from anywhere else (VO restarted on a frame it reported as lost) cannot be
  // used: the anchor moves to this frame and the next motion starts there.
  bool reanchor = vo_ok;
  if (vo_ok && vo_anchor_ns_ && m.t_prev_ns != *vo_anchor_ns_) {
    ++vo_anchor_mismatches_;
    vo_ok = false;
  }
  const int64_t prev_frame_ns = last_frame_ns_.value_or(m.t_prev_ns);
  const double frame_dt = std::max(1e-3, Seconds(m.t_ns, prev_frame_ns));
  const double vo_dt = std::max(1e-3, Seconds(m.t_ns, m.t_prev_ns));
  last_frame_ns_ = m.t_ns;
  if (!vo_anchor_ns_) reanchor = true;
  Eigen::Isometry3d motion = m.T_prev_curr;  // from the anchor (vo_ok) or the last frame (coasting)
  if (!vo_ok) {
    // Coast at the last VO velocity.
    motion = Eigen::Isometry3d::Identity();
    motion.translation() = last_vo_velocity_body_mps_ * frame_dt;
  } else {
    last_vo_velocity_body_mps_ = motion.translation() / vo_dt;
  }
  Mat6 Rvo = VoNoiseModel(config_, m.covariance, motion);
  if (config_.use_imu && config_.adaptive_vo_rotation_noise)
    for (int i = 0; i < 3; ++i) Rvo(3 + i, 3 + i) *= vo_rotation_noise_scale_[i];
  // Motion to apply from the last frame: the VO motion minus what was coasted
  // since the anchor (no-IMU propagation and the initialisation chain).
  const Eigen::Isometry3d step = vo_ok ? T_coast_.inverse() * motion : motion;
  T_coast_ = vo_ok ? Eigen::Isometry3d::Identity() : T_coast_ * motion;
  if (reanchor) {
    vo_anchor_ns_ = m.t_ns;
    T_coast_ = Eigen::Isometry3d::Identity();
  }
  const double dt = vo_ok ? vo_dt : frame_dt;

  if (!initialized_) {
    // Attach the buffered fixes of (t_prev, t] to the VO chain (interpolated).
    const Eigen::Isometry3d T_prev = T_start_body_;
    T_start_body_ = T_start_body_ * step;
    for (auto& f : init_fixes_) {
      if (!std::isnan(f.T_start_body.matrix()(0, 0))) continue;
      const double a = std::clamp(Seconds(f.t_ns, prev_frame_ns) / frame_dt, 0.0, 1.0);
      f.T_start_body = T_start_body_;
      f.T_start_body.translation() = (1 - a) * T_prev.translation() + a * T_start_body_.translation();
    }
    // Specific force and VO position in the start frame, for the gravity fit
    // (FitGravity) at initialisation; coasted frames carry no position.
    if (!init_accel_.empty() && vo_ok) {
      Vec3 f_mean = Vec3::Zero();
      for (const auto& a : init_accel_) f_mean += a;
      f_mean /= static_cast<double>(init_accel_.size());
      GravitySample g;
      g.t_s = Seconds(m.t_ns, m.t_prev_ns) * 0.5 + Seconds(m.t_prev_ns, init_fit_t0_ns_.value_or(m.t_prev_ns));
      if (!init_fit_t0_ns_) init_fit_t0_ns_ = m.t_prev_ns;
      g.R_start_body = T_start_body_.linear();
      g.f_body_mps2 = f_mean;
      g.v_body_mps = motion.translation() / dt;
      g.w_body_radps = LogSO3(motion.linear()) / dt;
      init_gravity_.push_back(g);
    }
    init_accel_.clear();
    t_ns_ = m.t_ns;
    TryInitialize(m.t_ns);
    return;
  }

  if (!config_.use_imu) {
    Mat6 F = OdometryTransitionJacobian(x_.R_enu_body, step);
    Mat6 G = OdometryNoiseJacobian(x_.R_enu_body, step);
    if (!vo_ok) {
      Rvo.setZero();
      Rvo.topLeftCorner<3, 3>().diagonal().setConstant(std::pow(config_.no_imu_lost_sigma_mps * dt, 2));
      Rvo.bottomRightCorner<3, 3>().diagonal().setConstant(std::pow(0.05 * dt, 2));
    }
    OdometryPropagate(x_.p_enu_m, x_.R_enu_body, step);
    P_ = F * P_ * F.transpose() + G * Rvo * G.transpose();
    Symmetrize(P_);
    x_.v_enu_mps = x_.R_enu_body * last_vo_velocity_body_mps_;
    t_ns_ = m.t_ns;
    return;
  }

  PropagateTo(m.t_ns);
  if (vo_ok) {
    // The VO translation with the estimated boresight and scale removed.
    Eigen::Isometry3d corrected = motion;
    corrected.translation() = CorrectVoTranslation(motion.translation(), R_boresight_, vo_scale_error_);
    const Vec6 r = VoResidual(x_.p_enu_m, x_.R_enu_body, p_clone_, R_clone_, corrected);
    const MatVoH Hs = VoJacobian(x_.p_enu_m, x_.R_enu_body, p_clone_, R_clone_, corrected);
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, P_.rows());
    H.middleCols<3>(kP) = Hs.middleCols<3>(0);
    H.middleCols<3>(kTh) = Hs.middleCols<3>(3);
    H.middleCols<3>(kPc) = Hs.middleCols<3>(6);
    H.middleCols<3>(kThc) = Hs.middleCols<3>(9);
    H.middleCols<kVoCalibStates>(kCal) =
        VoCalibrationJacobian(motion.linear(), motion.translation(), R_boresight_, vo_scale_error_);
    const Mat6 S = H * P_ * H.transpose() + Rvo;
    const double nis = r.dot(S.ldlt().solve(r));
    last_vo_nis_ = nis;
    AdaptVoRotationNoise(r.tail<3>(), S.bottomRightCorner<3, 3>());
    const bool gate_ok = std::isfinite(nis) && nis < vo_gate_;
    // A run of rejections means the prediction, not the VO, is off: accept.
    if (gate_ok || (std::isfinite(nis) && ++vo_consecutive_rejections_ > 2)) {
      if (gate_ok) vo_consecutive_rejections_ = 0;
      const Eigen::MatrixXd K = P_ * H.transpose() * S.inverse();
      const int n = static_cast<int>(P_.rows());
      const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
      P_ = IKH * P_ * IKH.transpose() + K * Rvo * K.transpose();
      Symmetrize(P_);
      Correct(K * r);
    }
    if (!gate_ok) ++vo_rejected_;
  }
  if (reanchor) Clone();  // else the clone stays at the anchor the next motion starts from
}


void Ekf::AdaptVoRotationNoise(const Vec3& r_rot, const Mat3& S_rot) {
  if (!config_.adaptive_vo_rotation_noise) return;
  // Per body axis: mean normalised squared rotation innovation (1 when
  // consistent); one outlier moves it by at most 10 x the rate.
  constexpr double kRate = 0.05;
  const double max_scale = std::max(1.0, config_.adaptive_vo_rotation_noise_max_scale);
  for (int i = 0; i < 3; ++i) {
    const double q = r_rot[i] * r_rot[i] / S_rot(i, i);
    if (!std::isfinite(q)) return;
    rot_nis_mean_[i] = (1 - kRate) * rot_nis_mean_[i] + kRate * std::min(q, 10.0);
    vo_rotation_noise_scale_[i] =
        std::clamp(vo_rotation_noise_scale_[i] * std::pow(rot_nis_mean_[i], kRate), 1.0, max_scale);
  }
}

void Ekf::Clone() {
  p_clone_ = x_.p_enu_m;
  R_clone_ = x_.R_enu_body;
  const int n = static_cast<int>(P_.rows());
  Eigen::MatrixXd J = Eigen::MatrixXd::Identity(n, n);
  J.block<3, 3>(kPc, kPc).setZero();
  J.block<3, 3>(kThc, kThc).setZero();
  J.block<3, 3>(kPc, kP).setIdentity();
  J.block<3, 3>(kThc, kTh).setIdentity();
  P_ = J * P_ * J.transpose();
  Symmetrize(P_);
}

void Ekf::Correct(const Eigen::VectorXd& dx) {
  if (!dx.allFinite()) return;
  if (config_.use_imu) {
    x_ = BoxPlus(x_, dx.head<15>());
    p_clone_ += dx.segment<3>(kPc);
    R_clone_ = ExpSO3(dx.segment<3>(kThc)) * R_clone_;
    R_boresight_ = ExpSO3(dx.segment<3>(kCal)) * R_boresight_;
    vo_scale_error_ += dx(kCal + 3);
  } else {
    x_.p_enu_m += dx.head<3>();
    x_.R_enu_body = ExpSO3(dx.segment<3>(3)) * x_.R_enu_body;
  }
}

// ------------------------------------------------------------------ output

FusedPose Ekf::Output(int64_t t_ns, bool vo_ok) const {
  FusedPose out;
  out.t_ns = t_ns;
  out.gps_used = gps_used_;
  out.gps_rejected = gps_rejected_;
  out.gps_resets = gps_resets_;
  out.last_gps_nis = last_nis_;
  out.gps_gate = gate_h_;
  out.seconds_since_gps = last_gps_accepted_ns_ ? Seconds(t_ns, *last_gps_accepted_ns_)
                                                : std::numeric_limits<double>::infinity();
  if (!initialized_) {
    out.mode = Mode::kLost;
    out.covariance = Mat6::Identity() * 1e6;
    if (enu_.has_origin()) enu_.ToGeodetic(Vec3::Zero(), out.lat_deg, out.lon_deg, out.alt_m);
    return out;
  }
  out.T_enu_body.linear() = x_.R_enu_body;
  out.T_enu_body.translation() = x_.p_enu_m;
  out.v_enu_mps = x_.v_enu_mps;
  enu_.ToGeodetic(x_.p_enu_m, out.lat_deg, out.lon_deg, out.alt_m);
  const int th = config_.use_imu ? kTh : 3;
  out.covariance.block<3, 3>(0, 0) = P_.block<3, 3>(0, 0);
  out.covariance.block<3, 3>(0, 3) = P_.block<3, 3>(0, th);
  out.covariance.block<3, 3>(3, 0) = P_.block<3, 3>(th, 0);
  out.covariance.block<3, 3>(3, 3) = P_.block<3, 3>(th, th);
  // Fixes that reach the filter late (a live receiver's latency) are not an
  // outage: twice their recent worst lag is added to the allowance (margin
  // for the jitter of that lag).
  if (out.seconds_since_gps > config_.vo_only_after_periods * gps_period_s_ + 2 * gps_lag_s_) {
    out.mode = vo_ok ? Mode::kVoOnly : Mode::kLost;
  } else if (last_gps_rejected_ns_ && Seconds(t_ns, *last_gps_rejected_ns_) < config_.degraded_hold_s) {
    out.mode = Mode::kGpsDegraded;
  } else {
    out.mode = Mode::kGpsFused;
  }
  return out;
}

}  // namespace locaid::fusion
