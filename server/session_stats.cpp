#include "server/session_stats.hpp"

#include "output/pose_message.hpp"

#include <algorithm>
#include <cmath>

namespace locaid::server {
namespace {

using Clock = std::chrono::steady_clock;
using Kind = pipeline::StepResult::Kind;

}  // namespace

void SessionCounters::Record(const pipeline::StepResult& r, double latency_ms) {
  std::lock_guard lock(mu_);
  if (r.kind != Kind::kIdle && r.kind != Kind::kEnd && r.kind != Kind::kFused) {
    stats_.set_frames_in(stats_.frames_in() + 1);
  }
  stats_.set_oxts_bad_lines(stats_.oxts_bad_lines() + static_cast<uint64_t>(std::max(0, r.oxts_bad_lines)));
  if (!r.error.empty()) stats_.set_last_input_error(r.error);
  if (r.kind == Kind::kSkipped) stats_.set_frames_skipped(stats_.frames_skipped() + 1);
  if (r.kind == Kind::kCorrupt) stats_.set_frames_corrupt(stats_.frames_corrupt() + 1);
  if (r.kind != Kind::kPose) return;
  stats_.set_frames_processed(stats_.frames_processed() + 1);
  latency_sum_ms_ += latency_ms;
  stats_.set_latency_mean_ms(latency_sum_ms_ / static_cast<double>(stats_.frames_processed()));
  stats_.set_latency_max_ms(std::max(stats_.latency_max_ms(), latency_ms));
  const auto now = Clock::now();
  recent_.push_back(now);
  while (!recent_.empty() && now - recent_.front() > std::chrono::seconds(2)) recent_.pop_front();
  const fusion::FusedPose& p = r.frame.pose;
  last_.has_pose = true;
  last_.mode = p.mode;
  last_.seconds_since_gps = p.seconds_since_gps;
  last_.last_gps_nis = p.last_gps_nis;
  last_.gps_gate = p.gps_gate;
  last_.position_sigma_h_m = std::sqrt(std::max(0.0, p.covariance(0, 0) + p.covariance(1, 1)));
  last_.vo_inliers = r.frame.vo.inliers;
  last_.vo_health = r.frame.vo.health;
  last_.speed_scale_error = r.frame.pose.speed_scale_error;
  last_.speed_used = r.frame.pose.speed_used;
  output::FillNoiseLearning(p, &last_.noise);
  *stats_.mutable_noise() = last_.noise;
  last_.gps_used = p.gps_used;
  last_.gps_rejected = p.gps_rejected;
  const double latency_s = latency_ms / 1000.0;
  for (size_t b = 0; b < SessionMetricsSnapshot::kLatencyBucketsS.size(); ++b)
    last_.latency_le[b] += latency_s <= SessionMetricsSnapshot::kLatencyBucketsS[b] ? 1 : 0;
  ++last_.latency_count;
  last_.latency_sum_s += latency_s;
}

locaid::v1::SessionStats SessionCounters::Stats() const {
  std::lock_guard lock(mu_);
  locaid::v1::SessionStats s = stats_;
  const auto now = Clock::now();
  size_t n = 0;
  for (const auto& t : recent_) n += (now - t <= std::chrono::seconds(2)) ? 1 : 0;
  if (n >= 2) {
    const double span_s = std::chrono::duration<double>(recent_.back() - recent_[recent_.size() - n]).count();
    s.set_fps(span_s > 0 ? static_cast<double>(n - 1) / span_s : 0.0);
  }
  return s;
}

SessionMetricsSnapshot SessionCounters::Metrics() const {
  std::lock_guard lock(mu_);
  return last_;
}

std::optional<Clock::time_point> Pacer::Due(int64_t t_ns) {
  if (rate_ <= 0) return std::nullopt;
  if (!t0_ns_) {
    t0_ns_ = t_ns;
    w0_ = Clock::now();
    return std::nullopt;
  }
  const double dt_s = static_cast<double>(t_ns - *t0_ns_) * 1e-9 / rate_;
  return w0_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(std::max(0.0, dt_s)));
}

}  // namespace locaid::server
