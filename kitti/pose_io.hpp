// Pose files: KITTI odometry format and TUM format, read and written.
//
//   KITTI: one pose per line, 12 numbers = the 3x4 matrix [R | t] of T_world_cam
//          row-major (the frame index is the line index; no time).
//   TUM:   "t tx ty tz qx qy qz qw" per line (t in seconds, quaternion
//          Hamilton, x y z w order); lines starting with '#' are comments.
//
// Blank lines are ignored in both formats. Every reader error throws
// kitti::Error naming file, line and reason, e.g.
//   "est.txt:17: 11 numbers, expected 12 (KITTI 3x4 row-major)".
// Writers write to a temporary file in the same folder, then rename it over the
// target, so a reader never sees a half-written file. Numbers are written with
// the shortest representation that reads back to the identical double.
#pragma once

#include "kitti/types.hpp"

#include <Eigen/Geometry>

#include <filesystem>
#include <vector>

namespace locaid::kitti {

struct StampedPose {
  double t_s = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

enum class PoseFormat { kKitti, kTum };

struct PoseReadConfig {
  // Largest allowed |R^T R - I| entry of a KITTI rotation block (files written
  // with 6 decimals deviate by ~1e-6; float output by ~1e-7). det(R) must also
  // be within this tolerance of +1 (reflections are rejected).
  double rotation_tolerance = 1e-2;
};

// KITTI rotation blocks are kept exactly as read (not re-orthonormalised), so
// metrics see the same numbers as the official devkit.
std::vector<Eigen::Isometry3d> ReadKittiPoses(const std::filesystem::path& path,
                                              const PoseReadConfig& config = {});

// The quaternion is normalised; a (near) zero-norm quaternion is an error.
std::vector<StampedPose> ReadTumPoses(const std::filesystem::path& path);

// Poses of either format; KITTI poses get t_s = line index (frame number).
struct PoseFile {
  PoseFormat format = PoseFormat::kKitti;
  std::vector<StampedPose> poses;
};

// Detects the format from the first non-blank, non-comment line: 12 numbers =
// KITTI, 8 numbers = TUM; anything else (or no pose line at all) is an error.
PoseFile ReadPoses(const std::filesystem::path& path, const PoseReadConfig& config = {});

void WriteKittiPoses(const std::filesystem::path& path,
                     const std::vector<Eigen::Isometry3d>& poses_T_world_cam);
void WriteTumPoses(const std::filesystem::path& path, const std::vector<StampedPose>& poses);

}  // namespace locaid::kitti
