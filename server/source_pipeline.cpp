#include "server/source_pipeline.hpp"

#include <chrono>
#include <cmath>

namespace locaid::server {
StepResult SourcePipeline::Step() {
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
  switch (item.kind) {
    case SourceItem::Kind::kEnd: r.kind = StepResult::Kind::kEnd; return r;
    case SourceItem::Kind::kIdle: r.kind = StepResult::Kind::kIdle; return r;
    case SourceItem::Kind::kSkipped: r.kind = StepResult::Kind::kSkipped; return r;
    case SourceItem::Kind::kCorrupt: r.kind = StepResult::Kind::kCorrupt; return r;
    case SourceItem::Kind::kFrame: break;
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (!first_t_ns_) {
    first_t_ns_ = item.t_ns;
    for (const auto& [start_s, duration_s] : early_windows_) AddOutageWindow(start_s, duration_s);
    early_windows_.clear();
  }
  last_t_ns_ = item.t_ns;
  vo::StereoFrame frame{item.t_ns, std::move(item.left), std::move(item.right)};
  const Estimate e = estimator_->Process(frame, item.oxts);
  r.kind = StepResult::Kind::kPose;
  r.pose = e.pose;
  r.vo_inliers = e.vo_inliers;
  r.vo_status = e.vo_status;
  r.gps_outage_active = e.in_outage;
  r.processing_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void SourcePipeline::StartOutageNow(double duration_s) {
  if (duration_s > 0 && !first_t_ns_) {
    AddOutageWindow(0, duration_s);  // no frame yet: from the first frame on
  } else if (duration_s > 0) {
    const auto d_ns = static_cast<int64_t>(std::llround(duration_s * 1e9));
    estimator_->ScheduleOutage(last_t_ns_, last_t_ns_ + d_ns);
  } else {
    estimator_->StartOutageNow();
  }
}

void SourcePipeline::AddOutageWindow(double start_s, double duration_s) {
  if (!first_t_ns_) {
    early_windows_.emplace_back(start_s, duration_s);
    return;
  }
  const int64_t start_ns = *first_t_ns_ + static_cast<int64_t>(std::llround(start_s * 1e9));
  estimator_->ScheduleOutage(start_ns, start_ns + static_cast<int64_t>(std::llround(duration_s * 1e9)));
}

}  // namespace locaid::server
