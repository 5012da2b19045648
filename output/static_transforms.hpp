// Fixed transforms published on /tf besides the fused pose.
#pragma once

#include <array>

namespace locaid::output {

// Pose of a child frame in its parent frame (what foxglove.FrameTransform
// carries): translation in metres, rotation as a unit quaternion x, y, z, w.
struct StaticTransform {
  std::array<double, 3> translation;
  std::array<double, 4> rotation_xyzw;
};

// base_link (body/IMU) -> cam0 (left rectified camera) of the KITTI
// 2011_09_26 rig: the inverse of T_cam0_imu = R_rect_00 * T_cam0_velo *
// T_velo_imu from that day's calibration files, the same constant the server
// uses for live sessions without a calibration (server/synthetic_drive.cpp).
// It is right for KITTI 2011_09_26 drives and synthetic drives; other rigs
// differ by centimetres to decimetres (the pose itself is unaffected).
const StaticTransform& BaseLinkToCam0();

}  // namespace locaid::output
