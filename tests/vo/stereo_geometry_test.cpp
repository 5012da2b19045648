// Free functions of vo/stereo_geometry.hpp.
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
  const kitti::StereoCamera cam = testing::SyntheticCamera();
  const Eigen::Vector3d p(1.5, -0.4, 12.0);
  const double u = cam.fx * p.x() / p.z() + cam.cx, v = cam.fy * p.y() / p.z() + cam.cy;
  const double ur = cam.fx * (p.x() - cam.baseline_m) / p.z() + cam.cx;
  EXPECT_TRUE(TriangulateStereo(cam, u, v, ur).isApprox(p, kTightTol));
}

TEST(StereoGeometry, RefineRecoversPoseWithNoiseAndOutliers) {
  const kitti::StereoCamera cam = testing::SyntheticCamera();
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

TEST(StereoGeometry, RefineFailsCleanlyWithoutObservations) {
  const PoseRefinement r = RefineStereoPose({}, testing::SyntheticCamera(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.covariance.allFinite());
}

}  // namespace
}  // namespace locaid::vo
