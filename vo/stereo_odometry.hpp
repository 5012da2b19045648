// Stereo visual odometry: one rectified stereo pair in, relative motion out.
#pragma once

#include "core/stereo_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace locaid::vo {

enum class Status { kOk, kDegraded, kLost };
const char* ToString(Status status);
// What the cameras gave VO on a frame: tracking (status OK / DEGRADED), too
// dark or noisy to track, frozen (the same content as the previous frame with
// a new time stamp: never taken as standstill), or lost for another reason.
// kNoImages: the cameras delivered no frame at this time (a live camera that
// stopped, failed or stalled): VO did not run.
enum class Health { kTracking, kDark, kFrozen, kLost, kNoImages };
const char* ToString(Health health);  // "tracking", "dark", "frozen", "lost", "no_images"

struct StereoFrame {
  int64_t t_ns = 0;
  cv::Mat left, right;  // rectified CV_8UC1; an empty Mat means "frame missing"
  // The cameras delivered nothing at t_ns (a live camera that is down): the
  // pipeline does not call Track; the frame's health is kNoImages.
  bool no_images = false;
};

// Wall time of each pipeline stage for one frame, in milliseconds, in the
// order the stages ran (e.g. {"detect", 2.1}, {"track", 1.3}, ...).
using StageTimings = std::vector<std::pair<std::string, double>>;

struct RelativeMotion {
  int64_t t_ns = 0;
  // Time of the pose the motion starts from: the last frame this odometry
  // reported a motion for (OK or DEGRADED) or restarted on. After missing or
  // lost frames it is older than the previous frame; equal to t_ns on the
  // first frame and on LOST results (no motion).
  int64_t t_prev_ns = 0;
  // Motion of cam0 between the pose at t_prev_ns and this frame: p_prev = T_prev_curr * p_curr.
  Eigen::Isometry3d T_prev_curr = Eigen::Isometry3d::Identity();
  // Covariance of the minimal perturbation [dt (m), dtheta (rad)] of
  // T_prev_curr, applied on the right (T * Exp(delta)); in cam0 (curr) axes.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Identity();
  int inliers = 0;
  Status status = Status::kLost;
  Health health = Health::kLost;
  StageTimings timings;
  double total_ms = 0;  // sum of timings
};

class StereoOdometry {
 public:
  virtual ~StereoOdometry() = default;
  // Never returns NaN; never throws on black, saturated, repeated or missing
  // frames (they come back DEGRADED or LOST with identity motion and a large
  // covariance). Sets `health`; a frame repeating the previous frame's
  // content (a frozen camera) is LOST with health kFrozen, never a standstill.
  virtual RelativeMotion Track(const StereoFrame& frame) = 0;
  virtual void Reset() = 0;
};

// Clock of StageTimings: wall time (default) or the calling thread's CPU time
// (stable when other processes share the cores; used by benchmarks).
enum class TimingClock { kWall, kThreadCpu };

