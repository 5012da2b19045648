// Every EKF model's analytic Jacobian against central differences, as one
// property over curated states (Sophus's style: a list of states picked for
// what breaks Jacobians, the identity, a heading next to +-pi, a car pitched
// and rolled with biases, far from the origin and fast, plus seeded random
// draws; one check that every model meets at every state).
#include "fusion/ekf_models.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace locaid::fusion {
namespace {

constexpr double kStep = 1e-6;         // finite-difference step
constexpr double kJacobianTol = 1e-5;  // max abs difference numeric vs analytic

using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using Vec15 = Eigen::Matrix<double, 15, 1>;

// A state of the filter and the inputs its models take besides it: the IMU
// reading, the pose of the clone and the body motion from it (as VO measures
// it, a little off, so residuals are not zero), the GPS antenna, the speed
// sensor's mounting and the VO calibration.
struct CuratedState {
  std::string name;
  NominalState x;
  Vec3 f_body_mps2 = Vec3(0, 0, 9.81), w_body_radps = Vec3::Zero();
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // body motion clone -> now
  Vec3 p_clone = Vec3::Zero();
  Mat3 R_clone = Mat3::Identity();
  Eigen::Isometry3d measured = Eigen::Isometry3d::Identity();  // the motion as VO measures it
  Vec3 lever_body_m = Vec3::Zero();
  double latency_s = 0;
  Mat3 R_vehicle_body = Mat3::Identity(), R_boresight = Mat3::Identity();
  double scale_error = 0;
};

std::ostream& operator<<(std::ostream& os, const CuratedState& s) { return os << s.name; }

CuratedState Named(std::string name) {
  CuratedState s;
  s.name = std::move(name);
  return s;
}

// The clone is where `motion` started; VO measures the motion off by a small
// rotation and translation (and the scale error, for the VO calibration).
CuratedState Complete(CuratedState s, const Vec3& rotation_error, const Vec3& translation_error) {
  s.R_clone = s.x.R_enu_body * s.motion.linear().transpose();
  s.p_clone = s.x.p_enu_m - s.R_clone * s.motion.translation();
  s.measured.linear() = s.motion.linear() * ExpSO3(rotation_error);
  s.measured.translation() = (1 + s.scale_error) * s.motion.translation() + translation_error;
  return s;
}

Eigen::Isometry3d Motion(const Vec3& rotation, const Vec3& translation) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = ExpSO3(rotation);
  T.translation() = translation;
  return T;
}

