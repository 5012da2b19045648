// The tables of a sweep: one row per filter run (results.csv), and per
// recording x scenario x imu the distribution of the end-of-outage error,
// the error inside the outage, RMSE, the share of runs whose NEES is over
// its 99 % bound, resets, GPS rejections and failures (summary.csv,
// summary.json); in a smoothed sweep (smooth: true) the same errors of the
// smoothed trajectory next to the forward filter's. report.md links them
// and the plots.
#pragma once

#include "sweep/plan.hpp"
#include "sweep/result_store.hpp"

#include <filesystem>
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
