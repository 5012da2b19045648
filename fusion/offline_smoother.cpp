#include "fusion/offline_smoother.hpp"

#include <stdexcept>
#include <unordered_map>

namespace locaid::fusion {

std::vector<FusedPose> OfflineSmoother::Smooth(const std::vector<FusedPose>& forward,
                                               const std::vector<int64_t>& epochs, const ErrorLayout& layout) {
  if (forward.size() != epochs.size()) throw std::invalid_argument("OfflineSmoother: one epoch per pose");
  log_.Finish();
  std::vector<FusedPose> out = forward;
  std::unordered_map<int64_t, std::vector<size_t>> poses_of;  // several poses may share an epoch
  for (size_t i = 0; i < epochs.size(); ++i)
    if (epochs[i] >= 0) poses_of[epochs[i]].push_back(i);
  store_.SmoothBackward([&](const Epoch& e, const SmoothedError& s) {
    const auto it = poses_of.find(e.seq);
    if (it == poses_of.end()) return;
    for (size_t i : it->second) out[i] = SmoothedPose(e, s, layout, forward[i]);
  });
  return out;
}

}  // namespace locaid::fusion
