#include "pipeline/frame_loop.hpp"

#include "kitti/oxts_pose.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>

namespace locaid::pipeline {

StepResult FrameLoop::Step() {
  SourceItem item = source_->Next();
  StepResult r;
  r.frame_index = item.index;
  r.t_ns = item.t_ns;
  r.oxts_bad_lines = item.oxts_bad_lines;
  r.error = item.error;
  if (item.kind != SourceItem::Kind::kFrame) {
    carried_oxts_.insert(carried_oxts_.end(), item.oxts.begin(), item.oxts.end());
  } else if (!carried_oxts_.empty()) {
    item.oxts.insert(item.oxts.begin(), carried_oxts_.begin(), carried_oxts_.end());
    carried_oxts_.clear();
  }
  const bool typed = !item.imu.empty() || !item.gps.empty() || item.receiver_has_fix.has_value();
  // Typed data first: a fix reaches the filter before VO runs on the frame.
  if (typed) FuseTyped(item);
  switch (item.kind) {
    case SourceItem::Kind::kSensors: r.kind = StepResult::Kind::kFused; return r;
    case SourceItem::Kind::kEnd: r.kind = StepResult::Kind::kEnd; return r;
    case SourceItem::Kind::kIdle: r.kind = StepResult::Kind::kIdle; return r;
    case SourceItem::Kind::kSkipped: r.kind = StepResult::Kind::kSkipped; return r;
    case SourceItem::Kind::kCorrupt: r.kind = StepResult::Kind::kCorrupt; return r;
    case SourceItem::Kind::kFrame: break;
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (!first_t_ns_) {
    first_t_ns_ = item.t_ns;
    if (r.error.empty()) r.error = std::move(notice_);
    for (const auto& [start_s, duration_s] : early_windows_) AddOutageWindow(start_s, duration_s);
    early_windows_.clear();
  }
  last_t_ns_ = item.t_ns;
  vo::StereoFrame frame{item.t_ns, std::move(item.left), std::move(item.right)};
  r.kind = StepResult::Kind::kPose;
  r.frame = estimator_->Process(frame, item.oxts);
  r.frame.gps_feeds.insert(r.frame.gps_feeds.begin(), std::make_move_iterator(typed_feeds_.begin()),
                           std::make_move_iterator(typed_feeds_.end()));
  typed_feeds_.clear();
  if (item.truth) r.truth = Truth(*item.truth);
  r.processing_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void FrameLoop::FuseTyped(const SourceItem& item) {
  SensorBatch batch;
  batch.imu = item.imu;
  batch.gps.reserve(item.gps.size());
  for (const ArrivedFix& f : item.gps) batch.gps.push_back(f.fix);
  batch.receiver_has_fix = item.receiver_has_fix;
  for (GpsFeed& f : estimator_->FuseSensors(batch).gps_feeds) typed_feeds_.push_back(std::move(f));
  const auto now = std::chrono::steady_clock::now().time_since_epoch();
  const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  std::lock_guard lock(latency_mu_);
  for (const ArrivedFix& f : item.gps) {
    if (f.arrival_steady_ns == 0) continue;
    fix_latency_ms_.push_back(static_cast<double>(now_ns - f.arrival_steady_ns) / 1e6);
    if (fix_latency_ms_.size() > kLatencyWindow) fix_latency_ms_.pop_front();
  }
}

TruthPose FrameLoop::Truth(const kitti::OxtsRecord& oxts) const {
  TruthPose t{oxts.lat_deg, oxts.lon_deg, oxts.alt_m, std::nullopt};
  const fusion::EnuFrame& enu = estimator_->enu();
  if (enu.has_origin()) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = kitti::OxtsAttitude(oxts.roll_rad, oxts.pitch_rad, oxts.yaw_rad);
    T.translation() = enu.ToEnu(oxts.lat_deg, oxts.lon_deg, oxts.alt_m);
    t.T_enu_body = T;
  }
  return t;
}

bool FrameLoop::origin(double* lat_deg, double* lon_deg, double* alt_m) const {
  const fusion::EnuFrame& enu = estimator_->enu();
  if (!enu.has_origin()) return false;
  *lat_deg = enu.origin_lat_deg();
  *lon_deg = enu.origin_lon_deg();
  *alt_m = enu.origin_alt_m();
  return true;
}

LiveInputStats FrameLoop::input_stats() const {
  LiveInputStats stats = source_->input_stats();
  std::vector<double> ms;
  {
    std::lock_guard lock(latency_mu_);
    ms.assign(fix_latency_ms_.begin(), fix_latency_ms_.end());
  }
  if (!ms.empty()) {
    std::sort(ms.begin(), ms.end());
    stats.fix_latency_median_ms = ms[ms.size() / 2];
    stats.fix_latency_max_ms = ms.back();
  }
  return stats;
}

void FrameLoop::StartOutageNow(double duration_s) {
  if (duration_s > 0 && !first_t_ns_) {
    AddOutageWindow(0, duration_s);  // no frame yet: from the first frame on
  } else if (duration_s > 0) {
    const auto d_ns = static_cast<int64_t>(std::llround(duration_s * 1e9));
    estimator_->ScheduleOutage(last_t_ns_, last_t_ns_ + d_ns);
  } else {
    estimator_->StartOutageNow();
  }
}

void FrameLoop::AddOutageWindow(double start_s, double duration_s) {
  if (!first_t_ns_) {
    early_windows_.emplace_back(start_s, duration_s);
    return;
  }
  const int64_t start_ns = *first_t_ns_ + static_cast<int64_t>(std::llround(start_s * 1e9));
  estimator_->ScheduleOutage(start_ns, start_ns + static_cast<int64_t>(std::llround(duration_s * 1e9)));
}

}  // namespace locaid::pipeline
