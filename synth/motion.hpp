// Synthetic route and vehicle motion: a smooth road centerline in a local ENU
// frame (east, north, up; origin = route start), an elevation profile, a
// speed profile between v_min and v_max, and the resulting continuous pose of
// the IMU (x forward, y left, z up) with the dynamics a real car shows: pitch
// on braking/acceleration, roll in turns, suspension vibration.
//
// "Tube" coordinates (s, d, h) place the world along the route: arc length s
// along the centerline (m), lateral offset d (m, left positive), height h above
// the road surface (m).
//
// Route mode (synth/route_file.hpp): a Route built from a measured track
// instead, and a VehicleMotion whose s(t) is the measured progress along it.
// There s is the arc length along the track (the middle of the right-hand
// lane, the road's centre line lies center_shift_m to its left) and the
// vehicle drives the track exactly.
#pragma once

#include "kitti/types.hpp"
#include "synth/track.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <vector>

namespace locaid::synth {

struct RouteConfig {
  double length_m = 1500;          // centerline length
  uint64_t seed = 1;
  double min_radius_m = 35;        // sharpest curve
  double max_radius_m = 220;
  double max_heading_dev_deg = 55;  // heading stays within +-this of the start heading
  double v_min_mps = 5, v_max_mps = 20;
  double lat_accel_max_mps2 = 2.0;  // speed limit in curves
  double accel_max_mps2 = 1.2, brake_max_mps2 = 1.8;
};

class Route {
 public:
  explicit Route(const RouteConfig& config);
  // Route mode: the track's [s_begin, s_end] (Speed/SpeedSlope are 0: the
  // vehicle's progress is measured, not planned).
  explicit Route(const TrackGeometry& track);

  bool follows_track() const { return track_.has_value(); }
  double center_shift_m() const { return track_ ? track_->center_shift_m : 0.0; }
  double length_m() const { return length_m_; }
  double Kappa(double s) const;                 // curvature, 1/m, left positive
  double Heading(double s) const;               // yaw of the centerline tangent (0 = east, CCW)
  Eigen::Vector2d Center(double s) const;       // ENU east/north of the centerline
  double Elevation(double s) const;             // road surface height, m
  double Grade(double s) const;                 // dElevation/ds
  double Speed(double s) const;                 // planned speed at s, m/s
  double SpeedSlope(double s) const;            // dSpeed/ds, 1/s
  // World point of tube coordinates (s, d, h).
  Eigen::Vector3d Point(double s, double d, double h) const;

 private:
  struct Piece {
    double s0 = 0, ramp_m = 0, arc_m = 0, kappa = 0;  // kappa 0: straight
    double heading0 = 0;
    double length() const { return 2 * ramp_m + arc_m; }
  };
  const Piece& PieceAt(double s) const;
  // Track position, tangent and its derivative (per m of s) at route s.
  void TrackAt(double s, Eigen::Vector2d* p, Eigen::Vector2d* d1, Eigen::Vector2d* d2) const;

  std::optional<TrackGeometry> track_;
  double length_m_ = 0;
  std::vector<Piece> pieces_;
  double knot_step_m_ = 1.0;
  std::vector<Eigen::Vector2d> knots_;  // Center at s = i * knot_step_m_
  struct Wave { double amp_m, omega, phase; };
  std::vector<Wave> hills_;
  double speed_step_m_ = 1.0;
  std::vector<double> speed_;  // planned speed at s = i * speed_step_m_
};

struct MotionConfig {
  double imu_height_m = 0.93;         // IMU above the road surface
  double lane_offset_m = -1.75;       // right-hand traffic: right lane
  double pitch_per_accel = 0.0052;    // rad per m/s^2 (braking -> front down)
  double roll_per_lat_accel = 0.0087; // rad per m/s^2 (left turn -> left side up)
  double heave_amp_m = 0.002, pitch_vib_amp_rad = 0.0015, roll_vib_amp_rad = 0.0010;
};

// Vehicle along the route: s(t) from the speed profile, pose of the IMU in ENU.
class VehicleMotion {
 public:
  VehicleMotion(const Route& route, const MotionConfig& config, uint64_t seed,
                double duration_s);
  // Route mode: s(t), ds/dt and d2s/dt2 at t = k * dt_s (k = 0 .. n-1) on a
  // Route that follows a track. The vehicle keeps to the track (no lane
  // wander) and its body vibrations fade out as it comes to a stop.
  VehicleMotion(const Route& route, const MotionConfig& config, uint64_t seed, double dt_s,
                std::vector<double> s, std::vector<double> v, std::vector<double> a);

  double duration_s() const { return duration_s_; }
  double S(double t) const;        // arc length at time t
  double SpeedAt(double t) const;  // ds/dt
  double AccelAt(double t) const;  // d2s/dt2
  // Time at which s first reaches `s` (for --length-m), or -1 if never in the duration.
  double TimeAtS(double s) const;
  Eigen::Isometry3d T_enu_imu(double t) const;

 private:
  const Route& route_;
  MotionConfig cfg_;
  double duration_s_;
  double dt_ = 0.01;
  std::vector<double> s_, v_, a_;  // knots at t = k * dt_
  struct Osc { double amp, omega, phase; };
  std::vector<Osc> heave_, pitch_vib_, roll_vib_;
  double wander_phase_[2] = {0, 0};
  void InitDynamics(uint64_t seed);
  double LaneOffset(double s) const;
  double LaneOffsetSlope(double s) const;
};

// Kinematics an OXTS unit reports at time t, from the continuous motion.
struct ImuKinematics {
  Eigen::Isometry3d T_enu_imu;
  Eigen::Vector3d v_enu_mps;          // velocity in ENU
  Eigen::Vector3d f_imu_mps2;         // specific force in body axes (incl. gravity: +g up at rest)
  Eigen::Vector3d w_imu_radps;        // angular rate in body axes
};
ImuKinematics KinematicsAt(const VehicleMotion& motion, double t, double gravity_mps2 = 9.81);

// roll, pitch, yaw with R = Rz(yaw) Ry(pitch) Rx(roll) (OXTS convention).
Eigen::Vector3d RollPitchYaw(const Eigen::Matrix3d& R_enu_imu);
Eigen::Matrix3d AttitudeFromRpy(double roll, double pitch, double yaw);

}  // namespace locaid::synth
