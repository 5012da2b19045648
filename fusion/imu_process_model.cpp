// ImuProcessModel (fusion/process_model.hpp): strapdown IMU propagation, the
// VO motion as a gated relative-pose measurement against a clone of the pose
// at the VO anchor, and the VO's boresight / scale as random constants.
#include "fusion/ekf.hpp"
#include "fusion/ekf_internal.hpp"
#include "fusion/noise_scale.hpp"
#include "fusion/process_model.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>

namespace locaid::fusion {
namespace {

using namespace detail;
constexpr double kMaxImuStepS = 0.01;

class ImuProcessModel final : public ProcessModel {
 public:
  explicit ImuProcessModel(const EkfConfig& config)
      : config_(config),
        vo_gate_(ChiSquareQuantile(config.vo.gate_probability, 6)),
        gate_vel_(ChiSquareQuantile(config.gps.gate_probability, 3)),
        speed_gate_(ChiSquareQuantile(config.vehicle.speed_gate_probability, 1)),
        vo_noise_(6, {.prior_samples = config.vo.noise_prior_frames,
                      .window_samples = config.vo.noise_window_frames,
                      .min_scale = config.vo.noise_scale_min,
                      .max_scale = config.vo.noise_scale_max}) {}

  int StateSize() const override { return kImuStates + kCloneStates + kVoCalibStates + kSpeedStates; }
  int AttitudeIndex() const override { return kTh; }

  Mat6 VoNoise(const Mat6& reported, const Eigen::Isometry3d& motion) const override {
    // The per-metre term: VO is a measurement checked against the IMU here.
    const Vec3 per_m(config_.vo.sigma_t_per_m, config_.vo.sigma_lateral_per_m, config_.vo.sigma_vertical_per_m);
    const Mat6 model = ScaledVoNoise(config_, reported, per_m * motion.translation().norm());
    const Vec6 d = vo_noise_scale_.cwiseSqrt();
    return d.asDiagonal() * model * d.asDiagonal();
  }

  bool AddImu(FilterState& s, const ImuSample& sample) override {
    // A non-finite sample would poison the state: refuse it.
    if (!sample.accel_mps2.allFinite() || !sample.gyro_radps.allFinite()) return false;
    if (!s.initialized) {
      init_accel_.push_back(sample.accel_mps2);
      last_imu_ = sample;
      return true;
    }
    if (sample.t_ns > s.t_ns && last_imu_) {
      // Interval [t_ns, sample.t_ns]: mean of the two samples bounding it.
      ImuSample mid = *last_imu_;
      mid.accel_mps2 = 0.5 * (last_imu_->accel_mps2 + sample.accel_mps2);
      mid.gyro_radps = 0.5 * (last_imu_->gyro_radps + sample.gyro_radps);
      last_imu_ = mid;
      PropagateTo(s, sample.t_ns);
    }
    last_imu_ = sample;
    return true;
  }

  void AddStartupFrame(const VoMeasurement& m, const Eigen::Isometry3d& T_start_body,
                       const Eigen::Isometry3d& motion, double dt_s, bool vo_ok) override {
    // Specific force and VO motion in the start frame, for the gravity fit
    // (FitGravity) at initialisation; coasted frames carry no position.
    if (!init_accel_.empty() && vo_ok) {
      Vec3 f_mean = Vec3::Zero();
      for (const auto& a : init_accel_) f_mean += a;
      f_mean /= static_cast<double>(init_accel_.size());
      GravitySample g;
      g.t_s = Seconds(m.t_ns, m.t_prev_ns) * 0.5 + Seconds(m.t_prev_ns, init_fit_t0_ns_.value_or(m.t_prev_ns));
      if (!init_fit_t0_ns_) init_fit_t0_ns_ = m.t_prev_ns;
      g.R_start_body = T_start_body.linear();
      g.f_body_mps2 = f_mean;
      g.v_body_mps = motion.translation() / dt_s;
      g.w_body_radps = LogSO3(motion.linear()) / dt_s;
      init_gravity_.push_back(g);
    }
    init_accel_.clear();
  }

  void LevelStart(Mat3& R_level_start, double& tilt_var) const override {
    const GravityFit gravity = FitGravity(init_gravity_);
    if (!gravity.ok) return;
    tilt_var += std::pow(gravity.accel_sigma_mps2 / config_.imu.gravity_mps2, 2);
    const Vec3 up = gravity.up_start;  // "up" in start axes
    R_level_start = Eigen::Quaterniond::FromTwoVectors(up, Vec3::UnitZ()).toRotationMatrix();
  }

