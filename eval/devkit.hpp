// The KITTI odometry benchmark metric, computed the way the official devkit
// (devkit_odometry.zip, cpp/evaluate_odometry.cpp) computes it, so results
// agree with it to float rounding:
//   - distances along the ground truth are accumulated in float;
//   - for every first frame 0, step, 2*step, ... and every segment length L,
//     the last frame is the first frame whose distance exceeds dist[first] + L
//     (strictly); segments that run off the end are skipped;
//   - pose_error = inv(inv(est_f) est_l) * inv(gt_f) gt_l, with general 4x4
//     inverses in double;
//   - r_err = acos(clamp(0.5 (R00 + R11 + R22 - 1), -1, 1)) / L and
//     t_err = |t(pose_error)| / L, evaluated in float as the devkit does;
//   - the reported average is the plain mean over ALL segments of all lengths
//     (float sums), what the devkit writes to stats.txt.
// t_err is a fraction (x100 = %), r_err is rad/m (x 180/pi x 100 = deg/100 m).
#pragma once

#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace locaid::eval {

struct DevkitConfig {
  std::vector<float> lengths_m = {100, 200, 300, 400, 500, 600, 700, 800};
  int step_frames = 10;         // first frames are 0, step, 2 step, ...
  double frame_period_s = 0.1;  // only used for the speed of a segment
};

struct SegmentError {
  int first_frame = 0;
  int last_frame = 0;
  float length_m = 0;
  float r_err_rad_per_m = 0;
  float t_err = 0;  // translation error / length (fraction)
  float speed_mps = 0;
};

struct LengthAverage {
  float length_m = 0;
  int segments = 0;
  // Mean over the segments of this length (nullopt when there are none).
  std::optional<double> t_err, r_err_rad_per_m;
};

struct DevkitResult {
  std::vector<SegmentError> segments;
  std::vector<LengthAverage> per_length;  // one entry per configured length
  // Mean over all segments; nullopt when the trajectory has no segment (it is
  // shorter than the shortest length).
  std::optional<double> t_err, r_err_rad_per_m;
};

// Cumulative path length of the positions, dist[0] = 0, accumulated in float.
std::vector<float> TrajectoryDistances(const std::vector<Eigen::Isometry3d>& poses);

// First frame i >= first_frame with dist[i] > dist[first_frame] + length_m,
// or -1 if the trajectory is not long enough.
int LastFrameFromSegmentLength(const std::vector<float>& dist, int first_frame, float length_m);

// Rotation angle (rad) and translation norm (m) of a 4x4 pose error, in float.
float RotationError(const Eigen::Matrix4d& pose_error);
float TranslationError(const Eigen::Matrix4d& pose_error);

// Throws kitti::Error when the two trajectories differ in size.
std::vector<SegmentError> ComputeSequenceErrors(const std::vector<Eigen::Isometry3d>& gt,
                                                const std::vector<Eigen::Isometry3d>& est,
                                                const DevkitConfig& config = {});

DevkitResult EvaluateDevkit(const std::vector<Eigen::Isometry3d>& gt,
                            const std::vector<Eigen::Isometry3d>& est,
                            const DevkitConfig& config = {});

}  // namespace locaid::eval
