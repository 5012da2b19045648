// Transforms between frames of a bag's /tf_static (the tree tf2 builds):
// the chain of parent -> child edges from one frame to another, walked in
// either direction.
#pragma once

#include "bag/ros_messages.hpp"

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace locaid::bag {

// T_a_b (a point in frame b, expressed in frame a), or nothing when the
// transforms do not connect the two frames. The same frame: the identity.
std::optional<Eigen::Isometry3d> FindTransform(const std::vector<ros::TransformStamped>& transforms,
                                               const std::string& a, const std::string& b);

}  // namespace locaid::bag
