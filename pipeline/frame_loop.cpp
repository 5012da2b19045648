#include "pipeline/frame_loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

namespace locaid::pipeline {

StepResult FrameLoop::Step() {
  SourceItem item = source_->Next();
  const auto t0 = std::chrono::steady_clock::now();
  StepResult r;
  r.frame_index = item.index;
  r.t_ns = item.t_ns;
  r.oxts_bad_lines = item.oxts_bad_lines;
  r.error = item.error;
  if (item.kind == SourceItem::Kind::kFrame) scenario_.BeginFrame(item.t_ns, item.samples);
  if (!item.samples.empty()) {
    estimator_->Fuse(scenario_.Apply(item.samples));
    RecordFixLatency(item.samples);
  }
  switch (item.kind) {
    case SourceItem::Kind::kSamples: r.kind = StepResult::Kind::kFused; return r;
    case SourceItem::Kind::kEnd: r.kind = StepResult::Kind::kEnd; return r;
    case SourceItem::Kind::kIdle: r.kind = StepResult::Kind::kIdle; return r;
    case SourceItem::Kind::kSkipped: r.kind = StepResult::Kind::kSkipped; return r;
    case SourceItem::Kind::kCorrupt: r.kind = StepResult::Kind::kCorrupt; return r;
    case SourceItem::Kind::kFrame: break;
  }
  if (!std::exchange(had_frame_, true) && r.error.empty()) r.error = std::move(notice_);
  r.kind = StepResult::Kind::kPose;
  vo::StereoFrame frame{item.t_ns, std::move(item.left), std::move(item.right), item.no_images};
  if (!frame.no_images) camera_faults_.Apply(frame);  // nothing to degrade while the cameras are down
  r.frame = estimator_->Process(frame);
  r.frame.in_outage = scenario_.InOutage(item.t_ns);
  if (item.truth) r.truth = Truth(*item.truth);
  r.processing_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void FrameLoop::SetScenario(const sim::Scenario& scenario) {
  sim::ValidateScenario(scenario);
  scenario_.SetScenario(scenario);
  camera_faults_.SetScenario(scenario);
}

void FrameLoop::RecordFixLatency(const SampleBatch& samples) {
  const auto now = std::chrono::steady_clock::now().time_since_epoch();
  const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  std::lock_guard lock(latency_mu_);
  for (const ArrivedFix& f : samples.gps) {
    if (f.arrival_steady_ns == 0) continue;
    fix_latency_ms_.push_back(static_cast<double>(now_ns - f.arrival_steady_ns) / 1e6);
    if (fix_latency_ms_.size() > kLatencyWindow) fix_latency_ms_.pop_front();
  }
}

TruthPose FrameLoop::Truth(const fusion::TruthSample& ref) const {
  TruthPose t{ref.lat_deg, ref.lon_deg, ref.alt_m, std::nullopt};
  const fusion::EnuFrame& enu = estimator_->enu();
  if (enu.has_origin()) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = ref.R_enu_body;
    T.translation() = enu.ToEnu(ref.lat_deg, ref.lon_deg, ref.alt_m);
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

}  // namespace locaid::pipeline
