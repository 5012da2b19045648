// A pose with its time, as ground truth and trajectories carry it.
// Names: core/README.md.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>

namespace locaid {

struct TimedPose {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

}  // namespace locaid
