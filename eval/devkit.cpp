#include "eval/devkit.hpp"

#include "kitti/types.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <Eigen/Geometry>
#include <vector>

namespace locaid::eval {
namespace {

// The devkit buckets segments by length with |len - L| < 1 m.
constexpr float kLengthBucketM = 1.0f;

}  // namespace

std::vector<float> TrajectoryDistances(const std::vector<Eigen::Isometry3d>& poses) {
  std::vector<float> dist;
  dist.reserve(poses.size());
  if (poses.empty()) return dist;
  dist.push_back(0.0f);
  for (size_t i = 1; i < poses.size(); ++i) {
    // Differences in double, then float, as the devkit does.
    const float dx = static_cast<float>(poses[i - 1].matrix()(0, 3) - poses[i].matrix()(0, 3));
    const float dy = static_cast<float>(poses[i - 1].matrix()(1, 3) - poses[i].matrix()(1, 3));
    const float dz = static_cast<float>(poses[i - 1].matrix()(2, 3) - poses[i].matrix()(2, 3));
    dist.push_back(dist[i - 1] + std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return dist;
}

int LastFrameFromSegmentLength(const std::vector<float>& dist, int first_frame, float length_m) {
  if (first_frame < 0 || static_cast<size_t>(first_frame) >= dist.size()) return -1;
  const float target = dist[static_cast<size_t>(first_frame)] + length_m;
  for (size_t i = static_cast<size_t>(first_frame); i < dist.size(); ++i) {
    if (dist[i] > target) return static_cast<int>(i);
  }
  return -1;
}

float RotationError(const Eigen::Matrix4d& pose_error) {
  const float a = static_cast<float>(pose_error(0, 0));
  const float b = static_cast<float>(pose_error(1, 1));
  const float c = static_cast<float>(pose_error(2, 2));
  // The float sum a + b + c is promoted to double by "- 1.0", then stored as float.
  const float d = static_cast<float>(0.5 * (static_cast<double>(a + b + c) - 1.0));
  return std::acos(std::max(std::min(d, 1.0f), -1.0f));
}

float TranslationError(const Eigen::Matrix4d& pose_error) {
  const float dx = static_cast<float>(pose_error(0, 3));
  const float dy = static_cast<float>(pose_error(1, 3));
  const float dz = static_cast<float>(pose_error(2, 3));
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

std::vector<SegmentError> ComputeSequenceErrors(const std::vector<Eigen::Isometry3d>& gt,
                                                const std::vector<Eigen::Isometry3d>& est,
                                                const DevkitConfig& config) {
  if (gt.size() != est.size()) {
    throw kitti::Error("devkit metric: ground truth has " + std::to_string(gt.size()) +
                " poses, estimate has " + std::to_string(est.size()) + "; they must match");
  }
  if (config.step_frames < 1) {
    throw kitti::Error("devkit metric: step_frames must be >= 1, got " + std::to_string(config.step_frames));
  }
  std::vector<SegmentError> errors;
  const std::vector<float> dist = TrajectoryDistances(gt);
  const int n = static_cast<int>(gt.size());
  for (int first = 0; first < n; first += config.step_frames) {
    for (float length_m : config.lengths_m) {
      const int last = LastFrameFromSegmentLength(dist, first, length_m);
      if (last == -1) continue;
      const size_t f = static_cast<size_t>(first);
      const size_t l = static_cast<size_t>(last);
      // General inverses (the devkit does not assume orthonormal rotations).
      const Eigen::Matrix4d delta_gt = gt[f].matrix().inverse() * gt[l].matrix();
      const Eigen::Matrix4d delta_est = est[f].matrix().inverse() * est[l].matrix();
      const Eigen::Matrix4d pose_error = delta_est.inverse() * delta_gt;
      SegmentError e;
      e.first_frame = first;
      e.last_frame = last;
      e.length_m = length_m;
      e.r_err_rad_per_m = RotationError(pose_error) / length_m;
      e.t_err = TranslationError(pose_error) / length_m;
      const float num_frames = static_cast<float>(last - first + 1);
      e.speed_mps = static_cast<float>(length_m / (config.frame_period_s * num_frames));
      errors.push_back(e);
    }
  }
  return errors;
}

DevkitResult EvaluateDevkit(const std::vector<Eigen::Isometry3d>& gt,
                            const std::vector<Eigen::Isometry3d>& est, const DevkitConfig& config) {
  DevkitResult result;
  result.segments = ComputeSequenceErrors(gt, est, config);

  // Float sums in segment order, as the devkit's getStats / saveStats.
  if (!result.segments.empty()) {
    float t_sum = 0, r_sum = 0;
    for (const SegmentError& e : result.segments) {
      t_sum += e.t_err;
      r_sum += e.r_err_rad_per_m;
    }
    const float num = static_cast<float>(result.segments.size());
    result.t_err = t_sum / num;
    result.r_err_rad_per_m = r_sum / num;
  }

  for (float length_m : config.lengths_m) {
    LengthAverage avg;
    avg.length_m = length_m;
    float t_sum = 0, r_sum = 0;
    for (const SegmentError& e : result.segments) {
      if (std::fabs(e.length_m - length_m) < kLengthBucketM) {
        t_sum += e.t_err;
        r_sum += e.r_err_rad_per_m;
        ++avg.segments;
      }
    }
    if (avg.segments > 0) {
      const float num = static_cast<float>(avg.segments);
      avg.t_err = t_sum / num;
      avg.r_err_rad_per_m = r_sum / num;
    }
    result.per_length.push_back(avg);
  }
  return result;
}

}  // namespace locaid::eval
