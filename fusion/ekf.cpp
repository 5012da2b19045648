#include "fusion/ekf.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace locaid::fusion {
namespace {

constexpr double kNsPerS = 1e9;
constexpr int kP = 0, kV = 3, kTh = 6, kBa = 9, kBg = 12, kPc = 15, kThc = 18;  // IMU layout
constexpr int kCal = 21;  // VO boresight (3) and scale (1), IMU mode
constexpr double kMaxImuStepS = 0.01;

double Seconds(int64_t a_ns, int64_t b_ns) { return static_cast<double>(a_ns - b_ns) / kNsPerS; }

void Symmetrize(Eigen::MatrixXd& P) { P = 0.5 * (P + P.transpose()).eval(); }

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
  const int steps = std::max(1, static_cast<int>(std::ceil(total / kMaxImuStepS)));
  const double dt = total / steps;
  for (int i = 0; i < steps; ++i) {
    const Mat15 F = ImuTransitionJacobian(x_, f, w, dt);
    const Mat15 Q = ImuProcessNoise(x_, dt, config_.accel_noise_mps2_sqrt_hz * gap_scale,
                                    config_.gyro_noise_radps_sqrt_hz * gap_scale,
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

// ------------------------------------------------------------------ GPS

Vec3 Ekf::GpsEnu(const GpsFix& fix) {
  if (!enu_.has_origin()) enu_.SetOrigin(fix.lat_deg, fix.lon_deg, fix.alt_m);
  return enu_.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m);
}

bool Ekf::UpdateGps(const GpsFix& fix) {
  // Non-finite fixes or sigmas are refused before they can set the ENU origin
  // or reach the covariance.
  if (!std::isfinite(fix.lat_deg) || !std::isfinite(fix.lon_deg) || !std::isfinite(fix.alt_m) ||
      !std::isfinite(fix.sigma_h_m) || !std::isfinite(fix.sigma_v_m) || fix.sigma_h_m <= 0 ||
      fix.sigma_v_m <= 0) {
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
  if (!initialized_) {
    init_fixes_.push_back({fix.t_ns, z, fix.sigma_h_m, Eigen::Isometry3d::Identity()});
    init_fixes_.back().T_start_body.matrix()(0, 0) = std::numeric_limits<double>::quiet_NaN();
    return false;
  }
  PropagateTo(fix.t_ns);
  // The antenna, latency_s before the time stamp (lever arm and latency; both
  // 0 by default).
  Vec3 predicted = GpsAntennaPrediction(x_.p_enu_m, x_.v_enu_mps, x_.R_enu_body, config_.gps_lever_arm_body_m,
                                        config_.gps_latency_s);
  Mat3 R = Mat3::Zero();
  R.diagonal() << fix.sigma_h_m * fix.sigma_h_m, fix.sigma_h_m * fix.sigma_h_m,
      fix.sigma_v_m * fix.sigma_v_m;
  if (!config_.use_imu) {
    // State lives at the last frame: extrapolate with the VO velocity.
    const double dt = Seconds(fix.t_ns, t_ns_);
    predicted += x_.v_enu_mps * dt;
    R.diagonal().array() += std::pow(0.3 * dt, 2);
  }
  const Vec3 y = z - predicted;
  const Eigen::MatrixXd H = GpsMeasurementJacobian();
  // Horizontal (E, N) and vertical (U) are gated on their own, so that a
  // vertical disagreement does not throw away the horizontal information.
  const GpsGateResult gate = GateGps(y, R, H);
  last_nis_ = gate.nis_h;
  last_nis_v_ = gate.nis_v;
  bool use_h = gate.h_ok, use_v = gate.v_ok;
  // A run of rejections means the filter, not the GPS, is off (an open-sky
  // receiver does not fail 3 times in a row at the 0.1 % gate): reset the
  // rejected component's position covariance to cover the innovation, so the
  // fix is taken and the state snaps back to GPS. Counted on the pose.
  const int reset_after = std::max(1, config_.gps_reset_after_rejections);
  const bool reset_h = !use_h && std::isfinite(gate.nis_h) && ++rejections_h_ > reset_after;
  const bool reset_v = !use_v && std::isfinite(gate.nis_v) && ++rejections_v_ > reset_after;
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
  if (!use_v) ++gps_rejected_vertical_;
  if (!use_h || !use_v) last_gps_rejected_ns_ = fix.t_ns;  // GPS_DEGRADED for a while
  if (!use_h) {
    ++gps_rejected_;
    return false;
  }
  ++gps_used_;
  last_gps_accepted_ns_ = fix.t_ns;
  return true;
}

Eigen::MatrixXd Ekf::GpsMeasurementJacobian() const {
  const int n = static_cast<int>(P_.rows());
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, n);
  const auto J = GpsAntennaJacobian(x_.R_enu_body, config_.gps_lever_arm_body_m, config_.gps_latency_s);
  H.middleCols<3>(0) = J.middleCols<3>(0);
  if (config_.use_imu) {
    H.middleCols<3>(kV) = J.middleCols<3>(3);
    H.middleCols<3>(kTh) = J.middleCols<3>(6);
  } else {
    H.middleCols<3>(3) = J.middleCols<3>(6);  // [p, theta]; velocity is not a state
  }
  return H;
}

Ekf::GpsGateResult Ekf::GateGps(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H) const {
  const Mat3 S = H * P_ * H.transpose() + R;
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
  // start-up uncertainty back plus the drift rate since the last used fix.
  const Vec3 mask(horizontal ? 1.0 : 0.0, horizontal ? 1.0 : 0.0, vertical ? 1.0 : 0.0);
  const Vec3 jump = y.cwiseProduct(mask);
  x_.p_enu_m += jump;
  const bool clone = config_.use_imu;
  if (clone) p_clone_ += jump;
  const double gap_s = last_gps_accepted_ns_ ? std::max(1.0, Seconds(t_ns_, *last_gps_accepted_ns_)) : 1.0;
  for (int i = 0; i < 3; ++i) {
    if (mask[i] == 0.0) continue;
    P_.row(i).setZero();
    P_.col(i).setZero();
    P_(i, i) = R(i, i);
    if (clone) {
      P_.row(kPc + i).setZero();
      P_.col(kPc + i).setZero();
      P_(kPc + i, kPc + i) = P_(i, kPc + i) = P_(kPc + i, i) = R(i, i);
      P_(kV + i, kV + i) += std::pow(config_.init_velocity_sigma_mps, 2) + std::pow(jump[i] / gap_s, 2);
    }
  }
  Symmetrize(P_);
  ++gps_resets_;
}

void Ekf::ApplyGpsUpdate(const Vec3& y, const Mat3& R, const Eigen::MatrixXd& H3, bool horizontal, bool vertical) {
  std::vector<int> rows;
  if (horizontal) rows = {0, 1};
  if (vertical) rows.push_back(2);
  const int m = static_cast<int>(rows.size());
  const int n = static_cast<int>(P_.rows());
  Eigen::MatrixXd H(m, n);
  Eigen::VectorXd ym(m);
  Eigen::MatrixXd Rm(m, m);
  for (int i = 0; i < m; ++i) {
    H.row(i) = H3.row(rows[static_cast<size_t>(i)]);
    ym(i) = y(rows[static_cast<size_t>(i)]);
    for (int j = 0; j < m; ++j) Rm(i, j) = R(rows[static_cast<size_t>(i)], rows[static_cast<size_t>(j)]);
  }
  const Eigen::MatrixXd PHt = P_ * H.transpose();
  const Eigen::MatrixXd S = H * PHt + Rm;
  const Eigen::MatrixXd K = PHt * S.inverse();
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  P_ = IKH * P_ * IKH.transpose() + K * Rm * K.transpose();
  Symmetrize(P_);
  Correct(K * ym);
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

// ------------------------------------------------------------------ init

void Ekf::TryInitialize(int64_t t_ns) {
  // Fixes already attached to the VO chain.
  std::vector<const InitFix*> fixes;
  for (const auto& f : init_fixes_)
    if (!std::isnan(f.T_start_body.matrix()(0, 0))) fixes.push_back(&f);
  if (static_cast<int>(fixes.size()) < std::max(2, config_.init_min_fixes)) return;
  const double sigma_h = fixes.back()->sigma_h;
  const double min_baseline =
      std::max(config_.init_min_baseline_m, config_.init_min_baseline_sigmas * sigma_h);
  double gps_span = 0, vo_span = 0;
  for (const auto* f : fixes) {
    gps_span = std::max(gps_span, (f->p_enu.head<2>() - fixes.front()->p_enu.head<2>()).norm());
    vo_span = std::max(vo_span, (f->T_start_body.translation() -
                                 fixes.front()->T_start_body.translation()).norm());
  }
  if (gps_span < min_baseline || vo_span < 0.5 * min_baseline) return;

  // Roll / pitch of the start frame from gravity (IMU), else level.
  Mat3 R_level_start = Mat3::Identity();
  const GravityFit gravity = FitGravity(init_gravity_);
  double tilt_var = std::pow(config_.init_roll_pitch_sigma_rad, 2);
  if (config_.use_imu && gravity.ok) {
    tilt_var += std::pow(gravity.accel_sigma_mps2 / config_.gravity_mps2, 2);
    const Vec3 up = gravity.up_start;  // "up" in start axes
    R_level_start = Eigen::Quaterniond::FromTwoVectors(up, Vec3::UnitZ()).toRotationMatrix();
  }
  // 2D Procrustes: p_i ~= Rz(psi) q_i + t, robust (drop > 3 sigma, twice).
  std::vector<char> use(fixes.size(), 1);
  double psi = 0;
  Eigen::Vector2d p_mean, q_mean;
  double z_off = 0, spread2 = 0;
  int used = 0;
  for (int iter = 0; iter < 3; ++iter) {
    p_mean.setZero(); q_mean.setZero(); z_off = 0; used = 0;
    for (size_t i = 0; i < fixes.size(); ++i) {
      if (!use[i]) continue;
      const Vec3 q = R_level_start * fixes[i]->T_start_body.translation();
      p_mean += fixes[i]->p_enu.head<2>(); q_mean += q.head<2>();
      z_off += fixes[i]->p_enu.z() - q.z();
      ++used;
    }
    if (used < 2) return;
    p_mean /= used; q_mean /= used; z_off /= used;
    double sxx = 0, sxy = 0;
    spread2 = 0;
    for (size_t i = 0; i < fixes.size(); ++i) {
      if (!use[i]) continue;
      const Eigen::Vector2d q = (R_level_start * fixes[i]->T_start_body.translation()).head<2>() - q_mean;
      const Eigen::Vector2d p = fixes[i]->p_enu.head<2>() - p_mean;
      sxx += q.dot(p);
      sxy += q.x() * p.y() - q.y() * p.x();
      spread2 += q.squaredNorm();
    }
    psi = std::atan2(sxy, sxx);
    const Eigen::Rotation2Dd Rz(psi);
    bool changed = false;
    for (size_t i = 0; i < fixes.size(); ++i) {
      const Eigen::Vector2d q = (R_level_start * fixes[i]->T_start_body.translation()).head<2>();
      const double res = (fixes[i]->p_enu.head<2>() - (Rz * (q - q_mean) + p_mean)).norm();
      const char keep = res < 3.5 * sigma_h + 1.0;
      if (keep != use[i]) { use[i] = keep; changed = true; }
    }
    if (!changed) break;
  }
  if (used < std::max(2, config_.init_min_fixes) || spread2 < min_baseline * min_baseline / 4) return;

  const Mat3 R_enu_start = Eigen::AngleAxisd(psi, Vec3::UnitZ()).toRotationMatrix() * R_level_start;
  const Vec3 q_now = R_level_start * T_start_body_.translation();
  const Eigen::Vector2d p_now_xy = Eigen::Rotation2Dd(psi) * (q_now.head<2>() - q_mean) + p_mean;
  x_ = NominalState{};
  x_.p_enu_m = Vec3(p_now_xy.x(), p_now_xy.y(), q_now.z() + z_off);
  x_.R_enu_body = R_enu_start * T_start_body_.linear();
  x_.v_enu_mps = x_.R_enu_body * last_vo_velocity_body_mps_;

  // Covariance: centroid noise + yaw lever arm.
  const double k = std::max(1.0, config_.init_cov_inflation);
  const double var_c = k * sigma_h * sigma_h / used;
  const double sigma_psi = std::sqrt(k) * sigma_h / std::sqrt(spread2);
  const Vec3 lever(p_now_xy.x() - p_mean.x(), p_now_xy.y() - p_mean.y(), 0);
  const Vec3 J_psi = Vec3::UnitZ().cross(lever);
  const int n = config_.use_imu ? kImuStates + kCloneStates + kVoCalibStates : kPoseStates;
  const int th = config_.use_imu ? kTh : 3;
  P_ = Eigen::MatrixXd::Zero(n, n);
  const double sigma_v = std::max(3.0, 1.5 * sigma_h);
  P_.block<3, 3>(0, 0).diagonal() << var_c, var_c, sigma_v * sigma_v / used;
  P_.block<3, 3>(0, 0) += J_psi * J_psi.transpose() * sigma_psi * sigma_psi;
  P_.block<3, 3>(th, th).diagonal() << tilt_var, tilt_var, sigma_psi * sigma_psi;
  P_.block<3, 1>(0, th + 2) = J_psi * sigma_psi * sigma_psi;
  P_.block<1, 3>(th + 2, 0) = (J_psi * sigma_psi * sigma_psi).transpose();
  if (config_.use_imu) {
    P_.block<3, 3>(kV, kV).diagonal().setConstant(std::pow(config_.init_velocity_sigma_mps, 2));
    P_.block<3, 3>(kBa, kBa).diagonal().setConstant(std::pow(config_.init_accel_bias_sigma_mps2, 2));
    P_.block<3, 3>(kBg, kBg).diagonal().setConstant(std::pow(config_.init_gyro_bias_sigma_radps, 2));
    P_.block<3, 3>(kCal, kCal).diagonal().setConstant(std::pow(config_.vo_boresight_sigma_rad, 2));
    P_(kCal + 3, kCal + 3) = std::pow(config_.vo_scale_sigma, 2);
    R_boresight_ = Mat3::Identity();
    vo_scale_error_ = 0;
    Clone();
  }
  t_ns_ = t_ns;
  initialized_ = true;
  gps_used_ += used;
  gps_rejected_ += static_cast<int>(fixes.size()) - used;
  last_gps_accepted_ns_ = fixes.back()->t_ns;
  init_fixes_.clear();
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
  if (out.seconds_since_gps > config_.vo_only_after_periods * gps_period_s_) {
    out.mode = vo_ok ? Mode::kVoOnly : Mode::kLost;
  } else if (last_gps_rejected_ns_ && Seconds(t_ns, *last_gps_rejected_ns_) < config_.degraded_hold_s) {
    out.mode = Mode::kGpsDegraded;
  } else {
    out.mode = Mode::kGpsFused;
  }
  return out;
}

}  // namespace locaid::fusion
