// The LiveSource of a client that pushes rectified stereo frames (locaid-push,
// locaid-ros2 --inputs): the camera model and T_cam0_imu as the server reads
// them back (server/live_source_request.cpp: fx .. height, the rig as a
// row-major 3x4).
#pragma once

#include "core/stereo_camera.hpp"
#include "locaid/v1/localization.pb.h"

#include <Eigen/Geometry>

namespace locaid::output {

v1::LiveSource LiveSourceOf(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu);

}  // namespace locaid::output
