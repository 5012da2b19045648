// The tables of a sweep: one row per filter run (results.csv), and per
// recording x scenario x imu the distribution of the end-of-outage error,
// RMSE, the share of runs whose NEES is over its 99 % bound, resets, GPS
// rejections and failures (summary.csv, summary.json); report.md links them
// and the plots.
#pragma once

#include "sweep/plan.hpp"
#include "sweep/result_store.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace locaid::sweep {

struct ResultRow {
  std::string id, recording, scenario;
  int64_t seed = 0;
  bool imu = true;
  RunState state = RunState::kPending;
  std::optional<double> end_error_pct, end_error_m;  // the first outage's; none without one
  std::optional<double> rmse_gps_m, nees_mean, nees_bound_99;
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

struct GroupSummary {
  std::string recording, scenario;
  bool imu = true;
  size_t runs = 0, done = 0, failed = 0, pending = 0;
  Distribution end_error_pct, end_error_m, rmse_gps_m;
  double nees_over_bound_share = 0;  // of the done runs
  int64_t gps_resets = 0, gps_rejected = 0;  // summed over the done runs
};
std::vector<GroupSummary> Summarize(const std::vector<ResultRow>& rows);

void WriteResultsCsv(const std::vector<ResultRow>& rows, const std::filesystem::path& file);
void WriteSummaryCsv(const std::vector<GroupSummary>& groups, const std::filesystem::path& file);
void WriteSummaryJson(const std::vector<GroupSummary>& groups, const std::filesystem::path& file);
// `plots`: the PNG files written next to it (may be empty, with `plot_note` saying why).
void WriteReportMd(const Plan& plan, const std::vector<ResultRow>& rows, const std::vector<GroupSummary>& groups,
                   const std::vector<std::string>& plots, const std::string& plot_note,
                   const std::filesystem::path& file);

}  // namespace locaid::sweep
