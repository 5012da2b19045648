// Sliding-window bundle adjustment for the default VO method: the poses of the
// last few keyframes and the points they observe are refined together on the
// stereo reprojection error (left u, v and right u of every observation),
// Huber-weighted, by Levenberg-Marquardt with the points eliminated through the
// Schur complement. Free function with explicit inputs, so tests can drive it.
#pragma once

#include "core/stereo_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace locaid::vo {

// One image observation of point `point` in window frame `frame`.
struct WindowObservation {
  int frame = 0;
  int point = 0;
  Eigen::Vector2d uv_left = Eigen::Vector2d::Zero();
  double u_right = 0;   // used when has_right (rectified: same row as uv_left)
  bool has_right = false;
};

struct WindowProblem {
  // Pose of each window frame: T_w_c maps the frame's cam0 coordinates into
  // the window's world frame. Frames [0, fixed_frames) are held (the gauge).
  std::vector<Eigen::Isometry3d> T_w_c;
  std::vector<Eigen::Vector3d> p_w;            // points in the world frame
  std::vector<WindowObservation> observations;
  int fixed_frames = 1;
};

struct WindowOptions {
  int iterations = 4;          // Levenberg-Marquardt steps (accepted or not)
  double huber_px = 1.0;       // Huber threshold on an observation's residual norm
  double outlier_px = 3.0;     // residual norm beyond this after solving: outlier
  double min_depth_m = 0.1;    // an observation with the point closer than this: outlier
};

struct WindowResult {
  int points_used = 0;         // points with observations in >= 2 frames
  int observations_used = 0;
  double initial_cost = 0;     // sum of Huber costs (px^2) over the used observations
  double final_cost = 0;
  int iterations = 0;
  std::vector<char> outlier;   // per observation (also set for unused ones when bad)
  bool ok = false;             // solved, finite, cost did not rise
};

// Refines problem.T_w_c (frames >= fixed_frames) and problem.p_w in place. Points
// seen in a single frame are left unchanged (they carry no pose information).
// On failure (non-finite, singular) the inputs are left unchanged and ok = false.
WindowResult SolveWindow(WindowProblem& problem, const StereoCamera& camera,
                         const WindowOptions& options = {});

}  // namespace locaid::vo