  void Initialize(FilterState& s) override {
    Eigen::MatrixXd& P = s.P;
    P.block<3, 3>(kV, kV).diagonal().setConstant(std::pow(config_.startup.velocity_sigma_mps, 2));
    P.block<3, 3>(kBa, kBa).diagonal().setConstant(std::pow(config_.startup.accel_bias_sigma_mps2, 2));
    P.block<3, 3>(kBg, kBg).diagonal().setConstant(std::pow(config_.startup.gyro_bias_sigma_radps, 2));
    P.block<3, 3>(kCal, kCal).diagonal().setConstant(std::pow(config_.vo.boresight_sigma_rad, 2));
    P(kCal + 3, kCal + 3) = std::pow(config_.vo.scale_sigma, 2);
    P(kSpd, kSpd) = std::pow(config_.vehicle.speed_scale_sigma, 2);
    R_boresight_ = Mat3::Identity();
    vo_scale_error_ = 0;
    speed_scale_error_ = 0;
    Clone(s);
  }

  void PropagateTo(FilterState& s, int64_t t_ns) override {
    if (!s.initialized || t_ns <= s.t_ns) return;
    const double total = Seconds(t_ns, s.t_ns);
    const Vec3 f = last_imu_ ? last_imu_->accel_mps2 : Vec3(0, 0, config_.imu.gravity_mps2);
    const Vec3 w = last_imu_ ? last_imu_->gyro_radps : Vec3::Zero();
    const Vec3 g(0, 0, -config_.imu.gravity_mps2);
    // Long gaps: the held sample is stale; inflate the noise accordingly.
    const double gap_scale = total > config_.imu.max_gap_s ? total / config_.imu.max_gap_s : 1.0;
    // The IMU's own noise densities when its samples state them.
    const double accel_noise = last_imu_ && last_imu_->accel_noise_mps2_sqrt_hz > 0
                                   ? last_imu_->accel_noise_mps2_sqrt_hz
                                   : config_.imu.accel_noise_mps2_sqrt_hz;
    const double gyro_noise = last_imu_ && last_imu_->gyro_noise_radps_sqrt_hz > 0
                                  ? last_imu_->gyro_noise_radps_sqrt_hz
                                  : config_.imu.gyro_noise_radps_sqrt_hz;
    const int steps = std::max(1, static_cast<int>(std::ceil(total / kMaxImuStepS)));
    const double dt = total / steps;
    Eigen::MatrixXd& P = s.P;
    Mat15 phi = Mat15::Identity();  // the steps composed, for a smoother's log
    for (int i = 0; i < steps; ++i) {
      const Mat15 F = ImuTransitionJacobian(s.x, f, w, dt);
      if (s.log) phi = F * phi;
      const Mat15 Q = ImuProcessNoise(s.x, dt, accel_noise * gap_scale, gyro_noise * gap_scale,
                                      config_.imu.accel_bias_walk_mps3_sqrt_hz, config_.imu.gyro_bias_walk_radps2_sqrt_hz);
      s.x = fusion::IntegrateImuStep(s.x, f, w, dt, g);
      const Eigen::MatrixXd P15 = P.topLeftCorner<15, 15>();
      const Eigen::Index rest = P.cols() - 15;  // clone and VO calibration
      P.topLeftCorner<15, 15>() = F * P15 * F.transpose() + Q;
      P.topRightCorner(15, rest) = F * P.topRightCorner(15, rest);
      P.bottomLeftCorner(rest, 15) = P.topRightCorner(15, rest).transpose();
    }
    Symmetrize(P);
    s.t_ns = t_ns;
    if (s.log) {
      Eigen::MatrixXd phi_full = Eigen::MatrixXd::Identity(P.rows(), P.cols());
      phi_full.topLeftCorner<15, 15>() = phi;
      s.log->Transition(s, phi_full);
    }
  }

  std::optional<VoGate> ApplyVo(FilterState& s, const VoStep& vo) override {
    // R_vo carries the learner's scale (VoNoise); the adaptation may ask
    // for more on a rotation axis: the larger of the two holds.
    Mat6 Rvo = vo.R_vo;
    if (adapt_rotation_)
      for (int i = 0; i < 3; ++i)
        Rvo(3 + i, 3 + i) *= std::max(1.0, rotation_scale_[i] / vo_noise_scale_[3 + i]);
    PropagateTo(s, vo.t_ns);
    std::optional<VoGate> gate;
    if (vo.vo_ok) gate = UpdateVo(s, vo.motion, Rvo, vo.learn_noise);
    if (vo.reanchor) Clone(s);  // else the clone stays at the anchor the next motion starts from
    return gate;
  }

