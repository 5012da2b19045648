// Numeric-vs-analytic Jacobians of every EKF model.
#include "fusion/ekf_models.hpp"

#include <gtest/gtest.h>

#include <random>

namespace locaid::fusion {
namespace {

constexpr double kStep = 1e-6;       // finite-difference step
constexpr double kJacobianTol = 1e-5;  // max abs difference numeric vs analytic

NominalState RandomState(std::mt19937_64& rng) {
  std::normal_distribution<double> n01;
  NominalState x;
  x.p_enu_m = Vec3(100 * n01(rng), 100 * n01(rng), 5 * n01(rng));
  x.v_enu_mps = Vec3(8 * n01(rng), 8 * n01(rng), 0.5 * n01(rng));
  x.R_enu_body = ExpSO3(Vec3(0.1 * n01(rng), 0.1 * n01(rng), 3 * n01(rng)));
  x.accel_bias_mps2 = 0.05 * Vec3(n01(rng), n01(rng), n01(rng));
  x.gyro_bias_radps = 0.002 * Vec3(n01(rng), n01(rng), n01(rng));
  return x;
}

class ImuJacobianTest : public ::testing::TestWithParam<double> {};

TEST_P(ImuJacobianTest, MatchesFiniteDifferences) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n01;
  const double dt = GetParam();
  const Vec3 g(0, 0, -9.81);
  for (int trial = 0; trial < 5; ++trial) {
    const NominalState x = RandomState(rng);
    const Vec3 f(2 * n01(rng), 2 * n01(rng), 9.81 + n01(rng));
    const Vec3 w(0.3 * n01(rng), 0.3 * n01(rng), 0.5 * n01(rng));
    const Mat15 F = ImuTransitionJacobian(x, f, w, dt);
    const NominalState y0 = IntegrateImuStep(x, f, w, dt, g);
    Mat15 F_num;
    for (int j = 0; j < 15; ++j) {
      Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
      d[j] = kStep;
      const auto yp = IntegrateImuStep(BoxPlus(x, d), f, w, dt, g);
      const auto ym = IntegrateImuStep(BoxPlus(x, -d), f, w, dt, g);
      F_num.col(j) = (BoxMinus(yp, y0) - BoxMinus(ym, y0)) / (2 * kStep);
    }
    EXPECT_LT((F - F_num).cwiseAbs().maxCoeff(), kJacobianTol) << "dt " << dt << "\nF\n" << F << "\nnum\n" << F_num;
  }
}

INSTANTIATE_TEST_SUITE_P(Steps, ImuJacobianTest, ::testing::Values(0.001, 0.01, 0.1, 0.5));

TEST(VoJacobian, MatchesFiniteDifferences) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 10; ++trial) {
    const NominalState a = RandomState(rng), b = RandomState(rng);
    const Vec3 p = a.p_enu_m, p_c = p + Vec3(n01(rng), n01(rng), 0.1 * n01(rng));
    const Mat3 R = a.R_enu_body, R_c = R * ExpSO3(0.1 * Vec3(n01(rng), n01(rng), n01(rng)));
    // A measurement near (not at) the prediction, so the residual is non-zero.
    Eigen::Isometry3d T_m = Eigen::Isometry3d::Identity();
    T_m.linear() = R_c.transpose() * R * ExpSO3(0.02 * Vec3(n01(rng), n01(rng), n01(rng)));
    T_m.translation() = R_c.transpose() * (p - p_c) + 0.05 * Vec3(n01(rng), n01(rng), n01(rng));
    (void)b;
    const MatVoH H = VoJacobian(p, R, p_c, R_c, T_m);
    MatVoH H_num;
    for (int j = 0; j < 12; ++j) {
      auto eval = [&](double s) {
        Vec3 pp = p, ppc = p_c;
        Mat3 RR = R, RRc = R_c;
        Vec3 d = Vec3::Zero();
        d[j % 3] = s;
        if (j < 3) pp += d;
        else if (j < 6) RR = ExpSO3(d) * R;
        else if (j < 9) ppc += d;
        else RRc = ExpSO3(d) * R_c;
        return VoResidual(pp, RR, ppc, RRc, T_m);
      };
      // r(x + dx) ~= r(x) - H dx
      H_num.col(j) = -(eval(kStep) - eval(-kStep)) / (2 * kStep);
    }
    EXPECT_LT((H - H_num).cwiseAbs().maxCoeff(), kJacobianTol) << "H\n" << H << "\nnum\n" << H_num;
  }
}

