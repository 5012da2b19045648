#include "fusion/fixed_lag_smoother.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace locaid::fusion {

FixedLagSmoother::FixedLagSmoother(double lag_s, ErrorLayout layout) : lag_s_(lag_s), layout_(layout) {
  if (!(lag_s > 0) || !std::isfinite(lag_s))
    throw std::invalid_argument("fixed-lag smoother: lag must be > 0 s (got " + std::to_string(lag_s) + ")");
}

void FixedLagSmoother::AddEpoch(const Epoch& epoch) {
  // Epochs older than the oldest waiting pose's are no longer needed.
  window_.push_back(epoch);
  const int64_t oldest = waiting_.empty() ? epoch.seq : waiting_.front().epoch;
  while (window_.size() > 1 && window_.front().seq < oldest) window_.pop_front();
}

std::vector<FusedPose> FixedLagSmoother::AddPose(const FusedPose& forward, int64_t epoch, const Epoch* open) {
  waiting_.push_back({forward, epoch});
  const auto lag_ns = static_cast<int64_t>(std::llround(lag_s_ * 1e9));
  return Release(forward.t_ns - lag_ns, open, false);
}

std::vector<FusedPose> FixedLagSmoother::Flush(const Epoch* open) { return Release(0, open, true); }

std::vector<FusedPose> FixedLagSmoother::Release(int64_t until_ns, const Epoch* open, bool flush) {
  std::vector<FusedPose> out;
  size_t ready = 0;
  while (ready < waiting_.size() && (flush || waiting_[ready].pose.t_ns <= until_ns)) ++ready;
  if (ready == 0) return out;
  // The backward pass from the newest epoch down to the oldest ready pose's.
  int64_t oldest = -1;
  for (size_t i = 0; i < ready; ++i)
    if (waiting_[i].epoch >= 0) oldest = oldest < 0 ? waiting_[i].epoch : std::min(oldest, waiting_[i].epoch);
  std::vector<std::pair<int64_t, SmoothedError>> smoothed;  // newest first
  if (oldest >= 0) {
    const Epoch* next = open;
    SmoothedError next_s;
    auto visit = [&](const Epoch& e) {
      SmoothedError s = next && next->linked && next->seq == e.seq + 1 ? RtsStep(e, *next, next_s) : ChainEnd(e);
      smoothed.emplace_back(e.seq, s);
      next = &e;
      next_s = std::move(s);
    };
    if (open) visit(*open);
    for (auto it = window_.rbegin(); it != window_.rend() && it->seq >= oldest; ++it) {
      if (open && it->seq >= open->seq) continue;
      visit(*it);
    }
  }
  const auto epoch_at = [&](int64_t seq) -> const Epoch* {
    if (open && open->seq == seq) return open;
    if (window_.empty() || seq < window_.front().seq || seq > window_.back().seq) return nullptr;
    return &window_[static_cast<size_t>(seq - window_.front().seq)];  // consecutive seqs
  };
  const int64_t newest = smoothed.empty() ? 0 : smoothed.front().first;
  for (size_t i = 0; i < ready; ++i) {
    const Waiting& w = waiting_[i];
    FusedPose p = w.pose;
    p.smoothed = true;
    const Epoch* e = w.epoch >= 0 ? epoch_at(w.epoch) : nullptr;
    const auto k = static_cast<size_t>(newest - w.epoch);  // smoothed is newest first, consecutive
    if (e && w.epoch <= newest && k < smoothed.size()) p = SmoothedPose(*e, smoothed[k].second, layout_, w.pose);
    out.push_back(std::move(p));
  }
  waiting_.erase(waiting_.begin(), waiting_.begin() + static_cast<ptrdiff_t>(ready));
  return out;
}

}  // namespace locaid::fusion