std::vector<CuratedState> CuratedStates() {
  std::vector<CuratedState> states;
  {
    CuratedState s = Named("identity");  // at the origin, level, standing, nothing mounted off the body's origin
    states.push_back(Complete(s, Vec3(0.01, -0.02, 0.005), Vec3(0.02, -0.01, 0.01)));
  }
  {
    CuratedState s = Named("driving_north_east");
    s.x.R_enu_body = ExpSO3(Vec3(0, 0, M_PI / 4));
    s.x.v_enu_mps = Vec3(7, 7, 0.1);
    s.w_body_radps = Vec3(0.01, -0.02, 0.1);
    s.motion = Motion(Vec3(0, 0, 0.01), Vec3(1.0, 0.02, 0.01));
    s.lever_body_m = Vec3(1.2, 0.9, 0.3);
    s.latency_s = 0.1;
    s.R_vehicle_body = ExpSO3(Vec3(0.01, -0.02, 0.03));
    s.R_boresight = ExpSO3(Vec3(0.005, 0.01, -0.008));
    s.scale_error = 0.02;
    states.push_back(Complete(s, Vec3(-0.01, 0.02, 0.01), Vec3(0.05, -0.03, 0.02)));
  }
  {
    CuratedState s = Named("heading_next_to_pi");  // yaw wraps around between the clone and now
    s.x.p_enu_m = Vec3(-120, 40, 3);
    s.x.R_enu_body = ExpSO3(Vec3(0, 0, M_PI - 1e-3));
    s.x.v_enu_mps = Vec3(-12, 0.01, 0);
    s.w_body_radps = Vec3(0, 0, 0.05);
    s.motion = Motion(Vec3(0, 0, 0.02), Vec3(1.2, 0, 0));
    s.lever_body_m = Vec3(-0.5, 0, 1.5);
    s.latency_s = 0.05;
    states.push_back(Complete(s, Vec3(0.003, 0.002, -0.01), Vec3(-0.02, 0.04, 0.0)));
  }
  {
    CuratedState s = Named("pitched_rolled_with_biases");  // on a slope, banked, biased sensors
    s.x.p_enu_m = Vec3(30, -60, 12);
    s.x.R_enu_body = ExpSO3(Vec3(0.1, -0.15, 1.0));
    s.x.v_enu_mps = Vec3(3, 5, -0.8);
    s.x.accel_bias_mps2 = Vec3(0.05, -0.04, 0.06);
    s.x.gyro_bias_radps = Vec3(0.002, -0.003, 0.001);
    s.f_body_mps2 = Vec3(1.5, -0.9, 9.6);
    s.w_body_radps = Vec3(0.2, -0.1, 0.3);
    s.motion = Motion(Vec3(0.02, -0.03, 0.05), Vec3(0.6, -0.05, 0.1));
    s.lever_body_m = Vec3(0.3, -1.1, 0.8);
    s.latency_s = 0.2;
    s.R_vehicle_body = ExpSO3(Vec3(-0.04, 0.03, 0.02));
    s.R_boresight = ExpSO3(Vec3(-0.01, 0.004, 0.012));
    s.scale_error = -0.03;
    states.push_back(Complete(s, Vec3(0.02, 0.01, -0.02), Vec3(0.01, 0.05, -0.04)));
  }
  {
    CuratedState s = Named("far_and_fast");  // kilometres from the origin, motorway speed, turning hard
    s.x.p_enu_m = Vec3(5000, -3000, 200);
    s.x.R_enu_body = ExpSO3(Vec3(-0.02, 0.03, -2.0));
    s.x.v_enu_mps = Vec3(-12, -27, 0.3);
    s.f_body_mps2 = Vec3(-2, 4, 9.9);
    s.w_body_radps = Vec3(0.05, 0.02, 0.5);
    s.motion = Motion(Vec3(0.01, 0.0, 0.15), Vec3(3.0, 0.1, 0.02));
    s.lever_body_m = Vec3(2.0, 0.0, 1.4);
    s.latency_s = 0.15;
    s.R_vehicle_body = ExpSO3(Vec3(0.0, 0.05, -0.05));
    s.scale_error = 0.01;
    states.push_back(Complete(s, Vec3(-0.005, 0.01, 0.03), Vec3(0.1, -0.05, 0.02)));
  }
  // Seeded random draws around a moving car (the earlier per-model draws).
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n01;
  auto v3 = [&](double a, double b, double c) { return Vec3(a * n01(rng), b * n01(rng), c * n01(rng)); };
  for (int i = 0; i < 8; ++i) {
    CuratedState s = Named("random_" + std::to_string(i));
    s.x.p_enu_m = v3(100, 100, 5);
    s.x.v_enu_mps = v3(8, 8, 0.5);
    s.x.R_enu_body = ExpSO3(v3(0.1, 0.1, 3));
    s.x.accel_bias_mps2 = v3(0.05, 0.05, 0.05);
    s.x.gyro_bias_radps = v3(0.002, 0.002, 0.002);
    s.f_body_mps2 = v3(2, 2, 1) + Vec3(0, 0, 9.81);
    s.w_body_radps = v3(0.3, 0.3, 0.5);
    s.motion = Motion(v3(0.05, 0.05, 0.05), v3(1, 0.1, 0.05) + Vec3(1, 0, 0));
    s.lever_body_m = v3(1.5, 1.5, 0.5);
    s.latency_s = 0.2 * std::abs(n01(rng));
    s.R_vehicle_body = ExpSO3(v3(0.05, 0.05, 0.05));
    s.R_boresight = ExpSO3(v3(0.01, 0.01, 0.01));
    s.scale_error = 0.02 * n01(rng);
    const Vec3 rotation_error = v3(0.02, 0.02, 0.02), translation_error = v3(0.05, 0.05, 0.05);
    states.push_back(Complete(s, rotation_error, translation_error));
  }
  return states;
}

