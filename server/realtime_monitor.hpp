// Does a session keep real time, and what does its thread cost? For paced
// sessions (playback_rate > 0) every pose has a due time (its sensor time
// over the rate, from the first pose); the monitor keeps how late the newest
// pose was published, how overdue the next one is, the sensor seconds per
// wall second over the last ~2 s and the session thread's CPU time per wall
// second (with its decode helper's) over the last ~5 s (docs/api.md "Keeping real time"). Note*() on
// the session thread; Fill() from any thread. Bounded: at most ~100 samples
// per window.
#pragma once

#include "locaid/v1/localization.pb.h"

#include <chrono>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

namespace locaid::server {

class RealTimeMonitor {
 public:
  using Clock = std::chrono::steady_clock;

  // rate: the session's playback rate (<= 0: not paced, nothing is ever
  // late); threshold_s: lateness above which the session is falling behind.
  RealTimeMonitor(double rate, double threshold_s) : rate_(rate), threshold_s_(threshold_s) {}

  // A pose with sensor time t_ns published at `now`; `due`: when it was due
  // (nullopt: not paced, or the first pose). Returns its lateness, s.
  double NotePose(int64_t t_ns, std::optional<Clock::time_point> due, Clock::time_point now);
  // The session waits until `due` to publish its next pose: until then it
  // is not behind, whatever the previous frame period suggested (a gap in
  // the input).
  void NoteWaiting(Clock::time_point due);
  // The calling (session) thread's CPU time so far plus `other_cpu_s` (what
  // its helper threads used so far), sampled at most every 50 ms.
  void NoteCpu(Clock::time_point now, double other_cpu_s = 0);
  // The session stopped publishing for good (ended): nothing is overdue.
  void NoteEnded();

  // Lateness now: the newest pose's, or how overdue the next one is.
  double BehindNow(Clock::time_point now) const;
  bool FallingBehind(Clock::time_point now) const { return BehindNow(now) > threshold_s_; }
  // CPU cores the session thread used over the last ~5 s.
  double CpuCores(Clock::time_point now) const;
  // Sets behind_real_time_s, behind_real_time_max_s, falling_behind,
  // realtime_factor and cpu_cores.
  void Fill(locaid::v1::SessionStats* stats, Clock::time_point now) const;
  double threshold_s() const { return threshold_s_; }

 private:
  double BehindLocked(Clock::time_point now) const;

  const double rate_;
  const double threshold_s_;
  mutable std::mutex mu_;
  double last_behind_s_ = 0, max_behind_s_ = 0;
  std::optional<Clock::time_point> next_due_;  // when the pose after the newest is due (estimate)
  std::optional<int64_t> last_t_ns_;
  bool ended_ = false;
  std::deque<std::pair<Clock::time_point, int64_t>> poses_;  // (published, sensor time), last ~2 s
  std::deque<std::pair<Clock::time_point, double>> cpu_;     // (sampled, thread CPU s), last ~5 s
};

}  // namespace locaid::server
