#include "pipeline/scenario_stage.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace locaid::pipeline {
namespace {

int64_t Nanoseconds(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

}  // namespace

ScenarioStage::ScenarioStage(sim::Scenario scenario) : scenario_(std::move(scenario)) {
  sim::ValidateScenario(scenario_);
  RebuildDegradation(std::nullopt);
}

void ScenarioStage::RebuildDegradation(std::optional<int64_t> drive_start_ns) {
  gps_ = std::make_unique<sim::GpsReceiverSim>(scenario_);
  imu_ = std::make_unique<sim::ImuDegrader>(scenario_);
  speed_ = std::make_unique<sim::SpeedSimulator>(scenario_);
  // Keep the drive clock: the scenario's outages stay relative to the drive start.
  if (drive_start_ns) gps_->SetDriveStart(*drive_start_ns);
  for (const auto& [a, b] : runtime_outages_) gps_->ScheduleOutage(a, b);
  gps_->SetForcedOutage(forced_);
}

void ScenarioStage::BeginFrame(int64_t t_ns, const SampleBatch& its_samples) {
  // Without truth samples the scenario's drive clock starts at the first frame.
  if (!gps_->drive_start_ns() && its_samples.truth_poses.empty()) gps_->SetDriveStart(t_ns);
  last_frame_ns_ = t_ns;
  if (first_frame_ns_) return;
  first_frame_ns_ = t_ns;
  for (const auto& [start_s, duration_s] : std::exchange(early_windows_, {})) AddOutageWindow(start_s, duration_s);
}

Measurements ScenarioStage::Apply(const SampleBatch& batch) {
  if (batch.receiver_has_fix) receiver_has_fix_ = *batch.receiver_has_fix;
  Measurements out;
  out.imu.reserve(batch.imu.size() + batch.truth_imu.size());
  // One time line: each truth IMU sample before the fix of its time.
  size_t next_imu = 0;
  for (const fusion::TruthSample& p : batch.truth_poses) {
    for (; next_imu < batch.truth_imu.size() && batch.truth_imu[next_imu].t_ns <= p.t_ns; ++next_imu)
      out.imu.push_back(imu_->Apply(batch.truth_imu[next_imu]));
    if (auto fix = gps_->Apply(p.t_ns, p.lat_deg, p.lon_deg, p.alt_m, &p.R_enu_body)) out.gps.push_back(*fix);
    if (p.v_body_mps)
      for (const fusion::SpeedSample& v : speed_->Apply(p.t_ns, p.v_body_mps->x())) out.speed.push_back(v);
  }
  for (; next_imu < batch.truth_imu.size(); ++next_imu) out.imu.push_back(imu_->Apply(batch.truth_imu[next_imu]));
  // Measured data: IMU as it is, fixes unless GPS is out at their time.
  out.imu.insert(out.imu.end(), batch.imu.begin(), batch.imu.end());
  for (const ArrivedFix& f : batch.gps) {
    if (gps_->InOutage(f.fix.t_ns)) continue;
    if (!gps_->scenario().degrade_measured_gps) {
      out.gps.push_back(f.fix);
      continue;
    }
    // The scenario's receiver on top of the recorded fix: its noise adds to
    // the recorded uncertainty.
    auto fix = gps_->Apply(f.fix.t_ns, f.fix.lat_deg, f.fix.lon_deg, f.fix.alt_m);
    if (!fix) continue;  // decimated to the scenario's rate
    fix->sigma_h_m = std::hypot(f.fix.horizontal_sigma_m(), fix->sigma_h_m);
    fix->sigma_v_m = std::hypot(f.fix.vertical_sigma_m(), fix->sigma_v_m);
    fix->has_altitude = f.fix.has_altitude;
    out.gps.push_back(*fix);
  }
  out.speed.insert(out.speed.end(), batch.speed.begin(), batch.speed.end());
  auto by_time = [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; };
  std::stable_sort(out.imu.begin(), out.imu.end(), by_time);
  std::stable_sort(out.gps.begin(), out.gps.end(), by_time);
  std::stable_sort(out.speed.begin(), out.speed.end(), by_time);
  return out;
}

bool ScenarioStage::InOutage(int64_t t_ns) const { return gps_->InOutage(t_ns) || !receiver_has_fix_; }

void ScenarioStage::ScheduleAbsolute(int64_t start_ns, int64_t end_ns) {
  if (end_ns <= start_ns)
    throw std::invalid_argument("outage: end (" + std::to_string(end_ns) + " ns) must be after its start (" +
                                std::to_string(start_ns) + " ns)");
  gps_->ScheduleOutage(start_ns, end_ns);
  runtime_outages_.emplace_back(start_ns, end_ns);
}

void ScenarioStage::StartOutageNow(double duration_s) {
  if (duration_s > 0 && !first_frame_ns_) {
    AddOutageWindow(0, duration_s);  // no frame yet: from the first frame on
  } else if (duration_s > 0) {
    ScheduleAbsolute(last_frame_ns_, last_frame_ns_ + Nanoseconds(duration_s));
  } else {
    forced_ = true;
    gps_->SetForcedOutage(true);
  }
}

void ScenarioStage::StopOutage() {
  forced_ = false;
  gps_->SetForcedOutage(false);
}

void ScenarioStage::AddOutageWindow(double start_s, double duration_s) {
  if (!first_frame_ns_) {
    early_windows_.emplace_back(start_s, duration_s);
    return;
  }
  const int64_t start_ns = *first_frame_ns_ + Nanoseconds(start_s);
  ScheduleAbsolute(start_ns, start_ns + Nanoseconds(duration_s));
}

void ScenarioStage::SetScenario(sim::Scenario scenario) {
  sim::ValidateScenario(scenario);
  scenario_ = std::move(scenario);
  RebuildDegradation(gps_->drive_start_ns());
}

}  // namespace locaid::pipeline
