// What a session counts from its step results: the SessionStats figures, the
// frame rate over the last 2 s, and the newest pose's figures with a latency
// histogram for the operator metrics (server/metrics.cpp). Record() on the
// session thread; the readers from any thread.
#pragma once

#include "fusion/types.hpp"
#include "locaid/v1/localization.pb.h"
#include "pipeline/frame_loop.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <mutex>

namespace locaid::server {

struct SessionMetricsSnapshot {
  static constexpr std::array<double, 8> kLatencyBucketsS = {0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0};
  locaid::v1::SessionStats stats;
  locaid::v1::SessionState state = locaid::v1::SESSION_STATE_UNSPECIFIED;
  bool has_pose = false;
  fusion::Mode mode = fusion::Mode::kLost;
  double seconds_since_gps = 0, last_gps_nis = 0, gps_gate = 0, position_sigma_h_m = 0;
  int vo_inliers = 0, gps_used = 0, gps_rejected = 0;
  vo::Health vo_health = vo::Health::kLost;
  double speed_scale_error = 0;
  int speed_used = 0;
  locaid::v1::NoiseLearning noise;  // the newest pose's learned noise
  std::array<uint64_t, kLatencyBucketsS.size()> latency_le{};  // cumulative counts per bucket
  uint64_t latency_count = 0;
  double latency_sum_s = 0;
};

class SessionCounters {
 public:
  void Record(const pipeline::StepResult& r, double latency_ms);
  // The frame counters, latency and fps (what the pipeline and hub add is the session's).
  locaid::v1::SessionStats Stats() const;
  // The newest pose's figures and the latency histogram (stats and state unset).
  SessionMetricsSnapshot Metrics() const;

 private:
  mutable std::mutex mu_;
  locaid::v1::SessionStats stats_;
  std::deque<std::chrono::steady_clock::time_point> recent_;  // publish times, last 2 s
  double latency_sum_ms_ = 0;
  SessionMetricsSnapshot last_;
};

// Holds a paced session's poses until their sensor time is due: `rate` x real
// time from the first pose (rate <= 0: not paced). Session thread only.
class Pacer {
 public:
  explicit Pacer(double rate) : rate_(rate) {}
  // When the pose at sensor time t_ns is due; nullopt: now.
  std::optional<std::chrono::steady_clock::time_point> Due(int64_t t_ns);

 private:
  double rate_;
  std::optional<int64_t> t0_ns_;
  std::chrono::steady_clock::time_point w0_;
};

}  // namespace locaid::server
