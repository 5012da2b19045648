// Transforms between frames of tf2_msgs/TFMessage transforms (the tree tf2
// builds; a bag's /tf_static): the chain of parent -> child edges from one
// frame to another, walked in either direction.
#pragma once

#include "ros/messages.hpp"

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace locaid::ros {

// T_a_b (a point in frame b, expressed in frame a), or nothing when the
// transforms do not connect the two frames. The same frame: the identity.
std::optional<Eigen::Isometry3d> FindTransform(const std::vector<TransformStamped>& transforms,
                                               const std::string& a, const std::string& b);

}  // namespace locaid::ros
