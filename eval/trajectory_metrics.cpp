#include "eval/trajectory_metrics.hpp"

#include "kitti/types.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace locaid::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

void CheckSameSize(const std::vector<Eigen::Isometry3d>& gt,
                   const std::vector<Eigen::Isometry3d>& est, const char* what) {
  if (gt.size() != est.size()) {
    throw kitti::Error(std::string(what) + ": ground truth has " + std::to_string(gt.size()) +
                " poses, estimate has " + std::to_string(est.size()) + "; they must match");
  }
}

}  // namespace

ErrorStats ComputeStats(std::vector<double> values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) return s;
  double sum = 0, sum_sq = 0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
    s.max = std::max(s.max, v);
  }
  const double n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  s.median = values[mid];
  if (values.size() % 2 == 0) {
    const double lower = *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = 0.5 * (s.median + lower);
  }
  return s;
}

double RotationAngleRad(const Eigen::Matrix3d& R) {
  const Eigen::Vector3d skew(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * skew.norm(), 0.5 * (R.trace() - 1.0));
}

Eigen::Isometry3d AlignSe3(const std::vector<Eigen::Vector3d>& src,
                           const std::vector<Eigen::Vector3d>& dst) {
  if (src.size() != dst.size() || src.empty()) {
    throw kitti::Error("SE(3) alignment: needs equally many (>= 1) points, got " +
                std::to_string(src.size()) + " and " + std::to_string(dst.size()));
  }
  Eigen::Matrix3Xd S(3, static_cast<Eigen::Index>(src.size()));
  Eigen::Matrix3Xd D(3, static_cast<Eigen::Index>(dst.size()));
  for (size_t i = 0; i < src.size(); ++i) {
    S.col(static_cast<Eigen::Index>(i)) = src[i];
    D.col(static_cast<Eigen::Index>(i)) = dst[i];
  }
  Eigen::Isometry3d T;
  T.matrix() = Eigen::umeyama(S, D, /*with_scaling=*/false);
  return T;
}

AteResult ComputeAte(const std::vector<Eigen::Isometry3d>& gt,
                     const std::vector<Eigen::Isometry3d>& est, Alignment alignment) {
  CheckSameSize(gt, est, "ATE");
  if (gt.empty()) throw kitti::Error("ATE: no poses");
  AteResult result;
  if (alignment == Alignment::kSe3) {
    std::vector<Eigen::Vector3d> p_est(est.size()), p_gt(gt.size());
    for (size_t i = 0; i < gt.size(); ++i) {
      p_est[i] = est[i].translation();
      p_gt[i] = gt[i].translation();
    }
    result.T_gtworld_estworld = AlignSe3(p_est, p_gt);
  }
  std::vector<double> errors(gt.size());
  for (size_t i = 0; i < gt.size(); ++i) {
    errors[i] = (gt[i].translation() - result.T_gtworld_estworld * est[i].translation()).norm();
  }
  result.trans_m = ComputeStats(std::move(errors));
  return result;
}

RpeResult ComputeRpe(const std::vector<Eigen::Isometry3d>& gt,
                     const std::vector<Eigen::Isometry3d>& est) {
  CheckSameSize(gt, est, "RPE");
  std::vector<double> trans_m, rot_deg;
  for (size_t i = 0; i + 1 < gt.size(); ++i) {
    const Eigen::Isometry3d delta_gt = gt[i].inverse() * gt[i + 1];
    const Eigen::Isometry3d delta_est = est[i].inverse() * est[i + 1];
    const Eigen::Isometry3d E = delta_gt.inverse() * delta_est;
    trans_m.push_back(E.translation().norm());
    rot_deg.push_back(RotationAngleRad(E.linear()) * kRadToDeg);
  }
  RpeResult result;
  result.trans_m = ComputeStats(std::move(trans_m));
  result.rot_deg = ComputeStats(std::move(rot_deg));
  return result;
}

double PathLengthM(const std::vector<Eigen::Isometry3d>& poses) {
  double length_m = 0;
  for (size_t i = 1; i < poses.size(); ++i) {
    length_m += (poses[i].translation() - poses[i - 1].translation()).norm();
  }
  return length_m;
}

}  // namespace locaid::eval