// One model at one state: its analytic Jacobian, and the function whose
// derivative it is, of a perturbation `d` of the model's error states
// (residual models give -r: their convention is r(x (+) dx) ~= r(x) - H dx).
// `compare` maps the Jacobian to what the model computes when that is not
// the Jacobian itself (a covariance propagated through it).
struct Check {
  Mat analytic;
  int n = 0;
  std::function<Vec(const Vec&)> f;
  std::function<Mat(const Mat&)> compare = [](const Mat& J) { return J; };
  double tol = kJacobianTol;
};

struct Model {
  std::string name;
  std::function<Check(const CuratedState&)> at;
};

std::ostream& operator<<(std::ostream& os, const Model& m) { return os << m.name; }

Vec15 Head15(const Vec& d) { return d.head<15>(); }

Model Imu(double dt, const std::string& name) {
  return {name, [dt](const CuratedState& s) {
            const Vec3 g(0, 0, -9.81);
            const NominalState y0 = IntegrateImuStep(s.x, s.f_body_mps2, s.w_body_radps, dt, g);
            return Check{ImuTransitionJacobian(s.x, s.f_body_mps2, s.w_body_radps, dt), 15, [=](const Vec& d) -> Vec {
                           return BoxMinus(IntegrateImuStep(BoxPlus(s.x, Head15(d)), s.f_body_mps2, s.w_body_radps,
                                                            dt, g),
                                           y0);
                         }};
          }};
}

// A pose perturbed by [dp, dtheta] (global attitude error).
void Perturb(const Vec& d, Vec3& p, Mat3& R) {
  p += d.head<3>();
  R = ExpSO3(d.segment<3>(3)) * R;
}

