#include "ros/tf_tree.hpp"

#include <map>
#include <queue>
#include <utility>

namespace locaid::ros {

std::optional<Eigen::Isometry3d> FindTransform(const std::vector<TransformStamped>& transforms,
                                               const std::string& a, const std::string& b) {
  // Undirected edges: from each frame, the neighbour and T_frame_neighbour.
  std::multimap<std::string, std::pair<std::string, Eigen::Isometry3d>> edges;
  for (const auto& t : transforms) {
    edges.emplace(t.header.frame_id, std::make_pair(t.child_frame_id, t.T_parent_child));
    edges.emplace(t.child_frame_id, std::make_pair(t.header.frame_id, t.T_parent_child.inverse()));
  }
  // Breadth-first from a, keeping T_a_frame.
  std::map<std::string, Eigen::Isometry3d> reached{{a, Eigen::Isometry3d::Identity()}};
  std::queue<std::string> open;
  open.push(a);
  while (!open.empty()) {
    const std::string f = open.front();
    open.pop();
    if (f == b) return reached.at(f);
    const auto range = edges.equal_range(f);
    for (auto it = range.first; it != range.second; ++it) {
      const auto& [next, T_f_next] = it->second;
      if (reached.count(next)) continue;
      reached.emplace(next, reached.at(f) * T_f_next);
      open.push(next);
    }
  }
  return std::nullopt;
}

}  // namespace locaid::ros
