// How a stereo car's ROS 2 messages map onto locaid's sensors, for a
// recorded bag and live topics alike: the camera-IMU extrinsic and the GPS
// antenna's lever arm from /tf_static (REP-103 frames), and what a
// NavSatFix states.
#pragma once

#include "ros/messages.hpp"

#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace locaid::ros {

// T_cam0_imu: the IMU (body) frame in the rectified left camera, from the
// /tf_static chain between `imu_frame` and the left camera_info's frame (the
// camera's optical frame), followed by the camera_info's R. Nothing when the
// transforms do not connect the two frames.
std::optional<Eigen::Isometry3d> CameraImuExtrinsic(const CameraInfo& left,
                                                    const std::vector<TransformStamped>& static_transforms,
                                                    const std::string& imu_frame);
// The body (x forward, y left, z up) when there is no IMU to define it: the
// rectified left camera (x right, y down, z forward) turned x forward.
Eigen::Isometry3d CameraBodyWithoutImu();
// The GPS antenna (`gps_frame`, a NavSatFix's frame_id) in the body frame
// given by T_cam0_imu; nothing when /tf_static does not reach that frame.
std::optional<Eigen::Vector3d> GpsLeverArm(const CameraInfo& left,
                                           const std::vector<TransformStamped>& static_transforms,
                                           const Eigen::Isometry3d& T_cam0_imu, const std::string& gps_frame);

// A NavSatFix is a fix: status above NO_FIX and a finite position in range.
bool HasPosition(const NavSatFix& fix);
// Its position covariance (ENU, m^2) when it states one: a covariance type
// other than UNKNOWN, every value finite and a positive diagonal;
// DIAGONAL_KNOWN keeps the diagonal only. Symmetrised.
std::optional<Eigen::Matrix3d> StatedCovariance(const NavSatFix& fix);

}  // namespace locaid::ros