std::vector<Model> Models() {
  std::vector<Model> models{Imu(0.001, "imu_1ms"), Imu(0.01, "imu_10ms"), Imu(0.1, "imu_100ms"),
                            Imu(0.5, "imu_500ms")};
  models.push_back({"vo", [](const CuratedState& s) {
                      const Vec3 p = s.x.p_enu_m;
                      const Mat3 R = s.x.R_enu_body;
                      return Check{VoJacobian(p, R, s.p_clone, s.R_clone, s.measured), 12, [=](const Vec& d) -> Vec {
                                     Vec3 pp = p, pc = s.p_clone;
                                     Mat3 RR = R, Rc = s.R_clone;
                                     Perturb(d.head<6>(), pp, RR);
                                     Perturb(d.tail<6>(), pc, Rc);
                                     return -VoResidual(pp, RR, pc, Rc, s.measured);
                                   }};
                    }});
  models.push_back({"vo_calibration", [](const CuratedState& s) {
                      return Check{VoCalibrationJacobian(s.measured.linear(), s.measured.translation(), s.R_boresight,
                                                         s.scale_error),
                                   kVoCalibStates, [=](const Vec& d) -> Vec {
                                     Eigen::Isometry3d corrected = s.measured;
                                     corrected.translation() = CorrectVoTranslation(
                                         s.measured.translation(), ExpSO3(d.head<3>()) * s.R_boresight,
                                         s.scale_error + d[3]);
                                     return -VoResidual(s.x.p_enu_m, s.x.R_enu_body, s.p_clone, s.R_clone, corrected);
                                   }};
                    }});
  models.push_back({"gps_antenna", [](const CuratedState& s) {
                      return Check{GpsAntennaJacobian(s.x.R_enu_body, s.lever_body_m, s.latency_s), 9,
                                   [=](const Vec& d) -> Vec {
                                     Vec15 dx = Vec15::Zero();
                                     dx.head<9>() = d;  // [dp, dv, dtheta]: the first 9 error states
                                     const NominalState x = BoxPlus(s.x, dx);
                                     return GpsAntennaPrediction(x.p_enu_m, x.v_enu_mps, x.R_enu_body, s.lever_body_m,
                                                                 s.latency_s);
                                   }};
                    }});
  models.push_back({"gps", [](const CuratedState& s) {
                      // h(x) = p over the IMU model's states with the clone and the calibration (21).
                      return Check{GpsJacobian(21), 21,
                                   [=](const Vec& d) -> Vec { return BoxPlus(s.x, Head15(d)).p_enu_m; }};
                    }});
  // Without IMU: the pose after the motion, as [p, Log(R R0^T)] from where it goes unperturbed.
  auto odometry_after = [](const CuratedState& s, Vec3 p, Mat3 R, const Eigen::Isometry3d& T) -> Vec {
    Vec3 p0 = s.x.p_enu_m;
    Mat3 R0 = s.x.R_enu_body;
    OdometryPropagate(p0, R0, s.motion);
    OdometryPropagate(p, R, T);
    Vec6 d;
    d.head<3>() = p - p0;
    d.tail<3>() = LogSO3(R * R0.transpose());
    return d;
  };
  models.push_back({"odometry_transition", [=](const CuratedState& s) {
                      return Check{OdometryTransitionJacobian(s.x.R_enu_body, s.motion), 6, [=](const Vec& d) -> Vec {
                                     Vec3 p = s.x.p_enu_m;
                                     Mat3 R = s.x.R_enu_body;
                                     Perturb(d, p, R);
                                     return odometry_after(s, p, R, s.motion);
                                   }};
                    }});
  models.push_back({"odometry_noise", [=](const CuratedState& s) {
                      // The VO noise in the motion's own axes: [n_t, n_theta].
                      return Check{OdometryNoiseJacobian(s.x.R_enu_body, s.motion), 6, [=](const Vec& d) -> Vec {
                                     Eigen::Isometry3d T = s.motion;
                                     T.translation() += s.motion.linear() * d.head<3>();
                                     T.linear() = s.motion.linear() * ExpSO3(d.tail<3>());
                                     return odometry_after(s, s.x.p_enu_m, s.x.R_enu_body, T);
                                   }};
                    }});
  models.push_back({"camera_motion_to_body_covariance", [](const CuratedState& s) {
                      // A KITTI-like cam0 <- imu extrinsic; the body motion seen by the camera.
                      Eigen::Isometry3d T_cam_body = Eigen::Isometry3d::Identity();
                      T_cam_body.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
                      T_cam_body.linear() = T_cam_body.linear() * ExpSO3(Vec3(0.01, -0.02, 0.005));
                      T_cam_body.translation() = Vec3(-0.33, 0.72, -1.08);
                      const Eigen::Isometry3d T_cam = T_cam_body * s.motion * T_cam_body.inverse();
                      Mat6 C = Mat6::Zero();
                      C.diagonal() << 0.01, 0.02, 0.03, 1e-4, 2e-4, 3e-4;
                      C(0, 4) = C(4, 0) = 1e-4;
                      const VoMeasurement m0 = CameraMotionToBody(T_cam, Mat6::Identity(), T_cam_body);
                      Check c;
                      c.analytic = CameraMotionToBody(T_cam, C, T_cam_body).covariance;
                      c.n = 6;
                      // The body motion's error [dt, dtheta] (its own axes) for a camera motion error.
                      c.f = [=](const Vec& d) -> Vec {
                        Eigen::Isometry3d Tc = T_cam;
                        Tc.translation() += T_cam.linear() * d.head<3>();
                        Tc.linear() = T_cam.linear() * ExpSO3(d.tail<3>());
                        const Eigen::Isometry3d Tb = T_cam_body.inverse() * Tc * T_cam_body;
                        Vec6 r;
                        r.head<3>() = m0.T_prev_curr.linear().transpose() * (Tb.translation() - m0.T_prev_curr.translation());
                        r.tail<3>() = LogSO3(m0.T_prev_curr.linear().transpose() * Tb.linear());
                        return r;
                      };
                      c.compare = [C](const Mat& J) -> Mat { return J * C * J.transpose(); };
                      c.tol = 1e-8;
                      return c;
                    }});
  models.push_back({"vehicle_velocity", [](const CuratedState& s) {
                      // The speed reading and the non-holonomic constraints both measure v_veh.
                      return Check{VehicleVelocityJacobian(s.x.v_enu_mps, s.x.R_enu_body, s.R_vehicle_body), 6,
                                   [=](const Vec& d) -> Vec {
                                     Vec15 dx = Vec15::Zero();
                                     dx.segment<6>(3) = d;  // [dv, dtheta]: error states 3..8
                                     const NominalState x = BoxPlus(s.x, dx);
                                     return VehicleVelocity(x.v_enu_mps, x.R_enu_body, s.R_vehicle_body);
                                   }};
                    }});
  return models;
}

