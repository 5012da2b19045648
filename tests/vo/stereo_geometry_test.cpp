// Free functions of vo/stereo_geometry.hpp.
#include "core/stereo_camera.hpp"
#include "vo/stereo_geometry.hpp"

#include "tests/vo/synthetic_scene.hpp"

#include <gtest/gtest.h>

#include <random>

namespace locaid::vo {
namespace {

constexpr double kTightTol = 1e-9;
constexpr double kPoseTolM = 0.01;
constexpr double kPoseTolRad = 5e-4;

TEST(StereoGeometry, ExpLogRoundTripAndScale) {
  Vector6d d;
  d << 0.3, -0.2, 1.1, 0.05, -0.02, 0.1;
  EXPECT_TRUE(LogSE3(ExpSE3(d)).isApprox(d, kTightTol));
  const Eigen::Isometry3d half = ScaleMotion(ExpSE3(d), 0.5);
  EXPECT_TRUE((half * half).matrix().isApprox(ExpSE3(d).matrix(), 1e-2));
  EXPECT_TRUE(ScaleMotion(ExpSE3(d), 0.0).matrix().isApprox(Eigen::Matrix4d::Identity()));
}

TEST(StereoGeometry, TriangulateInvertsProjection) {
  const StereoCamera cam = testing::SyntheticCamera();
  const Eigen::Vector3d p(1.5, -0.4, 12.0);
  const double u = cam.fx * p.x() / p.z() + cam.cx, v = cam.fy * p.y() / p.z() + cam.cy;
  const double ur = cam.fx * (p.x() - cam.baseline_m) / p.z() + cam.cx;
  EXPECT_TRUE(TriangulateStereo(cam, u, v, ur).isApprox(p, kTightTol));
}

TEST(StereoGeometry, RefineRecoversPoseWithNoiseAndOutliers) {
  const StereoCamera cam = testing::SyntheticCamera();
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> ux(-8, 8), uy(-2, 1.5), uz(4, 40);
  std::normal_distribution<double> noise(0, 0.3);
  Vector6d d;
  d << 0.1, -0.02, 1.0, 0.002, 0.01, -0.003;
  const Eigen::Isometry3d T_ref_curr = ExpSE3(d);
  const Eigen::Isometry3d T_curr_ref = T_ref_curr.inverse();
  std::vector<StereoObservation> obs;
  while (obs.size() < 300) {
    StereoObservation ob;
    ob.p_ref = {ux(rng), uy(rng), uz(rng)};
    const Eigen::Vector3d q = T_curr_ref * ob.p_ref;
    if (q.z() < 1) continue;
    ob.uv_left = {cam.fx * q.x() / q.z() + cam.cx + noise(rng),
                  cam.fy * q.y() / q.z() + cam.cy + noise(rng)};
    ob.u_right = cam.fx * (q.x() - cam.baseline_m) / q.z() + cam.cx + noise(rng);
    ob.has_right = obs.size() % 3 != 0;
    if (obs.size() % 10 == 0) ob.uv_left += Eigen::Vector2d(25, -14);  // 10 % outliers
    obs.push_back(ob);
  }
  const PoseRefinement r = RefineStereoPose(obs, cam, ExpSE3(0.3 * d));
  ASSERT_TRUE(r.ok);
  const Eigen::Isometry3d err = T_ref_curr.inverse() * r.T_ref_curr;
  EXPECT_LT(err.translation().norm(), kPoseTolM);
  EXPECT_LT(Eigen::AngleAxisd(err.rotation()).angle(), kPoseTolRad);
  EXPECT_NEAR(r.inliers, 270, 5);
  EXPECT_NEAR(r.sigma_px, 0.3, 0.1);
  // The error is consistent with the covariance (Mahalanobis, 6 dof, generous bound).
  const Vector6d e = LogSE3(err);
  EXPECT_LT(e.dot(r.covariance.ldlt().solve(e)), 30.0);
}

// Forward rows (p_ref in the current images) agree with pose A, reverse rows
// (p_curr in the reference images) with pose B = A rotated by a small yaw: the
// symmetric solution lies between them; without reverse rows it is A.
TEST(StereoGeometry, ReverseRowsPullTowardsTheirPose) {
  const StereoCamera cam = testing::SyntheticCamera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-8, 8), uy(-2, 1.5), uz(4, 40);
  Vector6d a;
  a << 0.05, -0.01, 0.9, 0.001, 0.004, -0.002;
  constexpr double kGapRad = 0.004;
  Vector6d gap = Vector6d::Zero();
  gap(4) = kGapRad;
  const Eigen::Isometry3d T_a = ExpSE3(a), T_b = ExpSE3(a) * ExpSE3(gap);
  const auto project = [&](const Eigen::Vector3d& q, Eigen::Vector2d& uv, double& ur) {
    uv = {cam.fx * q.x() / q.z() + cam.cx, cam.fy * q.y() / q.z() + cam.cy};
    ur = cam.fx * (q.x() - cam.baseline_m) / q.z() + cam.cx;
  };
  std::vector<StereoObservation> obs;
  while (obs.size() < 200) {
    StereoObservation ob;
    ob.p_ref = {ux(rng), uy(rng), uz(rng)};
    const Eigen::Vector3d q = T_a.inverse() * ob.p_ref;
    if (q.z() < 1) continue;
    project(q, ob.uv_left, ob.u_right);
    ob.has_right = true;
    ob.has_reverse = true;
    ob.p_curr = T_b.inverse() * ob.p_ref;  // seen from B's current frame ...
    project(ob.p_ref, ob.uv_ref_left, ob.u_ref_right);  // ... at the reference pixels
    obs.push_back(ob);
  }
  RefineOptions opt;
  opt.huber_px = 100;  // quadratic: the two halves must balance, not be down-weighted
  opt.outlier_px = 100;
  const PoseRefinement sym = RefineStereoPose(obs, cam, Eigen::Isometry3d::Identity(), opt);
  ASSERT_TRUE(sym.ok);
  const double yaw_sym = LogSE3(T_a.inverse() * sym.T_ref_curr)(4);
  EXPECT_GT(yaw_sym, 0.25 * kGapRad);
  EXPECT_LT(yaw_sym, 0.75 * kGapRad);
  opt.reverse = false;
  const PoseRefinement fwd = RefineStereoPose(obs, cam, Eigen::Isometry3d::Identity(), opt);
  ASSERT_TRUE(fwd.ok);
  const Eigen::Isometry3d err = T_a.inverse() * fwd.T_ref_curr;
  EXPECT_LT(err.translation().norm(), 1e-6);
  EXPECT_LT(Eigen::AngleAxisd(err.rotation()).angle(), 1e-8);
}

TEST(StereoGeometry, RefineFailsCleanlyWithoutObservations) {
  const PoseRefinement r = RefineStereoPose({}, testing::SyntheticCamera(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.covariance.allFinite());
}

}  // namespace
}  // namespace locaid::vo
