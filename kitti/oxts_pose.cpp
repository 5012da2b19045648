#include "kitti/oxts_pose.hpp"
#include "core/timed_pose.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace locaid::kitti {

Eigen::Matrix3d OxtsAttitude(double roll_rad, double pitch_rad, double yaw_rad) {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Isometry3d OxtsToEnuPose(const OxtsRecord& r, const GeographicLib::LocalCartesian& enu) {
  double e = 0, n = 0, u = 0;
  enu.Forward(r.lat_deg, r.lon_deg, r.alt_m, e, n, u);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = OxtsAttitude(r.roll_rad, r.pitch_rad, r.yaw_rad);
  T.translation() = Eigen::Vector3d(e, n, u);
  return T;
}

Eigen::Isometry3d InterpolatePose(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                                  double alpha) {
  const Eigen::Quaterniond q_a(T_a.linear()), q_b(T_b.linear());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q_a.slerp(alpha, q_b).normalized().toRotationMatrix();
  T.translation() = (1.0 - alpha) * T_a.translation() + alpha * T_b.translation();
  return T;
}

std::optional<Eigen::Isometry3d> InterpolatePose(const std::vector<TimedPose>& poses,
                                                 int64_t t_ns, int64_t max_gap_ns) {
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) return std::nullopt;
  const auto b = std::lower_bound(poses.begin(), poses.end(), t_ns,
                                  [](const TimedPose& p, int64_t t) { return p.t_ns < t; });
  if (b->t_ns == t_ns) return b->T_world_cam;
  const auto a = b - 1;  // exists: t_ns > front().t_ns here
  const int64_t gap = b->t_ns - a->t_ns;
  if (gap > max_gap_ns) return std::nullopt;
  const double alpha = static_cast<double>(t_ns - a->t_ns) / static_cast<double>(gap);
  return InterpolatePose(a->T_world_cam, b->T_world_cam, alpha);
}

namespace {

void RequireSortedByTime(const std::vector<OxtsSample>& oxts) {
  for (size_t k = 1; k < oxts.size(); ++k) {
    if (oxts[k].t_ns < oxts[k - 1].t_ns) {
      throw Error("OXTS samples not sorted by time: record " + std::to_string(oxts[k].index) +
                  " is before record " + std::to_string(oxts[k - 1].index));
    }
  }
}

}  // namespace

std::vector<OxtsSample> IntegrateOxtsVelocity(const std::vector<OxtsSample>& oxts) {
  RequireSortedByTime(oxts);
  std::vector<OxtsSample> out = oxts;
  if (oxts.empty()) return out;
  const OxtsRecord& o = oxts.front().record;
  const GeographicLib::LocalCartesian enu(o.lat_deg, o.lon_deg, o.alt_m);
  Eigen::Vector3d p_enu = Eigen::Vector3d::Zero();
  for (size_t k = 1; k < oxts.size(); ++k) {
    const OxtsRecord& a = oxts[k - 1].record;
    const OxtsRecord& b = oxts[k].record;
    const double dt_s = static_cast<double>(oxts[k].t_ns - oxts[k - 1].t_ns) * 1e-9;
    p_enu += 0.5 * dt_s * Eigen::Vector3d(a.ve_mps + b.ve_mps, a.vn_mps + b.vn_mps, a.vu_mps + b.vu_mps);
    OxtsRecord& r = out[k].record;
    enu.Reverse(p_enu.x(), p_enu.y(), p_enu.z(), r.lat_deg, r.lon_deg, r.alt_m);
  }
  return out;
}

OxtsGroundTruth ComputeOxtsGroundTruth(const std::vector<OxtsSample>& oxts,
                                       const std::vector<int64_t>& frame_t_ns,
                                       const Eigen::Isometry3d& T_cam0_imu, double max_gap_s) {
  OxtsGroundTruth gt;
  gt.T_world_cam.assign(frame_t_ns.size(), std::nullopt);
  if (oxts.empty()) return gt;
  RequireSortedByTime(oxts);
  const OxtsRecord& o = oxts.front().record;
  gt.origin_lat_deg = o.lat_deg;
  gt.origin_lon_deg = o.lon_deg;
  gt.origin_alt_m = o.alt_m;
  const GeographicLib::LocalCartesian enu(o.lat_deg, o.lon_deg, o.alt_m);
  gt.enu_imu.reserve(oxts.size());
  for (const OxtsSample& s : oxts) gt.enu_imu.push_back({s.t_ns, OxtsToEnuPose(s.record, enu)});

  const auto max_gap_ns = static_cast<int64_t>(std::llround(max_gap_s * 1e9));
  const Eigen::Isometry3d T_imu_cam0 = T_cam0_imu.inverse();
  std::vector<std::optional<Eigen::Isometry3d>> T_enu_cam(frame_t_ns.size());
  for (size_t i = 0; i < frame_t_ns.size(); ++i) {
    if (auto T_enu_imu = InterpolatePose(gt.enu_imu, frame_t_ns[i], max_gap_ns)) {
      T_enu_cam[i] = *T_enu_imu * T_imu_cam0;
      if (gt.anchor_frame < 0) {
        gt.anchor_frame = static_cast<int>(i);
        gt.T_enu_world = *T_enu_cam[i];
      }
    }
  }
  const Eigen::Isometry3d T_world_enu = gt.T_enu_world.inverse();
  for (size_t i = 0; i < frame_t_ns.size(); ++i) {
    if (T_enu_cam[i]) gt.T_world_cam[i] = T_world_enu * *T_enu_cam[i];
  }
  return gt;
}

}  // namespace locaid::kitti