// Configuration of the "default" method (KLT tracking against a keyframe,
// stereo KLT depth, P3P RANSAC + Huber Gauss-Newton on both images).
struct DefaultConfig {
  // Detection / bucketing (left image split into grid_cols x grid_rows cells).
  int grid_cols = 16, grid_rows = 5;
  int max_features_per_cell = 6;     // tracked features kept per cell (oldest first)
  int fast_threshold = 15;           // FAST intensity threshold (grey levels)
  bool detect_half_resolution = true;   // FAST on pyramid level 1 (4x fewer pixels)
  int min_feature_distance_px = 8;  // no new corner this close to a tracked one
  // KLT.
  int klt_window_px = 11;
  int klt_levels = 3;                // pyramid levels above the base (temporal)
  double stereo_max_dy_px = 1.0;     // rectified: |v_right - v_left| bound
  int stereo_klt_levels_tracked = 0; // stereo KLT levels for tracked features (seeded)
  double min_disparity_px = 1.0;     // farther points are kept as mono observations
  double max_disparity_px = 200.0;
  int stereo_search_half_patch = 2;  // SAD patch half size (pyramid level 1) for new corners
  double stereo_uniqueness = 1.1;    // second-best SAD must exceed best x this
  double max_forward_backward_px = 1.0;  // temporal KLT forward-backward check
  // KLT start of each keyframe feature: its projection under the
  // constant-velocity prediction (true), or under the predicted rotation only
  // (false; the pyramid then finds the translation's flow). The rotation-only
  // start drifts less on synthetic drives but more on the real excerpt at
  // 5-2.5 Hz (docs/benchmarks.md, "Motorway speed" and "Real excerpt at lower
  // frame rates"), so the full prediction is the default.
  bool klt_guess_translation = true;
  // Motion.
  int ransac_iterations = 100;
  double ransac_threshold_px = 2.0;
  double huber_px = 1.0;             // Huber threshold of the Gauss-Newton refinement
  double outlier_px = 3.0;           // residual beyond which a point is dropped
  // Gauss-Newton also reprojects the current frame's stereo points into the
  // keyframe's two images (errors of both triangulations enter symmetrically).
  bool symmetric_residuals = true;
  // Sliding window: the last window_keyframes keyframes' poses and the points
  // they track are refined together (stereo bundle adjustment, the oldest pose
  // held) each time a keyframe is added; < 2 turns it off. Off by default: on
  // the KLT tracks it is less accurate than the two-frame estimate (chained
  // tracks drift on the ground; docs/benchmarks.md, "Sliding-window bundle
  // adjustment").
  int window_keyframes = 0;
  int window_iterations = 4;         // Levenberg-Marquardt steps per keyframe
  int min_inliers_ok = 40;           // fewer -> DEGRADED
  int min_inliers_degraded = 12;     // fewer -> LOST (re-initialise)
  // Keyframes / standstill: a new keyframe is taken when the median feature
  // displacement since the keyframe exceeds keyframe_flow_px; below
  // standstill_flow_px (and a motion not significant at 3 sigma) the motion
  // against the keyframe is snapped to identity.
  double keyframe_flow_px = 1.0;
  double standstill_flow_px = 0.25;
  double min_image_stddev = 3.0;     // below: black / saturated / flat image
  // Dark frames (vo/image_guard.hpp) are contrast-stretched and tracked while
  // their texture-to-noise ratio is at least this; below, LOST (health kDark).
  double min_dark_snr = 0.6;
  TimingClock timing_clock = TimingClock::kWall;
};

// Configuration of the "thesis" baseline: the stereo VO this project started
// from (docs/architecture.md, "The algorithms"; compared in docs/benchmarks.md).
struct ThesisConfig {
  int grid_cell_px = 60;             // detection grid (thesis: 60x60 px)
  int max_features_per_cell = 6;
  int fast_threshold = 20;
  double ratio = 0.8;                // Lowe ratio test, k = 2
  double max_angle_deg = 30.0;       // angle filter on ORB keypoint orientations
  int num_disparities = 128, block_size = 15;  // StereoBM depth map
  double essential_threshold_px = 1.0;
  int pnp_iterations = 100;
  double pnp_threshold_px = 2.0;
  int min_inliers_ok = 40, min_inliers_degraded = 12;
  double standstill_flow_px = 0.3;   // guard (not in the thesis): no flow -> identity
  double min_image_stddev = 3.0;
  double min_dark_snr = 2.5;         // ORB + StereoBM report wrong motions on noisier stretched images
  TimingClock timing_clock = TimingClock::kWall;
};

// Methods: "default" (locaid's design) and "thesis" (baseline), each behind
// the image checks of vo/image_guard.hpp (frozen and dark frames, health).
// Throws std::invalid_argument for an unknown name.
std::unique_ptr<StereoOdometry> MakeStereoOdometry(const std::string& method,
                                                   const StereoCamera& camera,
                                                   TimingClock clock = TimingClock::kWall);
// The same, with the settings of the "default" method (its timing_clock is
// replaced by `clock`; ignored for other methods).
std::unique_ptr<StereoOdometry> MakeStereoOdometry(const std::string& method,
                                                   const StereoCamera& camera,
                                                   TimingClock clock,
                                                   const DefaultConfig& default_config);
std::unique_ptr<StereoOdometry> MakeDefaultOdometry(const StereoCamera& camera,
                                                    const DefaultConfig& config = {});
std::unique_ptr<StereoOdometry> MakeThesisOdometry(const StereoCamera& camera,
                                                   const ThesisConfig& config = {});
std::vector<std::string> StereoOdometryMethods();

}  // namespace locaid::vo
