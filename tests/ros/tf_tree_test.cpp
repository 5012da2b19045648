// Transforms between tf frames: chains in either direction, the same frame,
// frames the transforms do not connect.
#include "ros/tf_tree.hpp"

#include <gtest/gtest.h>

namespace locaid::ros {
namespace {

TEST(TfTree, ChainsInEitherDirection) {
  TransformStamped a, b;
  a.header.frame_id = "base_link";
  a.child_frame_id = "imu";
  a.T_parent_child.translation() = Eigen::Vector3d(1, 0, 0);
  b.header.frame_id = "base_link";
  b.child_frame_id = "cam";
  b.T_parent_child = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(0, 2, 0);
  const auto T_imu_cam = FindTransform({a, b}, "imu", "cam");
  ASSERT_TRUE(T_imu_cam);
  EXPECT_TRUE(T_imu_cam->isApprox(a.T_parent_child.inverse() * b.T_parent_child));
  EXPECT_TRUE(FindTransform({a, b}, "cam", "cam")->isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(FindTransform({a}, "imu", "cam"));
}

}  // namespace
}  // namespace locaid::ros
