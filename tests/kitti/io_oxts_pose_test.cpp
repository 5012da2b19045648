#include "core/timed_pose.hpp"
#include "kitti/oxts_pose.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace locaid::kitti {
namespace {

constexpr double kTol = 1e-9;

TEST(IoOxtsPose, AttitudeFollowsOxtsConvention) {
  // yaw 90 deg: IMU x (forward) points north.
  EXPECT_LT((OxtsAttitude(0, 0, M_PI / 2) * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY())
                .norm(),
            kTol);
  // pitch > 0 = front down (dataformat.txt).
  EXPECT_LT((OxtsAttitude(0, 0.1, 0) * Eigen::Vector3d::UnitX()).z(), 0.0);
  // roll > 0 = left side up.
  EXPECT_GT((OxtsAttitude(0.1, 0, 0) * Eigen::Vector3d::UnitY()).z(), 0.0);
  // Composition order Rz * Ry * Rx.
  const Eigen::Matrix3d R = OxtsAttitude(0.1, -0.2, 0.3);
  const Eigen::Matrix3d want = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).matrix() *
                               Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()).matrix() *
                               Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).matrix();
  EXPECT_LT((R - want).norm(), kTol);
}

// A record 12.5 m east, 3 m south and 1.5 m above the origin, placed by hand
// with the WGS84 radii of curvature at the origin (latitude 49 deg, 100 m up;
// independent of GeographicLib and of the code under test). That placement is
// first order in the offset: at 13 m the tangent plane differs by ~2e-5 m
// (curvature), below kFirstOrderTolM, while a sphere instead of the ellipsoid
// (0.3 % in the north scale here), the origin's height left out (2e-4 m) or
// swapped axes are off by more.
TEST(IoOxtsPose, EnuPoseFromLatLon) {
  constexpr double kLat0Deg = 49.0, kLon0Deg = 8.4, kAlt0M = 100.0;
  constexpr double kEastM = 12.5, kNorthM = -3.0, kUpM = 1.5;
  constexpr double kFirstOrderTolM = 1e-4;
  constexpr double kA = 6378137.0, kF = 1 / 298.257223563, kE2 = kF * (2 - kF);  // WGS84
  const double phi = kLat0Deg * M_PI / 180;
  const double w = 1 - kE2 * std::sin(phi) * std::sin(phi);
  const double meridian_m = kA * (1 - kE2) / std::pow(w, 1.5);  // north-south radius of curvature
  const double prime_vertical_m = kA / std::sqrt(w);            // east-west, before cos(latitude)
  OxtsRecord r;
  r.lat_deg = kLat0Deg + kNorthM / (meridian_m + kAlt0M) * 180 / M_PI;
  r.lon_deg = kLon0Deg + kEastM / ((prime_vertical_m + kAlt0M) * std::cos(phi)) * 180 / M_PI;
  r.alt_m = kAlt0M + kUpM;
  r.yaw_rad = 0.7;
  const GeographicLib::LocalCartesian enu(kLat0Deg, kLon0Deg, kAlt0M);
  const Eigen::Isometry3d T = OxtsToEnuPose(r, enu);
  EXPECT_LT((T.translation() - Eigen::Vector3d(kEastM, kNorthM, kUpM)).norm(), kFirstOrderTolM)
      << T.translation().transpose();
  // Yaw 0.7 rad, no roll or pitch: a rotation about up, written out.
  Eigen::Matrix3d want;
  want << std::cos(0.7), -std::sin(0.7), 0,  //
      std::sin(0.7), std::cos(0.7), 0,       //
      0, 0, 1;
  EXPECT_LT((T.linear() - want).norm(), kTol);
}

TEST(IoOxtsPose, InterpolatesLinearlyAndBySlerp) {
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = Eigen::Isometry3d::Identity();
  b.translation() << 2, 4, -6;
  b.linear() = Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Isometry3d m = InterpolatePose(a, b, 0.25);
  EXPECT_LT((m.translation() - Eigen::Vector3d(0.5, 1, -1.5)).norm(), kTol);
  EXPECT_NEAR(Eigen::AngleAxisd(m.linear()).angle(), 0.2, kTol);

  const std::vector<TimedPose> poses = {{1000, a}, {2000, b}, {9000, a}};
  const auto at = InterpolatePose(poses, 1250, 5000);
  ASSERT_TRUE(at.has_value());
  EXPECT_LT((at->matrix() - m.matrix()).norm(), kTol);
  EXPECT_EQ(InterpolatePose(poses, 2000, 1)->matrix(), b.matrix());  // exact sample
  EXPECT_FALSE(InterpolatePose(poses, 999, 5000).has_value());       // before
  EXPECT_FALSE(InterpolatePose(poses, 9001, 5000).has_value());      // after
  EXPECT_FALSE(InterpolatePose(poses, 3000, 5000).has_value());      // 7000 ns gap
  EXPECT_TRUE(InterpolatePose(poses, 3000, 7000).has_value());
  EXPECT_FALSE(InterpolatePose({}, 0, 1).has_value());
}

