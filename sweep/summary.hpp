// The tables of a sweep: one row per filter run (results.csv), and per
// recording x scenario x imu the distribution of the end-of-outage error,
// the error inside the outage, RMSE, the share of runs whose NEES is over
// its 99 % bound, resets, GPS rejections and failures (summary.csv,
// summary.json); in a smoothed sweep (smooth: true) the same errors of the
// smoothed trajectory next to the forward filter's. Besides, per group:
// every outage's end error, the error it added and the reconvergence after
// it; each run's NEES against its bound; the vertical error; the GPS gates'
// rejections against their nominal rate, the longest run of them and the
// resets; the VO updates the filter's gate refused; poses per mode and per
// VO health; the speed sensor's scale error. report.md links them and the
// plots and tabulates the figures.
#pragma once

#include "sweep/plan.hpp"
#include "sweep/result_store.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace locaid::sweep {

// What results.csv and the summary read of one locaid-replay --json metrics
// object: the top level (the forward filter) or its "smoothed" object
// (--smooth), which has the same keys. Missing and non-finite values
// (NaN is written as null) are none.
struct RunMetrics {
  // The first outage's: end error (% of the distance driven in it, and m),
  // max horizontal error and horizontal RMSE over its frames; none without one.
  std::optional<double> end_error_pct, end_error_m, max_error_m, outage_rmse_m;
  std::optional<double> rmse_gps_m, nees_mean, nees_bound_99;
};
RunMetrics ReadRunMetrics(const nlohmann::json& metrics);

// The rest of a done run's locaid-replay --json that a group's figures
// need: every outage, the vertical error, the gates, the modes and what VO
// saw, the speed sensor's scale error. Missing and non-finite values are
// left out.
struct RunFigures {
  // Every outage's end error (% of the distance driven in it), the error it
  // added to the one it started with (%), the time to get back within 2
  // sigma_h of the truth after it (< 0: not before the drive ended).
  std::vector<double> end_error_pct, added_error_pct, reconverge_s;
  std::optional<double> max_vertical_error_m;
  std::optional<double> speed_scale_error;  // only when the run fused a speed reading
  std::map<std::string, int64_t> modes, vo_health;  // poses per mode, per VO health
  int64_t gps_used = 0, gps_rejected_vertical = 0, vo_rejected_by_gate = 0;
  int64_t longest_rejection_run = 0;  // consecutive refusals of either GPS gate
};
RunFigures ReadRunFigures(const nlohmann::json& metrics);

// The probability of each GPS gate (horizontal, vertical) of a run with
// these locaid-replay arguments: fusion::EkfConfig's, or what an
// `--ekf gps.gate_probability=P` among them sets.
double GpsGateProbability(const std::vector<std::string>& replay_args);

struct ResultRow {
  std::string id, recording, scenario;
  int64_t seed = 0;
  bool imu = true;
  RunState state = RunState::kPending;
  RunMetrics forward;
  std::optional<RunMetrics> smoothed;  // a done run of a smoothed sweep (smooth: true)
  std::optional<int64_t> gps_rejected, gps_resets, frames;
  std::optional<double> cpu_s;
  std::string error;  // a failed run's
  RunFigures figures;                // a done run's
  double gps_gate_probability = 0;  // GpsGateProbability of its arguments
};

// The state of every task of the plan in DIR (VO and filter).
std::vector<RunState> TaskStates(const Plan& plan, Stage stage);
// One row per filter task, in plan order.
std::vector<ResultRow> CollectRows(const Plan& plan);

struct Distribution {
  size_t n = 0;
  double median = 0, p90 = 0, max = 0;
};
// Linear interpolation between order statistics (numpy's default); n = 0: all 0.
Distribution Distribute(std::vector<double> values);

// The distributions of RunMetrics over a group's done runs.
struct MetricDistributions {
  Distribution end_error_pct, end_error_m, max_error_m, outage_rmse_m, rmse_gps_m;
};

struct GroupSummary {
  std::string recording, scenario;
  bool imu = true;
  size_t runs = 0, done = 0, failed = 0, pending = 0;
  MetricDistributions forward, smoothed;  // smoothed: n = 0 unless the sweep smooths
  double nees_over_bound_share = 0;  // of the done runs (forward filter)
  int64_t gps_resets = 0, gps_rejected = 0;  // summed over the done runs
  // Over every outage of the done runs (`forward` has the first outage's):
  // end error, added error, reconvergence; outages never back within 2
  // sigma_h before the drive ended are counted apart.
  Distribution end_error_pct_every, added_error_pct, reconverge_s;
  size_t reconverge_never = 0;
  Distribution nees_mean_over_bound;            // each run's NEES mean / its 99 % bound
  std::vector<int64_t> nees_over_bound_seeds;  // the runs above it
  Distribution max_vertical_error_m, speed_scale_error;
  std::map<std::string, int64_t> modes, vo_health;  // poses, summed
  // GPS fixes fused or refused, refusals of the vertical gate (gps_rejected:
  // of the horizontal one), what each gate refuses at its nominal rate
  // (fixes x (1 - the gate probability), per run), the longest run of
  // refusals of either gate.
  int64_t gps_fixes = 0, gps_rejected_vertical = 0, gps_longest_rejection_run = 0;
  double gps_expected_false_alarms = 0;
  double vo_rejected_per_run = 0;  // VO updates the filter's gate refused, per done run
};
std::vector<GroupSummary> Summarize(const std::vector<ResultRow>& rows);

// `smoothed` (the plan's smooth): the *_smoothed columns (results.csv,
// summary.csv) and the "smoothed" objects (summary.json) are there only then.
void WriteResultsCsv(const std::vector<ResultRow>& rows, bool smoothed, const std::filesystem::path& file);
void WriteSummaryCsv(const std::vector<GroupSummary>& groups, bool smoothed, const std::filesystem::path& file);
void WriteSummaryJson(const std::vector<GroupSummary>& groups, bool smoothed, const std::filesystem::path& file);
// `plots`: the PNG files written next to it (may be empty, with `plot_note` saying why).
// A smoothed plan adds a table of forward | smoothed per group.
void WriteReportMd(const Plan& plan, const std::vector<ResultRow>& rows, const std::vector<GroupSummary>& groups,
                   const std::vector<std::string>& plots, const std::string& plot_note,
                   const std::filesystem::path& file);

}  // namespace locaid::sweep
