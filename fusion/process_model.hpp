// The EKF's process model: what moves the state between camera frames and
// what the error state holds. Two kinds, chosen once from EkfConfig imu.enabled
// (MakeProcessModel); the filter (fusion/ekf.hpp) never asks which it has.
//
//   ImuProcessModel (imu_process_model.cpp): strapdown IMU propagation; error
//     state p v theta ba bg, a clone of the pose at the VO anchor and the VO
//     calibration (boresight, scale), the speed sensor's scale: 26 states.
//     The VO motion is a relative-pose measurement between the clone and now,
//     with a chi-square gate; fixes are compared at their own time (late
//     fixes) and their velocity is fused; vehicle speed readings and the car's
//     motion constraints measure the velocity.
//   OdometryProcessModel (odometry_process_model.cpp), for cars without an
//     IMU: the VO motion itself propagates the pose (error state p theta: 6
//     states); velocity is the VO's, and fixes are extrapolated to the frame.
#pragma once

#include "fusion/ekf_models.hpp"
#include "fusion/epoch_log.hpp"
#include "fusion/types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>

namespace locaid::fusion {

struct EkfConfig;

// The part of the filter state every model shares.
struct FilterState {
  bool initialized = false;
  int64_t t_ns = 0;        // time the state is at
  NominalState x;
  Eigen::MatrixXd P;       // error-state covariance (model's layout)
  // Records transitions and corrections for a smoother (fusion/epoch_log.hpp);
  // nullptr: nothing recorded. The models call it where they move x and P.
  EpochLog* log = nullptr;
};

// One frame's VO, as the filter hands it to the model once initialised.
struct VoStep {
  int64_t t_ns = 0;
  bool vo_ok = false;          // false: coasting (VO lost or not at the anchor)
  bool reanchor = false;       // the next motion starts at this frame
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // from the anchor (vo_ok), else coasted
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();    // since the last frame
  Mat6 R_vo = Mat6::Identity();  // VoNoise of `motion`
  double dt_s = 0;               // span of `motion` (vo_ok) or of the frame
  Vec3 vo_velocity_body_mps = Vec3::Zero();  // last VO velocity
  bool learn_noise = false;  // GPS holds the state: the VO innovation may teach the noise scale
};

// What a VO measurement update did (models that gate it).
struct VoGate {
  double nis = 0;
  bool rejected = false;
};

// What a vehicle measurement update did (same verdict as VoGate).
using VehicleGate = VoGate;

class ProcessModel {
 public:
  virtual ~ProcessModel() = default;

  // Error-state size and where the attitude error sits (position is at 0).
  virtual int StateSize() const = 0;
  virtual int AttitudeIndex() const = 0;

  // The filter's VO noise (body axes, [dt, dtheta]) for one motion: the
  // model times the learned scale (EkfConfig vo.learn_noise).
  virtual Mat6 VoNoise(const Mat6& reported, const Eigen::Isometry3d& motion) const = 0;

  // ---- Before initialisation
  // An IMU sample; returns false if it was refused (non-finite).
  virtual bool AddImu(FilterState& s, const ImuSample& sample) = 0;
  // A VO frame before initialisation (T_start_body: the VO chain so far).
  virtual void AddStartupFrame(const VoMeasurement& m, const Eigen::Isometry3d& T_start_body,
                               const Eigen::Isometry3d& motion, double dt_s, bool vo_ok) = 0;
  // Roll / pitch of the start frame (R_level_start) and the tilt variance.
  virtual void LevelStart(Mat3& R_level_start, double& tilt_var) const = 0;
  // The model's own states at initialisation (P's position / attitude blocks are set).
  virtual void Initialize(FilterState& s) = 0;

  // ---- Once initialised
  virtual void PropagateTo(FilterState& s, int64_t t_ns) = 0;
  // One frame's VO: a measurement update (returns the gate's verdict) or the propagation.
  virtual std::optional<VoGate> ApplyVo(FilterState& s, const VoStep& vo) = 0;
  // x (+) dx in the model's layout; a non-finite dx is ignored.
  void Correct(FilterState& s, const Eigen::VectorXd& dx) {
    if (!dx.allFinite()) return;
    BoxPlus(s, dx);
    if (s.log) s.log->Corrected(s, dx);
  }

  // ---- GPS
  // How long before the state time the fix was measured (a late fix), s.
  virtual double GpsLateness(const FilterState& s, int64_t fix_t_ns) const = 0;
  // Moves the predicted antenna position (and its noise) to the fix time.
  virtual void ExtrapolateGps(const FilterState& s, int64_t fix_t_ns, Vec3& predicted, Mat3& R) const = 0;
  // Jacobian (3 x n) of the antenna position; J: GpsAntennaJacobian [p, v, theta].
  virtual Eigen::MatrixXd GpsJacobian(const FilterState& s, const Eigen::Matrix<double, 3, 9>& J) const = 0;
  // Fuses the fix's velocity; nullopt when velocity is not a state, else whether the gate passed it.
  virtual std::optional<bool> FuseGpsVelocity(FilterState& s, const GpsFix& fix, double late_s) = 0;
  // After the filter reset position axes to the fix (jump, per-axis mask and
  // fix covariance R, gap since the last used fix): the model's own states.
  virtual void ResetPosition(FilterState& s, const Vec3& jump, const Vec3& mask, const Mat3& R, double gap_s) = 0;

  // ---- Vehicle measurements at the state time (models without a velocity
  // state return nullopt): a speed reading (1 + scale error) x forward speed,
  // zero velocity (3 dof), the non-holonomic constraints (vehicle-frame
  // lateral and vertical velocity 0, 2 dof, sigma per axis).
  virtual std::optional<VehicleGate> FuseSpeed(FilterState& s, double speed_mps, double sigma_mps,
                                               const Mat3& R_vehicle_body) = 0;
  // gate: chi-square (3 dof) the innovation must pass; 0 = none.
  virtual std::optional<VehicleGate> FuseZeroVelocity(FilterState& s, double sigma_mps, double gate) = 0;
  virtual std::optional<VehicleGate> FuseNonHolonomic(FilterState& s, const Mat3& R_vehicle_body,
                                                      const Eigen::Vector2d& sigma_mps) = 0;

  // ---- Estimates shown to users (identity / 0 / 1 where the model has none)
  virtual const Mat3& vo_boresight() const = 0;
  virtual double vo_scale_error() const = 0;
  virtual const Vec6& vo_noise_scale() const = 0;
  virtual double speed_scale_error() const = 0;

 private:
  virtual void BoxPlus(FilterState& s, const Eigen::VectorXd& dx) = 0;
};

// ImuProcessModel when config.imu.enabled, else OdometryProcessModel.
std::unique_ptr<ProcessModel> MakeProcessModel(const EkfConfig& config);
std::unique_ptr<ProcessModel> MakeImuProcessModel(const EkfConfig& config);
std::unique_ptr<ProcessModel> MakeOdometryProcessModel(const EkfConfig& config);

// VO noise shared by both models: reported * vo.cov_scale, plus sigma_rel^2 on
// the translation axes, floored at vo.min_sigma_t_m / vo.min_sigma_rot_rad.
Mat6 ScaledVoNoise(const EkfConfig& config, const Mat6& reported, const Vec3& sigma_rel);

}  // namespace locaid::fusion
