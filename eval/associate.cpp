#include "eval/associate.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <tuple>

namespace locaid::eval {
namespace {

// A trajectory needs at least two poses for any relative metric.
constexpr size_t kMinMatchedPoses = 2;

const char* FormatName(kitti::PoseFormat f) { return f == kitti::PoseFormat::kKitti ? "KITTI" : "TUM"; }

}  // namespace

std::vector<IndexPair> AssociateByTime(const std::vector<double>& t_gt_s,
                                       const std::vector<double>& t_est_s, double max_dt_s) {
  if (!(max_dt_s >= 0)) throw kitti::Error("association: max_dt_s must be >= 0, got " + std::to_string(max_dt_s));
  // gt indices sorted by time, for a window search per est stamp.
  std::vector<size_t> gt_order(t_gt_s.size());
  std::iota(gt_order.begin(), gt_order.end(), size_t{0});
  std::stable_sort(gt_order.begin(), gt_order.end(),
                   [&](size_t a, size_t b) { return t_gt_s[a] < t_gt_s[b]; });

  struct Candidate {
    double dt;
    size_t gt, est;
  };
  std::vector<Candidate> candidates;
  for (size_t e = 0; e < t_est_s.size(); ++e) {
    const double t = t_est_s[e];
    auto it = std::lower_bound(gt_order.begin(), gt_order.end(), t - max_dt_s,
                               [&](size_t g, double value) { return t_gt_s[g] < value; });
    for (; it != gt_order.end() && t_gt_s[*it] <= t + max_dt_s; ++it) {
      const double dt = std::abs(t_gt_s[*it] - t);
      if (dt <= max_dt_s) candidates.push_back({dt, *it, e});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.dt, a.gt, a.est) < std::tie(b.dt, b.gt, b.est);
  });

  std::vector<bool> gt_used(t_gt_s.size(), false), est_used(t_est_s.size(), false);
  std::vector<IndexPair> pairs;
  for (const Candidate& c : candidates) {
    if (gt_used[c.gt] || est_used[c.est]) continue;
    gt_used[c.gt] = est_used[c.est] = true;
    pairs.push_back({c.gt, c.est});
  }
  std::sort(pairs.begin(), pairs.end(), [](const IndexPair& a, const IndexPair& b) { return a.est < b.est; });
  return pairs;
}

MatchedPoses LoadMatchedPoses(const std::filesystem::path& gt_path,
                              const std::filesystem::path& est_path, double max_dt_s,
                              const kitti::PoseReadConfig& read_config) {
  const kitti::PoseFile gt = kitti::ReadPoses(gt_path, read_config);
  const kitti::PoseFile est = kitti::ReadPoses(est_path, read_config);
  if (gt.format != est.format) {
    throw kitti::Error("ground truth " + gt_path.string() + " is " + FormatName(gt.format) +
                " but estimate " + est_path.string() + " is " + FormatName(est.format) +
                "; both files must have the same format");
  }
  MatchedPoses m;
  m.format = gt.format;
  m.gt_count = gt.poses.size();
  m.est_count = est.poses.size();
  if (gt.format == kitti::PoseFormat::kKitti) {
    if (gt.poses.size() != est.poses.size()) {
      throw kitti::Error("ground truth " + gt_path.string() + " has " + std::to_string(gt.poses.size()) +
                  " poses but estimate " + est_path.string() + " has " +
                  std::to_string(est.poses.size()) +
                  "; KITTI files are matched line by line and must have the same count");
    }
    for (size_t i = 0; i < gt.poses.size(); ++i) {
      m.t_s.push_back(gt.poses[i].t_s);
      m.gt.push_back(gt.poses[i].T_world_cam);
      m.est.push_back(est.poses[i].T_world_cam);
    }
  } else {
    std::vector<double> t_gt, t_est;
    for (const kitti::StampedPose& p : gt.poses) t_gt.push_back(p.t_s);
    for (const kitti::StampedPose& p : est.poses) t_est.push_back(p.t_s);
    for (const IndexPair& ij : AssociateByTime(t_gt, t_est, max_dt_s)) {
      m.t_s.push_back(gt.poses[ij.gt].t_s);
      m.gt.push_back(gt.poses[ij.gt].T_world_cam);
      m.est.push_back(est.poses[ij.est].T_world_cam);
    }
  }
  if (m.gt.size() < kMinMatchedPoses) {
    throw kitti::Error("only " + std::to_string(m.gt.size()) + " matched poses between " + gt_path.string() +
                " (" + std::to_string(m.gt_count) + " poses) and " + est_path.string() + " (" +
                std::to_string(m.est_count) + " poses) with max_dt " + std::to_string(max_dt_s) +
                " s; need at least " + std::to_string(kMinMatchedPoses));
  }
  return m;
}

}  // namespace locaid::eval