  double GpsLateness(const FilterState& s, int64_t fix_t_ns) const override {
    return std::max(0.0, Seconds(s.t_ns, fix_t_ns));
  }
  void ExtrapolateGps(const FilterState&, int64_t, Vec3&, Mat3&) const override {}  // compared at its time

  Eigen::MatrixXd GpsJacobian(const FilterState& s, const Eigen::Matrix<double, 3, 9>& J) const override {
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, s.P.rows());
    H.middleCols<3>(0) = J.middleCols<3>(0);
    H.middleCols<3>(kV) = J.middleCols<3>(3);
    H.middleCols<3>(kTh) = J.middleCols<3>(6);
    return H;
  }

  std::optional<bool> FuseGpsVelocity(FilterState& s, const GpsFix& fix, double late_s) override {
    // The antenna moves with the body plus the lever arm's rotation; the
    // gyro's rate (bias removed) gives that part.
    if (!s.initialized) return std::nullopt;
    const Vec3 w = last_imu_ ? Vec3(last_imu_->gyro_radps - s.x.gyro_bias_radps) : Vec3::Zero();
    const Vec3 predicted = s.x.v_enu_mps + s.x.R_enu_body * w.cross(config_.gps.lever_arm_body_m);
    const Vec3 y = *fix.v_enu_mps - predicted;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, s.P.rows());
    H.middleCols<3>(kV).setIdentity();
    // A late fix's velocity is compared with the current one: the acceleration
    // since then is noise.
    const Mat3 R = Mat3::Identity() * (std::pow(fix.sigma_v_enu_mps, 2) + std::pow(0.5 * late_s, 2));
    return !Update(s, H, R, y, gate_vel_).rejected;
  }

  void ResetPosition(FilterState& s, const Vec3& jump, const Vec3& mask, const Mat3& R, double gap_s) override {
    // A reset is not motion: the clone jumps too, so the next VO update does
    // not see it; the velocity gets its start-up uncertainty back plus the
    // drift rate since the last used fix.
    p_clone_ += jump;
    Eigen::MatrixXd& P = s.P;
    for (int i = 0; i < 3; ++i) {
      if (mask[i] == 0.0) continue;
      P.row(kPc + i).setZero();
      P.col(kPc + i).setZero();
      P(kPc + i, kPc + i) = P(i, kPc + i) = P(kPc + i, i) = R(i, i);
      P(kV + i, kV + i) += std::pow(config_.startup.velocity_sigma_mps, 2) + std::pow(jump[i] / gap_s, 2);
    }
  }

