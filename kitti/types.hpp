// KITTI dataset types: the reader error and the OXTS record. Types that are
// not KITTI's (StereoCamera, TimedPose) and the naming scheme: core/.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

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

}  // namespace locaid::kitti
