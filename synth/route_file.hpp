// Route mode of the synthetic drive: a real drive's KITTI odometry ground
// truth (poses/NN.txt, and sequences/NN/times.txt) as the route to render.
//
// The poses (T_world_cam0, world = cam0 at frame 0: x right, y down, z
// forward) become a local ENU frame: east = cam0's forward at frame 0, north
// = its left, up = -y, origin = frame 0's camera. The ground-truth poses are
// noisy at the centimetre level, too much to differentiate twice, so
// RouteFit turns them into one smooth trajectory:
//   - the track: east/north of the vehicle along the arc length s (cubic
//     P-spline over s, so a stop, many poses at one place, is one place),
//     refitted on the exact arc length; the road surface 1.65 m (KITTI's
//     camera height) below the camera, smoothed over a longer distance;
//     a straight lead-in before the first pose and lead-out after the last;
//   - the progress s(t): a monotone cubic P-spline over the poses' times of
//     each pose's place on the track, so the vehicle never backs up and
//     holds still (s constant) through a stop while time passes.
// The vehicle (VehicleMotion on a Route built from the track) drives exactly
// this trajectory: it is the drive's ground truth, and the OXTS velocities,
// accelerations and angular rates are its derivatives.
#pragma once

#include "synth/spline.hpp"
#include "synth/track.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <vector>

namespace locaid::synth {

struct RoutePoses {
  std::vector<double> t_s;                   // times.txt, or 0.1 s a pose (10 Hz)
  std::vector<Eigen::Vector3d> camera_enu;   // cam0 position in the local ENU frame
};

// ENU <- KITTI odometry world (a rotation; the origin stays frame 0's camera).
Eigen::Matrix3d EnuFromKittiWorld();

// Reads and checks a poses file and (non-empty `times_path`) its times.txt.
// Throws kitti::Error naming the file and the reason, e.g. "synth: route
// poses: P:17: 11 numbers, expected 12 (KITTI 3x4 row-major)", "synth: route:
// P has 4541 poses but T has 4540 times", "synth: route times: T:5: time
// 0.4 s is not after the previous one (0.4 s)", "... fewer than 2 poses".
RoutePoses ReadRoutePoses(const std::filesystem::path& poses_path, const std::filesystem::path& times_path);

struct RouteFitConfig {
  double camera_height_m = 1.65;    // KITTI cam0 above the road
  // Smoothing lengths, chosen on KITTI 00 (ground truth noise ~5 mm): the
  // fit stays within 1.5 cm of 90% of the poses (5 cm of 99%; more only at
  // the ground truth's own jumps), while the IMU's derivatives stay smooth.
  double knot_m = 1.0;              // track spline knots
  double track_smoothing_m = 1.25;  // smoothing length of the track (east/north) ...
  double track_smoothing_speed_mps = 10;  // ... up to this speed, growing as speed^0.8 above
  double height_smoothing_m = 4.0;  // of the road height
  double knot_s = 0.1;              // progress spline knots
  double time_smoothing_s = 0.2;    // smoothing length of the progress
  double lead_in_m = 120, lead_out_m = 320;  // straight road before the first / after the last pose
  double time_margin_s = 2.0;       // progress defined this long before the first / after the last pose
};

class RouteFit {
 public:
  // Throws kitti::Error when the poses do not move 5 m horizontally.
  explicit RouteFit(const RoutePoses& poses, const RouteFitConfig& config = {});

  // The whole track: s from track().s_begin (the lead-in's start, < 0) to
  // track().s_end (the lead-out's end); s = 0 is the first pose.
  const TrackGeometry& track() const { return track_; }
  // Arc length along the track at time t of the poses' clock (s), its speed
  // and acceleration: exact derivatives of one C2 function, non-decreasing.
  void Progress(double t, double* s, double* v, double* a) const;
  double S(double t) const;
  // First time >= t_from at which the progress reaches s, or -1 if it does
  // not before the last pose.
  double TimeAtS(double s, double t_from) const;
  double t_first() const { return t_.front(); }
  double t_last() const { return t_.back(); }
  // Each pose's place on the track (projection of its position).
  const std::vector<double>& pose_s() const { return pose_s_; }

 private:
  std::vector<double> t_, pose_s_;
  TrackGeometry track_;
  UniformCubicSpline progress_;
};

}  // namespace locaid::synth