  std::optional<VehicleGate> FuseSpeed(FilterState& s, double speed_mps, double sigma_mps,
                                       const Mat3& R_vehicle_body) override {
    // z = (1 + k) v_veh,x: the reading scales the vehicle's forward speed.
    if (!s.initialized) return std::nullopt;
    const Vec3 v_veh = VehicleVelocity(s.x.v_enu_mps, s.x.R_enu_body, R_vehicle_body);
    const Eigen::Matrix<double, 3, 6> J = VehicleVelocityJacobian(s.x.v_enu_mps, s.x.R_enu_body, R_vehicle_body);
    const double k = 1.0 + speed_scale_error_;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, s.P.rows());
    H.block<1, 3>(0, kV) = k * J.block<1, 3>(0, 0);
    H.block<1, 3>(0, kTh) = k * J.block<1, 3>(0, 3);
    H(0, kSpd) = v_veh.x();
    const Eigen::VectorXd r = Eigen::VectorXd::Constant(1, speed_mps - k * v_veh.x());
    const Eigen::MatrixXd R = Eigen::MatrixXd::Constant(1, 1, sigma_mps * sigma_mps);
    return Update(s, H, R, r, speed_gate_);
  }

  std::optional<VehicleGate> FuseZeroVelocity(FilterState& s, double sigma_mps, double gate) override {
    if (!s.initialized) return std::nullopt;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, s.P.rows());
    H.middleCols<3>(kV).setIdentity();
    const Eigen::MatrixXd R = Eigen::MatrixXd::Identity(3, 3) * sigma_mps * sigma_mps;
    return Update(s, H, R, -s.x.v_enu_mps, gate);
  }

  std::optional<VehicleGate> FuseNonHolonomic(FilterState& s, const Mat3& R_vehicle_body,
                                              const Eigen::Vector2d& sigma_mps) override {
    if (!s.initialized) return std::nullopt;
    const Vec3 v_veh = VehicleVelocity(s.x.v_enu_mps, s.x.R_enu_body, R_vehicle_body);
    const Eigen::Matrix<double, 3, 6> J = VehicleVelocityJacobian(s.x.v_enu_mps, s.x.R_enu_body, R_vehicle_body);
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, s.P.rows());
    H.middleCols<3>(kV) = J.block<2, 3>(1, 0);
    H.middleCols<3>(kTh) = J.block<2, 3>(1, 3);
    const Eigen::VectorXd r = -v_veh.tail<2>();
    const Eigen::MatrixXd R = sigma_mps.cwiseAbs2().asDiagonal();
    return Update(s, H, R, r, 0);  // a constraint, not a sensor: never gated
  }

  const Mat3& vo_boresight() const override { return R_boresight_; }
  double speed_scale_error() const override { return speed_scale_error_; }
  double vo_scale_error() const override { return vo_scale_error_; }
  const Vec6& vo_noise_scale() const override { return reported_scale_; }

 private:
  void BoxPlus(FilterState& s, const Eigen::VectorXd& dx) override {
    s.x = fusion::BoxPlus(s.x, dx.head<15>());
    p_clone_ += dx.segment<3>(kPc);
    R_clone_ = ExpSO3(dx.segment<3>(kThc)) * R_clone_;
    R_boresight_ = ExpSO3(dx.segment<3>(kCal)) * R_boresight_;
    vo_scale_error_ += dx(kCal + 3);
    speed_scale_error_ += dx(kSpd);
  }

  VehicleGate Update(FilterState& s, const Eigen::MatrixXd& H, const Eigen::MatrixXd& R, const Eigen::VectorXd& r,
                     double gate) {
    const GatedCorrection c = GatedKalmanUpdate(s.P, H, R, r, gate);
    if (c.accepted) Correct(s, c.dx);
    return {c.nis, !c.accepted};
  }

  // The VO motion since the clone, with the estimated boresight and scale removed.
  VoGate UpdateVo(FilterState& s, const Eigen::Isometry3d& motion, const Mat6& Rvo, bool learn_noise) {
    Eigen::Isometry3d corrected = motion;
    corrected.translation() = CorrectVoTranslation(motion.translation(), R_boresight_, vo_scale_error_);
    const Vec6 r = VoResidual(s.x.p_enu_m, s.x.R_enu_body, p_clone_, R_clone_, corrected);
    const MatVoH Hs = VoJacobian(s.x.p_enu_m, s.x.R_enu_body, p_clone_, R_clone_, corrected);
    Eigen::MatrixXd& P = s.P;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, P.rows());
    H.middleCols<3>(kP) = Hs.middleCols<3>(0);
    H.middleCols<3>(kTh) = Hs.middleCols<3>(3);
    H.middleCols<3>(kPc) = Hs.middleCols<3>(6);
    H.middleCols<3>(kThc) = Hs.middleCols<3>(9);
    H.middleCols<kVoCalibStates>(kCal) =
        VoCalibrationJacobian(motion.linear(), motion.translation(), R_boresight_, vo_scale_error_);
    const Mat6 S = H * P * H.transpose() + Rvo;
    const double nis = r.dot(S.ldlt().solve(r));
    const Vec6 applied = reported_scale_;  // the scale Rvo carries
    AdaptVoRotationNoise(r.tail<3>(), S.bottomRightCorner<3, 3>());
    if (learn_noise) LearnVoNoise(r, S, Rvo, applied);
    ReportScale();
    const bool gate_ok = std::isfinite(nis) && nis < vo_gate_;
    // A run of rejections means the prediction, not the VO, is off: accept.
    if (gate_ok || (std::isfinite(nis) && ++vo_consecutive_rejections_ > 2)) {
      if (gate_ok) vo_consecutive_rejections_ = 0;
      const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
      const int n = static_cast<int>(P.rows());
      const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
      P = IKH * P * IKH.transpose() + K * Rvo * K.transpose();
      Symmetrize(P);
      Correct(s, K * r);
    }
    return {nis, !gate_ok};
  }

  void LearnVoNoise(const Vec6& r, const Mat6& S, const Mat6& Rvo, const Vec6& applied) {
    // The model's own variance is Rvo / the scale it carries.
    if (!config_.vo.learn_noise) return;
    for (int i = 0; i < 6; ++i) vo_noise_.Add(i, r[i], S(i, i) - Rvo(i, i), Rvo(i, i) / applied[i]);
    vo_noise_scale_ = vo_noise_.scale();
    // While the adaptation takes the rotation axes, the learner's scale there
    // is held at most at vo.noise_rotation_scale_max (1: the model).
    if (adapt_rotation_)
      vo_noise_scale_.tail<3>() = vo_noise_scale_.tail<3>().cwiseMin(
          std::max(config_.vo.noise_scale_min, config_.vo.noise_rotation_scale_max));
  }

  void AdaptVoRotationNoise(const Vec3& r_rot, const Mat3& S_rot) {
    if (!adapt_rotation_) return;
    // Per body axis: mean normalised squared rotation innovation (1 when
    // consistent); one outlier moves it by at most 10 x the rate.
    constexpr double kRate = 0.05;
    const double max_scale = std::max(1.0, config_.vo.adaptive_rotation_noise_max_scale);
    for (int i = 0; i < 3; ++i) {
      const double q = r_rot[i] * r_rot[i] / S_rot(i, i);
      if (!std::isfinite(q)) return;
      rotation_nis_mean_[i] = (1 - kRate) * rotation_nis_mean_[i] + kRate * std::min(q, 10.0);
      rotation_scale_[i] = std::clamp(rotation_scale_[i] * std::pow(rotation_nis_mean_[i], kRate), 1.0, max_scale);
    }
  }

  void ReportScale() {  // the scale applied per axis: the learner's, or the adaptation's where larger
    reported_scale_ = vo_noise_scale_;
    if (adapt_rotation_)
      reported_scale_.tail<3>() = reported_scale_.tail<3>().cwiseMax(rotation_scale_);
  }

  void Clone(FilterState& s) {
    p_clone_ = s.x.p_enu_m;
    R_clone_ = s.x.R_enu_body;
    Eigen::MatrixXd& P = s.P;
    const int n = static_cast<int>(P.rows());
    Eigen::MatrixXd J = Eigen::MatrixXd::Identity(n, n);
    J.block<3, 3>(kPc, kPc).setZero();
    J.block<3, 3>(kThc, kThc).setZero();
    J.block<3, 3>(kPc, kP).setIdentity();
    J.block<3, 3>(kThc, kTh).setIdentity();
    P = J * P * J.transpose();
    Symmetrize(P);
    if (s.log) s.log->Transition(s, J);
  }

  EkfConfig config_;
  double vo_gate_ = 0, gate_vel_ = 0, speed_gate_ = 0;
  // Last IMU sample (zero-order hold between samples).
  std::optional<ImuSample> last_imu_;
  // Start-up: specific force since the last frame, and the gravity fit's samples.
  std::deque<Vec3> init_accel_;
  std::vector<GravitySample> init_gravity_;
  std::optional<int64_t> init_fit_t0_ns_;
  // Clone of the pose at the VO anchor.
  Vec3 p_clone_ = Vec3::Zero();
  Mat3 R_clone_ = Mat3::Identity();
  // VO calibration estimate.
  Mat3 R_boresight_ = Mat3::Identity();
  double vo_scale_error_ = 0;
  double speed_scale_error_ = 0;  // speed sensor: reads (1 + error) x true speed
  int vo_consecutive_rejections_ = 0;
  NoiseScaleEstimator vo_noise_;          // vo.learn_noise
  Vec6 vo_noise_scale_ = Vec6::Ones();    // its scale, applied by VoNoise
  // vo.adaptive_rotation_noise, part of the learned VO noise: off with the fixed model (vo.learn_noise false)
  const bool adapt_rotation_ = config_.vo.adaptive_rotation_noise && config_.vo.learn_noise;
  Vec3 rotation_scale_ = Vec3::Ones(), rotation_nis_mean_ = Vec3::Ones();
  Vec6 reported_scale_ = Vec6::Ones();    // both, as vo_noise_scale() shows them
};

}  // namespace

std::unique_ptr<ProcessModel> MakeImuProcessModel(const EkfConfig& config) {
  return std::make_unique<ImuProcessModel>(config);
}

}  // namespace locaid::fusion
