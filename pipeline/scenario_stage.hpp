// The scenario stage: between a source and the estimator, samples in, typed
// measurements out. It owns everything about GPS availability: the
// scenario's degradation of a reference unit's truth (receiver fixes made
// from the truth poses, the IMU degraded to the scenario's grade, a simulated
// speed sensor reading the true forward speed when the scenario has one), the scenario's
// and run-time outage windows, a forced outage, and the receiver's own no-fix
// state. Measured IMU samples pass unchanged; measured fixes pass unless GPS
// is in an outage.
//
// Threading: one thread (the session's or the replay's stepping thread);
// a session posts its outage controls there.
#pragma once

#include "sim/scenario.hpp"
#include "pipeline/samples.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

namespace locaid::pipeline {

class ScenarioStage {
 public:
  // Throws std::invalid_argument when the scenario is invalid.
  explicit ScenarioStage(sim::Scenario scenario);

  // A frame at t_ns comes next: the first one starts the clock of run-time
  // windows (and the scenario's, unless a truth sample came first).
  void BeginFrame(int64_t t_ns, const SampleBatch& its_samples);
  // Everything a source delivered with one item, in its order.
  Measurements Apply(const SampleBatch& batch);
  // Whether GPS is out at t_ns: a scheduled, run-time or forced outage, or
  // the receiver's last report was "no fix".
  bool InOutage(int64_t t_ns) const;

  // Run-time controls; times relative to the first frame.
  void StartOutageNow(double duration_s);  // 0 = until StopOutage
  void StopOutage();
  void AddOutageWindow(double start_s, double duration_s);
  // Replaces the degradation (new seed / noise / outages on the same drive
  // clock); run-time outages stay. Throws std::invalid_argument if invalid.
  void SetScenario(sim::Scenario scenario);
  const sim::Scenario& scenario() const { return scenario_; }

 private:
  void ScheduleAbsolute(int64_t start_ns, int64_t end_ns);
  void RebuildDegradation(std::optional<int64_t> drive_start_ns);

  sim::Scenario scenario_;
  std::unique_ptr<sim::GpsReceiverSim> gps_;
  std::unique_ptr<sim::ImuDegrader> imu_;
  std::unique_ptr<sim::SpeedSimulator> speed_;
  std::optional<int64_t> first_frame_ns_;
  int64_t last_frame_ns_ = 0;
  std::vector<std::pair<double, double>> early_windows_;      // asked for before the first frame
  std::vector<std::pair<int64_t, int64_t>> runtime_outages_;  // absolute, kept across SetScenario
  bool forced_ = false;
  bool receiver_has_fix_ = true;
};

}  // namespace locaid::pipeline
