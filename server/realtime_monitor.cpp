#include "server/realtime_monitor.hpp"

#include <algorithm>
#include <ctime>

namespace locaid::server {
namespace {

constexpr auto kRateWindow = std::chrono::seconds(2);
constexpr auto kCpuWindow = std::chrono::seconds(5);
constexpr auto kMinSampleGap = std::chrono::milliseconds(50);

double Seconds(RealTimeMonitor::Clock::duration d) { return std::chrono::duration<double>(d).count(); }

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

}  // namespace

double RealTimeMonitor::NotePose(int64_t t_ns, std::optional<Clock::time_point> due, Clock::time_point now) {
  std::lock_guard lock(mu_);
  const double behind = due ? std::max(0.0, Seconds(now - *due)) : 0.0;
  if (rate_ > 0 && due && last_t_ns_ && t_ns > *last_t_ns_) {
    // The next pose is due one frame period after this one's due time.
    const double period_s = static_cast<double>(t_ns - *last_t_ns_) * 1e-9 / rate_;
    next_due_ = *due + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s));
  }
  last_t_ns_ = t_ns;
  last_behind_s_ = behind;
  max_behind_s_ = std::max(max_behind_s_, behind);
  if (poses_.empty() || now - poses_.back().first >= kMinSampleGap) poses_.emplace_back(now, t_ns);
  while (poses_.size() > 1 && now - poses_.front().first > kRateWindow) poses_.pop_front();
  return behind;
}

void RealTimeMonitor::NoteCpu(Clock::time_point now, double other_cpu_s) {
  std::lock_guard lock(mu_);
  if (!cpu_.empty() && now - cpu_.back().first < kMinSampleGap) return;
  cpu_.emplace_back(now, ThreadCpuSeconds() + other_cpu_s);
  while (cpu_.size() > 1 && now - cpu_.front().first > kCpuWindow) cpu_.pop_front();
}

void RealTimeMonitor::NoteWaiting(Clock::time_point due) {
  std::lock_guard lock(mu_);
  next_due_ = due;
}

void RealTimeMonitor::NoteEnded() {
  std::lock_guard lock(mu_);
  ended_ = true;
}

double RealTimeMonitor::BehindLocked(Clock::time_point now) const {
  double behind = last_behind_s_;
  if (!ended_ && next_due_ && now > *next_due_) behind = std::max(behind, Seconds(now - *next_due_));
  return behind;
}

double RealTimeMonitor::BehindNow(Clock::time_point now) const {
  std::lock_guard lock(mu_);
  return BehindLocked(now);
}

double RealTimeMonitor::CpuCores(Clock::time_point now) const {
  std::lock_guard lock(mu_);
  if (cpu_.size() < 2 || ended_) return 0;
  const double wall = Seconds(now - cpu_.front().first);
  return wall > 0 ? (cpu_.back().second - cpu_.front().second) / wall : 0;
}

void RealTimeMonitor::Fill(locaid::v1::SessionStats* stats, Clock::time_point now) const {
  const double cores = CpuCores(now);
  std::lock_guard lock(mu_);
  const double behind = BehindLocked(now);
  stats->set_behind_real_time_s(behind);
  stats->set_behind_real_time_max_s(std::max(max_behind_s_, behind));
  stats->set_falling_behind(behind > threshold_s_);
  stats->set_cpu_cores(cores);
  if (poses_.size() >= 2) {
    // Up to now, not to the newest pose: a stalled session's factor falls.
    const double wall = Seconds((ended_ ? poses_.back().first : now) - poses_.front().first);
    const double sensor = static_cast<double>(poses_.back().second - poses_.front().second) * 1e-9;
    stats->set_realtime_factor(wall > 0 ? sensor / wall : 0);
  }
}

}  // namespace locaid::server
