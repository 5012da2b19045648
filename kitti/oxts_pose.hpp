// OXTS -> poses: ENU pose of the IMU from one record, pose interpolation, and
// cam0 ground truth at image times (what raw drives expose as ground_truth()).
#pragma once

#include "core/timed_pose.hpp"
#include "kitti/types.hpp"

#include <GeographicLib/LocalCartesian.hpp>

#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace locaid::kitti {

// R_enu_imu = Rz(yaw) * Ry(pitch) * Rx(roll), the OXTS / KITTI devkit convention
// (yaw 0 = east, counter-clockwise positive).
Eigen::Matrix3d OxtsAttitude(double roll_rad, double pitch_rad, double yaw_rad);

// T_enu_imu of one record: position through `enu` (GeographicLib LocalCartesian,
// metres east/north/up), attitude OxtsAttitude(roll, pitch, yaw).
Eigen::Isometry3d OxtsToEnuPose(const OxtsRecord& r, const GeographicLib::LocalCartesian& enu);

// Linear in translation, slerp in rotation; alpha 0 -> T_a, 1 -> T_b.
Eigen::Isometry3d InterpolatePose(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                                  double alpha);

// Pose at t_ns from time-sorted `poses` (any frames; uses TimedPose::T_world_cam
// as "the pose"). Exact sample time -> that pose. std::nullopt when t_ns is
// outside [first, last] or the two bracketing samples are more than
// max_gap_ns apart.
std::optional<Eigen::Isometry3d> InterpolatePose(const std::vector<TimedPose>& poses,
                                                 int64_t t_ns, int64_t max_gap_ns);

// Ground truth of cam0 at image times from OXTS.
struct OxtsGroundTruth {
  // ENU origin: the first (earliest) OXTS record.
  double origin_lat_deg = 0, origin_lon_deg = 0, origin_alt_m = 0;
  // T_enu_imu at each OXTS sample (TimedPose::T_world_cam holds T_enu_imu).
  std::vector<TimedPose> enu_imu;
  // World = cam0 at `anchor_frame`, the first frame whose time has an OXTS pose
  // (frame 0 whenever the OXTS span covers it); -1 if no frame has one.
  int anchor_frame = -1;
  Eigen::Isometry3d T_enu_world = Eigen::Isometry3d::Identity();
  // Per frame: T_world_cam0, std::nullopt outside the OXTS span / over a gap.
  std::vector<std::optional<Eigen::Isometry3d>> T_world_cam;
};

// T_enu_cam(t) = interp(T_enu_imu)(t) * inverse(T_cam0_imu);
// T_world_cam(t) = inverse(T_enu_cam(t_anchor)) * T_enu_cam(t).
// `oxts` must be sorted by time (throws kitti::Error otherwise).
OxtsGroundTruth ComputeOxtsGroundTruth(const std::vector<OxtsSample>& oxts,
                                       const std::vector<int64_t>& frame_t_ns,
                                       const Eigen::Isometry3d& T_cam0_imu,
                                       double max_gap_s = 0.5);

// The same records with lat/lon/alt replaced by the first record's position
// plus the time integral (trapezoid) of the OXTS velocity (ve, vn, vu), taken
// in the first record's local east-north-up frame; attitude, velocity and the
// other fields unchanged. A truth whose position is as smooth as the
// unit's velocity: on drives where the receiver is not in RTK-fixed mode the
// position solution can step by decimetres that no velocity explains (see
// docs/benchmarks.md). Drift grows with time, so it is meant for segments of
// tens of seconds. `oxts` must be sorted by time (throws kitti::Error).
std::vector<OxtsSample> IntegrateOxtsVelocity(const std::vector<OxtsSample>& oxts);

}  // namespace locaid::kitti
