// A fixed-lag smoother: the backward pass of rts_smoother.hpp over the
// epochs of the last `lag` seconds, run as poses arrive. Each pose comes out
// once the filter is `lag` seconds past it, as the estimate of its time given
// everything up to then (FusedPose::smoothed), with its covariance. A lag
// longer than the drive gives, at Flush, the offline smoother's poses.
//
// Feed it from an EpochLog's sink (AddEpoch) and each forward pose with its
// epoch (AddPose, after Ekf::MarkEpoch); several smoothers (several lags) can
// share one log. Memory: the epochs of one lag (EpochBytes each, at the
// filter's update rate) and the poses waiting in it.
//
// Single-threaded, like the filter it follows.
#pragma once

#include "fusion/epoch_log.hpp"
#include "fusion/rts_smoother.hpp"
#include "fusion/types.hpp"

#include <deque>
#include <vector>

namespace locaid::fusion {

class FixedLagSmoother {
 public:
  // Throws std::invalid_argument unless 0 < lag_s (finite).
  FixedLagSmoother(double lag_s, ErrorLayout layout);

  double lag_s() const { return lag_s_; }
  // A completed epoch (EpochLog's sink).
  void AddEpoch(const Epoch& epoch);
  // A forward pose and its epoch (-1: the filter had not started; it comes
  // out unchanged, in order). `open`: the log's open epoch (EpochLog::open),
  // the newest state. Returns the poses whose lag has passed, oldest first.
  std::vector<FusedPose> AddPose(const FusedPose& forward, int64_t epoch, const Epoch* open);
  // The end of the drive: every waiting pose, smoothed with what there is.
  std::vector<FusedPose> Flush(const Epoch* open);
  size_t waiting() const { return waiting_.size(); }
  size_t epochs() const { return window_.size(); }

 private:
  struct Waiting {
    FusedPose pose;
    int64_t epoch;
  };
  // Smooths and releases the waiting poses up to `until_ns` (all with flush).
  std::vector<FusedPose> Release(int64_t until_ns, const Epoch* open, bool flush);

  double lag_s_;
  ErrorLayout layout_;
  std::deque<Epoch> window_;
  std::deque<Waiting> waiting_;
};

}  // namespace locaid::fusion