TEST(VoCalibrationJacobian, MatchesFiniteDifferences) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 10; ++trial) {
    const NominalState a = RandomState(rng);
    const Vec3 p = a.p_enu_m, p_c = p + Vec3(n01(rng), n01(rng), 0.1 * n01(rng));
    const Mat3 R = a.R_enu_body, R_c = R * ExpSO3(0.05 * Vec3(n01(rng), n01(rng), n01(rng)));
    Eigen::Isometry3d T_m = Eigen::Isometry3d::Identity();
    T_m.linear() = (R_c.transpose() * R) * ExpSO3(0.01 * Vec3(n01(rng), n01(rng), n01(rng)));
    T_m.translation() = 1.02 * (R_c.transpose() * (p - p_c)) + 0.05 * Vec3(n01(rng), n01(rng), n01(rng));
    const Mat3 R_b = ExpSO3(0.01 * Vec3(n01(rng), n01(rng), n01(rng)));
    const double s = 0.02 * n01(rng);
    auto residual = [&](const Mat3& Rb, double scale) {
      Eigen::Isometry3d corrected = T_m;
      corrected.translation() = CorrectVoTranslation(T_m.translation(), Rb, scale);
      return VoResidual(p, R, p_c, R_c, corrected);
    };
    const auto H = VoCalibrationJacobian(T_m.linear(), T_m.translation(), R_b, s);
    Eigen::Matrix<double, 6, kVoCalibStates> H_num;
    for (int j = 0; j < 3; ++j) {
      Vec3 d = Vec3::Zero();
      d[j] = kStep;
      H_num.col(j) = -(residual(ExpSO3(d) * R_b, s) - residual(ExpSO3(-d) * R_b, s)) / (2 * kStep);
    }
    H_num.col(3) = -(residual(R_b, s + kStep) - residual(R_b, s - kStep)) / (2 * kStep);
    EXPECT_LT((H - H_num).cwiseAbs().maxCoeff(), kJacobianTol) << "H\n" << H << "\nnum\n" << H_num;
  }
}

TEST(GpsAntennaJacobian, MatchesFiniteDifferences) {
  std::mt19937_64 rng(13);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 10; ++trial) {
    const NominalState x = RandomState(rng);
    const Vec3 lever(1.5 * n01(rng), 1.5 * n01(rng), 0.5 * n01(rng));
    const double latency = 0.2 * std::abs(n01(rng));
    const auto H = GpsAntennaJacobian(x.R_enu_body, lever, latency);
    Eigen::Matrix<double, 3, 9> H_num;
    for (int j = 0; j < 9; ++j) {
      Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
      d[j] = kStep;  // [dp, dv, dtheta] are the first 9 error states
      const NominalState xp = BoxPlus(x, d), xm = BoxPlus(x, -d);
      H_num.col(j) = (GpsAntennaPrediction(xp.p_enu_m, xp.v_enu_mps, xp.R_enu_body, lever, latency) -
                      GpsAntennaPrediction(xm.p_enu_m, xm.v_enu_mps, xm.R_enu_body, lever, latency)) /
                     (2 * kStep);
    }
    EXPECT_LT((H - H_num).cwiseAbs().maxCoeff(), kJacobianTol) << "H\n" << H << "\nnum\n" << H_num;
  }
}

TEST(GpsJacobian, MatchesFiniteDifferences) {
  std::mt19937_64 rng(3);
  const NominalState x = RandomState(rng);
  const Eigen::MatrixXd H = GpsJacobian(21);
  ASSERT_EQ(H.rows(), 3);
  ASSERT_EQ(H.cols(), 21);
  // h(x) = p; perturb the first 15 error states through BoxPlus.
  for (int j = 0; j < 15; ++j) {
    Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
    d[j] = kStep;
    const Vec3 num = (BoxPlus(x, d).p_enu_m - BoxPlus(x, -d).p_enu_m) / (2 * kStep);
    EXPECT_LT((H.col(j) - num).cwiseAbs().maxCoeff(), kJacobianTol) << "column " << j;
  }
  EXPECT_EQ(H.rightCols(6).cwiseAbs().maxCoeff(), 0.0);
}

