// Matching the poses of a ground-truth file with those of an estimate file.
#pragma once

#include "kitti/pose_io.hpp"

#include <cstddef>
#include <filesystem>
#include <utility>
#include <vector>

namespace locaid::eval {

struct IndexPair {
  size_t gt = 0;
  size_t est = 0;
};

// Timestamp association as in TUM's associate.py (which evo follows): every
// (gt, est) pair with |t_gt - t_est| <= max_dt_s is a candidate; candidates
// are taken closest first, each gt and each est stamp used at most once.
// Returned sorted by est index. Stamps need not be sorted.
std::vector<IndexPair> AssociateByTime(const std::vector<double>& t_gt_s,
                                       const std::vector<double>& t_est_s, double max_dt_s);

struct MatchedPoses {
  kitti::PoseFormat format = kitti::PoseFormat::kKitti;
  size_t gt_count = 0, est_count = 0;  // poses in the files
  std::vector<double> t_s;             // gt stamp (KITTI: frame index)
  std::vector<Eigen::Isometry3d> gt, est;
};

// Reads both files (format auto-detected) and pairs them: KITTI by line index
// (both files must have the same number of poses), TUM by timestamp. Throws
// kitti::Error (mixed formats, count mismatch, fewer than 2 matched pairs).
MatchedPoses LoadMatchedPoses(const std::filesystem::path& gt_path,
                              const std::filesystem::path& est_path, double max_dt_s,
                              const kitti::PoseReadConfig& read_config = {});

}  // namespace locaid::eval
