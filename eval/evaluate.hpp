// All trajectory metrics of one estimate against ground truth, in one call:
// the KITTI devkit metric, ATE and per-frame RPE.
#pragma once

#include "eval/associate.hpp"
#include "eval/devkit.hpp"
#include "eval/trajectory_metrics.hpp"

#include <vector>

namespace locaid::eval {

struct EvalConfig {
  Alignment alignment = Alignment::kSe3;  // for ATE only
  double max_dt_s = 0.02;                 // TUM timestamp association
  DevkitConfig devkit;
  kitti::PoseReadConfig read;
};

struct EvalReport {
  size_t frames = 0;     // matched pose pairs
  double length_m = 0;   // ground-truth path length over the matched poses
  DevkitResult devkit;   // no segments when length_m < shortest segment length
  AteResult ate;
  RpeResult rpe;
};

// gt[i] is matched with est[i]. Throws kitti::Error on size mismatch / empty.
EvalReport Evaluate(const std::vector<Eigen::Isometry3d>& gt,
                    const std::vector<Eigen::Isometry3d>& est, const EvalConfig& config = {});

}  // namespace locaid::eval
