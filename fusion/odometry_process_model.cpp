// OdometryProcessModel (fusion/process_model.hpp), for cars without an IMU:
// the VO motion propagates the pose [p, theta]; the velocity is the VO's.
#include "fusion/ekf.hpp"
#include "fusion/ekf_internal.hpp"
#include "fusion/process_model.hpp"

#include <cmath>

namespace locaid::fusion {
namespace {

using namespace detail;

class OdometryProcessModel final : public ProcessModel {
 public:
  explicit OdometryProcessModel(const EkfConfig& config) : config_(config) {}

  int StateSize() const override { return kPoseStates; }
  int AttitudeIndex() const override { return 3; }

  // No per-metre term: it would only inflate the propagation noise (sim: worse GPS smoothing).
  Mat6 VoNoise(const Mat6& reported, const Eigen::Isometry3d&) const override {
    return ScaledVoNoise(config_, reported, Vec3::Zero());
  }

  bool AddImu(FilterState&, const ImuSample&) override { return true; }  // no IMU: ignored
  void AddStartupFrame(const VoMeasurement&, const Eigen::Isometry3d&, const Eigen::Isometry3d&, double,
                       bool) override {}
  void LevelStart(Mat3&, double&) const override {}  // level: no gravity to fit
  void Initialize(FilterState&) override {}
  void PropagateTo(FilterState&, int64_t) override {}  // the state lives at the last frame

  std::optional<VoGate> ApplyVo(FilterState& s, const VoStep& vo) override {
    const Mat6 F = OdometryTransitionJacobian(s.x.R_enu_body, vo.step);
    const Mat6 G = OdometryNoiseJacobian(s.x.R_enu_body, vo.step);
    Mat6 Rvo = vo.R_vo;
    if (!vo.vo_ok) {
      // Coasting: velocity noise for the lost frames.
      Rvo.setZero();
      Rvo.topLeftCorner<3, 3>().diagonal().setConstant(std::pow(config_.vo.lost_sigma_no_imu_mps * vo.dt_s, 2));
      Rvo.bottomRightCorner<3, 3>().diagonal().setConstant(std::pow(0.05 * vo.dt_s, 2));
    }
    OdometryPropagate(s.x.p_enu_m, s.x.R_enu_body, vo.step);
    s.P = F * s.P * F.transpose() + G * Rvo * G.transpose();
    Symmetrize(s.P);
    s.x.v_enu_mps = s.x.R_enu_body * vo.vo_velocity_body_mps;
    s.t_ns = vo.t_ns;
    if (s.log) s.log->Transition(s, F);
    return std::nullopt;
  }

  double GpsLateness(const FilterState&, int64_t) const override { return 0.0; }
  void ExtrapolateGps(const FilterState& s, int64_t fix_t_ns, Vec3& predicted, Mat3& R) const override {
    // The state lives at the last frame: extrapolate with the VO velocity.
    const double dt = Seconds(fix_t_ns, s.t_ns);
    predicted += s.x.v_enu_mps * dt;
    R.diagonal().array() += std::pow(0.3 * dt, 2);
  }

  Eigen::MatrixXd GpsJacobian(const FilterState& s, const Eigen::Matrix<double, 3, 9>& J) const override {
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(3, s.P.rows());
    H.middleCols<3>(0) = J.middleCols<3>(0);
    H.middleCols<3>(3) = J.middleCols<3>(6);  // [p, theta]; velocity is not a state
    return H;
  }

  std::optional<bool> FuseGpsVelocity(FilterState&, const GpsFix&, double) override { return std::nullopt; }
  void ResetPosition(FilterState&, const Vec3&, const Vec3&, const Mat3&, double) override {}

  const Mat3& vo_boresight() const override {
    static const Mat3 kIdentity = Mat3::Identity();
    return kIdentity;
  }
  double vo_scale_error() const override { return 0.0; }
  const Vec6& vo_noise_scale() const override {  // no innovation to learn from: the fixed model
    static const Vec6 kOnes = Vec6::Ones();
    return kOnes;
  }
  double speed_scale_error() const override { return 0.0; }
  // Velocity is not a state here (it is the VO's): no vehicle measurements.
  std::optional<VehicleGate> FuseSpeed(FilterState&, double, double, const Mat3&) override { return std::nullopt; }
  std::optional<VehicleGate> FuseZeroVelocity(FilterState&, double, double) override { return std::nullopt; }
  std::optional<VehicleGate> FuseNonHolonomic(FilterState&, const Mat3&, const Eigen::Vector2d&) override {
    return std::nullopt;
  }

 private:
  void BoxPlus(FilterState& s, const Eigen::VectorXd& dx) override {
    s.x.p_enu_m += dx.head<3>();
    s.x.R_enu_body = ExpSO3(dx.segment<3>(3)) * s.x.R_enu_body;
  }

  EkfConfig config_;
};

}  // namespace

std::unique_ptr<ProcessModel> MakeOdometryProcessModel(const EkfConfig& config) {
  return std::make_unique<OdometryProcessModel>(config);
}

}  // namespace locaid::fusion