TEST(IoOxtsPose, GroundTruthAnchorsAtFirstCoveredFrame) {
  // IMU drives north (yaw 90 deg) at 5 m/s; camera looks along IMU x.
  const GeographicLib::LocalCartesian enu(49.0, 8.4, 100.0);
  std::vector<OxtsSample> oxts;
  for (int k = 0; k < 11; ++k) {
    OxtsSample s;
    s.t_ns = 1'000'000'000LL + k * 100'000'000LL;
    s.index = k;
    enu.Reverse(0, 5.0 * 0.1 * k, 0, s.record.lat_deg, s.record.lon_deg, s.record.alt_m);
    s.record.yaw_rad = M_PI / 2;
    oxts.push_back(s);
  }
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  T_cam0_imu.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  T_cam0_imu.translation() << 0.1, 0.2, 0.3;
  // Frames at 0.95 s (before OXTS), 1.05, 1.55, 2.0, 2.05 s (after).
  const std::vector<int64_t> frames = {950'000'000, 1'050'000'000, 1'550'000'000,
                                       2'000'000'000, 2'050'000'000};
  const OxtsGroundTruth gt = ComputeOxtsGroundTruth(oxts, frames, T_cam0_imu);
  EXPECT_EQ(gt.anchor_frame, 1);
  EXPECT_DOUBLE_EQ(gt.origin_lat_deg, oxts.front().record.lat_deg);
  ASSERT_EQ(gt.T_world_cam.size(), frames.size());
  EXPECT_FALSE(gt.T_world_cam[0]);
  EXPECT_FALSE(gt.T_world_cam[4]);
  ASSERT_TRUE(gt.T_world_cam[1] && gt.T_world_cam[2] && gt.T_world_cam[3]);
  EXPECT_LT((gt.T_world_cam[1]->matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-6);
  // 0.5 s later the camera is 2.5 m further along its own z axis.
  EXPECT_LT((gt.T_world_cam[2]->translation() - Eigen::Vector3d(0, 0, 2.5)).norm(), 1e-6);
  EXPECT_LT((gt.T_world_cam[3]->translation() - Eigen::Vector3d(0, 0, 4.75)).norm(), 1e-6);
  // T_enu_world maps the anchor camera into ENU: its optical axis points north.
  EXPECT_LT((gt.T_enu_world.linear() * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitY()).norm(),
            1e-9);
  // Unsorted input is refused.
  std::swap(oxts[2], oxts[3]);
  EXPECT_THROW(ComputeOxtsGroundTruth(oxts, frames, T_cam0_imu), Error);
}

// Records 0.1 s apart at a known ENU track: east at 8 m/s, climbing at 0.5 m/s
// and accelerating north at 1 m/s^2 (velocity exact, so the trapezoid is exact).
std::vector<OxtsSample> TrackWithVelocity(const GeographicLib::LocalCartesian& enu, int n) {
  std::vector<OxtsSample> oxts;
  for (int k = 0; k < n; ++k) {
    const double t = 0.1 * k;
    OxtsSample s;
    s.t_ns = 1'000'000'000 + 100'000'000LL * k;
    s.index = k;
    enu.Reverse(8.0 * t, 0.5 * t * t, 0.5 * t, s.record.lat_deg, s.record.lon_deg, s.record.alt_m);
    s.record.ve_mps = 8.0;
    s.record.vn_mps = t;
    s.record.vu_mps = 0.5;
    s.record.yaw_rad = 0.25 * k;
    oxts.push_back(s);
  }
  return oxts;
}

TEST(IoOxtsPose, VelocityIntegralFollowsTheVelocityNotThePositionSteps) {
  const GeographicLib::LocalCartesian enu(49.0, 8.4, 100.0);
  constexpr double kPosTolM = 1e-4;  // LocalCartesian round trips and the sum of 50 steps
  std::vector<OxtsSample> oxts = TrackWithVelocity(enu, 51);
  // Consistent position and velocity: the positions come back.
  std::vector<OxtsSample> out = IntegrateOxtsVelocity(oxts);
  ASSERT_EQ(out.size(), oxts.size());
  for (size_t k = 0; k < oxts.size(); ++k) {
    const Eigen::Vector3d want = OxtsToEnuPose(oxts[k].record, enu).translation();
    EXPECT_LT((OxtsToEnuPose(out[k].record, enu).translation() - want).norm(), kPosTolM) << "record " << k;
    EXPECT_EQ(out[k].record.yaw_rad, oxts[k].record.yaw_rad);  // attitude untouched
    EXPECT_EQ(out[k].t_ns, oxts[k].t_ns);
  }
  // A 0.7 m altitude step in records 20..29 (what the real excerpt's position
  // solution shows): the integral does not see it.
  for (int k = 20; k < 30; ++k) oxts[k].record.alt_m += 0.7;
  out = IntegrateOxtsVelocity(oxts);
  const double up_25_m = OxtsToEnuPose(out[25].record, enu).translation().z();
  EXPECT_NEAR(up_25_m, 0.5 * 2.5, kPosTolM);
  // Unsorted input is refused.
  std::swap(oxts[2], oxts[3]);
  EXPECT_THROW(IntegrateOxtsVelocity(oxts), Error);
  EXPECT_TRUE(IntegrateOxtsVelocity({}).empty());
}

}  // namespace
}  // namespace locaid::kitti