TEST(OdometryJacobians, MatchFiniteDifferences) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 10; ++trial) {
    const NominalState x = RandomState(rng);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = ExpSO3(0.05 * Vec3(n01(rng), n01(rng), n01(rng)));
    T.translation() = Vec3(1 + n01(rng), 0.1 * n01(rng), 0.05 * n01(rng));
    const Mat6 F = OdometryTransitionJacobian(x.R_enu_body, T);
    const Mat6 G = OdometryNoiseJacobian(x.R_enu_body, T);
    Vec3 p0 = x.p_enu_m; Mat3 R0 = x.R_enu_body;
    OdometryPropagate(p0, R0, T);
    auto diff = [&](const Vec3& p, const Mat3& R) {
      Vec6 d;
      d.head<3>() = p - p0;
      d.tail<3>() = LogSO3(R * R0.transpose());
      return d;
    };
    Mat6 F_num, G_num;
    for (int j = 0; j < 6; ++j) {
      auto eval_state = [&](double s) {
        Vec3 p = x.p_enu_m; Mat3 R = x.R_enu_body;
        Vec3 d = Vec3::Zero(); d[j % 3] = s;
        if (j < 3) p += d; else R = ExpSO3(d) * R;
        OdometryPropagate(p, R, T);
        return diff(p, R);
      };
      F_num.col(j) = (eval_state(kStep) - eval_state(-kStep)) / (2 * kStep);
      auto eval_noise = [&](double s) {
        Vec3 p = x.p_enu_m; Mat3 R = x.R_enu_body;
        Vec3 d = Vec3::Zero(); d[j % 3] = s;
        Eigen::Isometry3d Tn = T;
        if (j < 3) Tn.translation() += T.linear() * d; else Tn.linear() = T.linear() * ExpSO3(d);
        OdometryPropagate(p, R, Tn);
        return diff(p, R);
      };
      G_num.col(j) = (eval_noise(kStep) - eval_noise(-kStep)) / (2 * kStep);
    }
    EXPECT_LT((F - F_num).cwiseAbs().maxCoeff(), kJacobianTol);
    EXPECT_LT((G - G_num).cwiseAbs().maxCoeff(), kJacobianTol);
  }
}

TEST(CameraMotionToBody, CovarianceMatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01;
  // KITTI-like cam0 <- imu extrinsic.
  Eigen::Isometry3d T_cam_body = Eigen::Isometry3d::Identity();
  T_cam_body.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  T_cam_body.linear() = T_cam_body.linear() * ExpSO3(Vec3(0.01, -0.02, 0.005));
  T_cam_body.translation() = Vec3(-0.33, 0.72, -1.08);
  Eigen::Isometry3d T_cam = Eigen::Isometry3d::Identity();
  T_cam.linear() = ExpSO3(Vec3(0.01, 0.05, -0.02));
  T_cam.translation() = Vec3(0.1, -0.02, 1.2);
  // Build the Jacobian of body perturbation w.r.t. camera perturbation numerically.
  const VoMeasurement m0 = CameraMotionToBody(T_cam, Mat6::Identity(), T_cam_body);
  Mat6 J;
  for (int j = 0; j < 6; ++j) {
    auto eval = [&](double s) {
      Vec3 d = Vec3::Zero(); d[j % 3] = s;
      Eigen::Isometry3d Tc = T_cam;
      if (j < 3) Tc.translation() += T_cam.linear() * d; else Tc.linear() = T_cam.linear() * ExpSO3(d);
      const Eigen::Isometry3d Tb = T_cam_body.inverse() * Tc * T_cam_body;
      Vec6 r;
      r.head<3>() = m0.T_prev_curr.linear().transpose() * (Tb.translation() - m0.T_prev_curr.translation());
      r.tail<3>() = LogSO3(m0.T_prev_curr.linear().transpose() * Tb.linear());
      return r;
    };
    J.col(j) = (eval(kStep) - eval(-kStep)) / (2 * kStep);
  }
  Mat6 C = Mat6::Zero();
  C.diagonal() << 0.01, 0.02, 0.03, 1e-4, 2e-4, 3e-4;
  C(0, 4) = C(4, 0) = 1e-4;
  const Mat6 expected = J * C * J.transpose();
  const VoMeasurement m = CameraMotionToBody(T_cam, C, T_cam_body);
  EXPECT_LT((m.covariance - expected).cwiseAbs().maxCoeff(), 1e-8);
  // Motion: body displacement has the camera's length up to the lever arm effect.
  EXPECT_NEAR(m.T_prev_curr.linear().determinant(), 1.0, 1e-12);
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

TEST(VehicleVelocityJacobian, MatchesFiniteDifferences) {
  // The speed reading and the non-holonomic constraints both measure v_veh.
  std::mt19937_64 rng(21);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 10; ++trial) {
    const NominalState x = RandomState(rng);
    const Mat3 R_vb = ExpSO3(Vec3(0.05 * n01(rng), 0.05 * n01(rng), 0.05 * n01(rng)));
    const auto H = VehicleVelocityJacobian(x.v_enu_mps, x.R_enu_body, R_vb);
    Eigen::Matrix<double, 3, 6> H_num;
    for (int j = 0; j < 6; ++j) {
      Eigen::Matrix<double, 15, 1> d = Eigen::Matrix<double, 15, 1>::Zero();
      d[3 + j] = kStep;  // [dv, dtheta] are error states 3..8
      const NominalState xp = BoxPlus(x, d), xm = BoxPlus(x, -d);
      H_num.col(j) = (VehicleVelocity(xp.v_enu_mps, xp.R_enu_body, R_vb) -
                      VehicleVelocity(xm.v_enu_mps, xm.R_enu_body, R_vb)) / (2 * kStep);
    }
    EXPECT_LT((H - H_num).cwiseAbs().maxCoeff(), kJacobianTol) << "H\n" << H << "\nnum\n" << H_num;
  }
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