// Central differences of f along each of the n error states.
Mat CentralDifferences(int n, const std::function<Vec(const Vec&)>& f) {
  Mat J;
  for (int j = 0; j < n; ++j) {
    Vec d = Vec::Zero(n);
    d[j] = kStep;
    const Vec column = (f(d) - f(-d)) / (2 * kStep);
    if (j == 0) J.resize(column.size(), n);
    J.col(j) = column;
  }
  return J;
}

class JacobianProperty : public ::testing::TestWithParam<std::tuple<Model, CuratedState>> {};

TEST_P(JacobianProperty, AnalyticMatchesCentralDifferences) {
  const auto& [model, state] = GetParam();
  const Check c = model.at(state);
  const Mat numeric = c.compare(CentralDifferences(c.n, c.f));
  ASSERT_EQ(numeric.rows(), c.analytic.rows());
  ASSERT_EQ(numeric.cols(), c.analytic.cols());
  EXPECT_LT((c.analytic - numeric).cwiseAbs().maxCoeff(), c.tol)
      << model.name << " at " << state.name << "\nanalytic\n" << c.analytic << "\nnumeric\n" << numeric;
}

INSTANTIATE_TEST_SUITE_P(EveryModelAtEveryState, JacobianProperty,
                         ::testing::Combine(::testing::ValuesIn(Models()), ::testing::ValuesIn(CuratedStates())),
                         [](const auto& info) {
                           return std::get<0>(info.param).name + "_at_" + std::get<1>(info.param).name;
                         });

TEST(GpsJacobian, TheCloneAndCalibrationColumnsAreExactlyZero) {
  EXPECT_EQ(GpsJacobian(21).rightCols(6).cwiseAbs().maxCoeff(), 0.0);
}

TEST(CameraMotionToBody, KeepsTheMotionARotation) {
  for (const CuratedState& s : CuratedStates()) {
    Eigen::Isometry3d T_cam_body = Eigen::Isometry3d::Identity();
    T_cam_body.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
    const VoMeasurement m = CameraMotionToBody(T_cam_body * s.motion * T_cam_body.inverse(), Mat6::Identity(),
                                               T_cam_body);
    EXPECT_NEAR(m.T_prev_curr.linear().determinant(), 1.0, 1e-12) << s.name;
  }
}

TEST(ChiSquareQuantile, MatchesTables) {
  // Reference values from standard chi-square tables.
  constexpr double kTableTol = 2e-3;  // tables give 3 decimals
  EXPECT_NEAR(ChiSquareQuantile(0.95, 3), 7.815, kTableTol);
  EXPECT_NEAR(ChiSquareQuantile(0.999, 3), 16.266, kTableTol);
  EXPECT_NEAR(ChiSquareQuantile(0.9999, 6), 27.856, kTableTol);
  EXPECT_NEAR(ChiSquareQuantile(0.025, 30), 16.791, kTableTol);
  EXPECT_NEAR(ChiSquareQuantile(0.975, 30), 46.979, kTableTol);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 1), 3.841, kTableTol);
}

TEST(VehicleVelocity, IsTheBodyVelocityInVehicleAxes) {
  // A car heading north-east at 10 m/s, IMU aligned: all of it forward.
  NominalState x;
  x.R_enu_body = ExpSO3(Vec3(0, 0, M_PI / 4));
  x.v_enu_mps = Vec3(10 / std::sqrt(2.0), 10 / std::sqrt(2.0), 0);
  const Vec3 v = VehicleVelocity(x.v_enu_mps, x.R_enu_body, Mat3::Identity());
  EXPECT_NEAR(v.x(), 10.0, 1e-12);
  EXPECT_NEAR(v.y(), 0.0, 1e-12);
  EXPECT_NEAR(v.z(), 0.0, 1e-12);
}

}  // namespace
}  // namespace locaid::fusion
