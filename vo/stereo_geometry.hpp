// Stereo geometry and pose refinement used by both VO methods: free functions
// with explicit inputs, so tests can drive them directly.
//
// Pose perturbation convention (the one RelativeMotion::covariance uses):
// delta = [rho (m), phi (rad)], T * Exp(delta) with Exp(delta) = (R = AngleAxis(phi),
// t = rho). To first order this is the usual SE(3) right perturbation.
#pragma once

#include "core/stereo_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace locaid::vo {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

Eigen::Isometry3d ExpSE3(const Vector6d& delta);
// Inverse of ExpSE3: [t, angle-axis(R)].
Vector6d LogSE3(const Eigen::Isometry3d& T);
// Motion T scaled by s along its geodesic (constant-velocity prediction over
// an interval s times the last one).
Eigen::Isometry3d ScaleMotion(const Eigen::Isometry3d& T, double s);
bool IsFinite(const Eigen::Isometry3d& T);
// Covariance reported with a LOST / failed motion: 1 m^2 and 1 rad^2 per axis.
Matrix6d LargeCovariance();

// Point in the left (cam0) frame from a rectified stereo observation; the
// disparity u_left - u_right must be > 0.
Eigen::Vector3d TriangulateStereo(const StereoCamera& camera, double u_left, double v_left,
                                  double u_right);

// Stereo reprojection rows of a point q (camera frame) observed at uv_left
// and, when has_right, at u_right in the right image: r = predicted - measured
// (u, v, u_right) and dproj = d r / d q. All three rows are filled; the
// return value is how many count (2 without has_right), 0 when q is not
// deeper than min_depth_m.
int ProjectRows(const StereoCamera& cam, const Eigen::Vector3d& q,
                const Eigen::Vector2d& uv_left, double u_right, bool has_right,
                double min_depth_m, Eigen::Ref<Eigen::Vector3d> r, Eigen::Matrix3d& dproj);

// One correspondence: a point known in the reference frame (from stereo there)
// observed in the current left image and, when has_right, in the current right
// image (only u_right is used: rectified rows coincide).
struct StereoObservation {
  Eigen::Vector3d p_ref = Eigen::Vector3d::Zero();
  Eigen::Vector2d uv_left = Eigen::Vector2d::Zero();
  double u_right = 0;
  bool has_right = false;
  // Optional reverse (symmetric) term: the point triangulated by stereo in the
  // current frame (p_curr, cam0 curr) observed in the reference left image at
  // uv_ref_left and right image at u_ref_right.
  bool has_reverse = false;
  Eigen::Vector3d p_curr = Eigen::Vector3d::Zero();
  Eigen::Vector2d uv_ref_left = Eigen::Vector2d::Zero();
  double u_ref_right = 0;
};

struct RefineOptions {
  int rounds = 2;              // re-select inliers between rounds
  int iterations = 6;          // Gauss-Newton iterations per round
  double huber_px = 1.0;       // Huber threshold on each pixel residual
  double outlier_px = 3.0;     // |residual| (max over the point's rows) beyond this: outlier
  double min_sigma_px = 0.1;   // floor of the residual standard deviation in the covariance
  double min_depth_m = 0.1;    // points closer than this in curr are dropped
  bool reverse = true;         // use the reverse rows of observations that have them
};

struct PoseRefinement {
  Eigen::Isometry3d T_ref_curr = Eigen::Isometry3d::Identity();
  // Covariance of delta in T_ref_curr * Exp(delta): sigma^2 (J^T W J)^-1 from the
  // last Gauss-Newton normal equations, sigma^2 = sum(w r^2) / (m - 6) over the
  // m residual rows of the inliers (Huber weights w), floored at min_sigma_px^2.
  Matrix6d covariance = LargeCovariance();
  std::vector<char> inlier;    // per observation
  int inliers = 0;
  double sigma_px = 0;
  bool ok = false;             // enough inliers, finite, well-conditioned
};

// Minimises the reprojection error of p_ref into the current left and right
// images over T_ref_curr (Huber-weighted Gauss-Newton), starting at T_ref_curr_init.
PoseRefinement RefineStereoPose(const std::vector<StereoObservation>& observations,
                                const StereoCamera& camera,
                                const Eigen::Isometry3d& T_ref_curr_init,
                                const RefineOptions& options = {});

// Covariance of T_ref_curr (same convention) from the given observations at a
// fixed pose (no iteration); used by the baseline.
Matrix6d PoseCovariance(const std::vector<StereoObservation>& observations,
                        const StereoCamera& camera, const Eigen::Isometry3d& T_ref_curr,
                        const RefineOptions& options = {});

}  // namespace locaid::vo
