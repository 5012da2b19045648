// Absolute trajectory error (ATE) and per-frame relative pose error (RPE) of
// an estimated trajectory against ground truth, pose i matched with pose i.
#pragma once

#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace locaid::eval {

struct ErrorStats {
  size_t count = 0;
  double rmse = 0, mean = 0, median = 0, max = 0;
};

// Statistics of non-negative error values (median of an even count is the
// mean of the two middle values). All zero for an empty input.
ErrorStats ComputeStats(std::vector<double> values);

// Rotation angle of a 3x3 rotation in radians, in [0, pi]; accurate for tiny
// angles (atan2 of the skew part and the trace, not acos).
double RotationAngleRad(const Eigen::Matrix3d& R);

// Least-squares rigid transform T (no scale) with dst_i ~ T * src_i
// (Umeyama 1991). Needs at least one point pair; with fewer than 3
// non-collinear points the rotation is not unique (one minimiser is returned).
Eigen::Isometry3d AlignSe3(const std::vector<Eigen::Vector3d>& src,
                           const std::vector<Eigen::Vector3d>& dst);

enum class Alignment { kNone, kSe3 };

struct AteResult {
  ErrorStats trans_m;
  // Maps estimate-world coordinates into ground-truth-world coordinates
  // (identity for Alignment::kNone).
  Eigen::Isometry3d T_gtworld_estworld = Eigen::Isometry3d::Identity();
};

// Position error |p_gt_i - T * p_est_i| after optional SE(3) alignment.
// Throws kitti::Error on size mismatch or empty input.
AteResult ComputeAte(const std::vector<Eigen::Isometry3d>& gt,
                     const std::vector<Eigen::Isometry3d>& est, Alignment alignment);

struct RpeResult {
  ErrorStats trans_m;
  ErrorStats rot_deg;
};

// Per consecutive frame pair: E = inv(inv(gt_i) gt_i+1) * inv(est_i) est_i+1;
// translation |t(E)| in m, rotation angle(E) in degrees. Alignment-free.
// Throws kitti::Error on size mismatch.
RpeResult ComputeRpe(const std::vector<Eigen::Isometry3d>& gt,
                     const std::vector<Eigen::Isometry3d>& est);

// Total path length (double precision) of the positions.
double PathLengthM(const std::vector<Eigen::Isometry3d>& poses);

}  // namespace locaid::eval
