// Core data types shared by every locaid module.
//
// Naming scheme (used everywhere in locaid):
//   T_a_b   rigid transform that maps points expressed in frame b into frame a
//           (p_a = T_a_b * p_b); Eigen::Isometry3d.
//   p_a_x   position of x expressed in frame a.   t_ns  int64 nanoseconds.
// Frames:
//   cam0    left rectified camera: x right, y down, z forward.
//   imu     OXTS/vehicle body: x forward, y left, z up.
//   enu     local East-North-Up, origin at the first GPS fix.
//   world   the frame of a pose file (KITTI: cam0 at frame 0).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace locaid::kitti {

// Thrown by every kitti/ reader and parser. what() names the file, the line
// (when there is one) and the reason, e.g.
//   "oxts/data/0000000017.txt:1: 29 fields, expected 30".
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One OXTS RT3003 record: the 30 fields of oxts/dataformat.txt, in order.
struct OxtsRecord {
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  double roll_rad = 0, pitch_rad = 0, yaw_rad = 0;  // yaw 0 = east, CCW positive
  double vn_mps = 0, ve_mps = 0, vf_mps = 0, vl_mps = 0, vu_mps = 0;
  // Specific force (includes gravity: ~+9.81 on z at rest), body x/y/z and f/l/u.
  double ax_mps2 = 0, ay_mps2 = 0, az_mps2 = 0, af_mps2 = 0, al_mps2 = 0, au_mps2 = 0;
  double wx_radps = 0, wy_radps = 0, wz_radps = 0, wf_radps = 0, wl_radps = 0, wu_radps = 0;
  double pos_accuracy_m = 0, vel_accuracy_mps = 0;
  int navstat = 0, numsats = 0, posmode = 0, velmode = 0, orimode = 0;
};

// An OXTS record with its time (nanoseconds, same clock as the images).
struct OxtsSample {
  int64_t t_ns = 0;
  int index = 0;  // file index in oxts/data (0000000017.txt -> 17)
  OxtsRecord record;
};

// Rectified stereo pinhole pair: both cameras share fx, fy, cx, cy; the right
// camera sits baseline_m along +x of the left one.
struct StereoCamera {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double baseline_m = 0;
  int width = 0, height = 0;
};

struct TimedPose {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

}  // namespace locaid::kitti
