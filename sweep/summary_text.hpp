// What the sweep's tables are written with (summary.csv/json, results.csv,
// report.md): the errors tabulated per run and per group, and numbers as
// text. Internal to sweep/ (summary.cpp, report_md.cpp).
#pragma once

#include "sweep/summary.hpp"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>

namespace locaid::sweep::summary_text {

// The errors a sweep tabulates for the forward filter and, smoothing, for the
// smoothed trajectory: one name for the run's value and its distribution.
struct MetricField {
  const char* name;
  std::optional<double> RunMetrics::*value;
  Distribution MetricDistributions::*distribution;
};
inline constexpr MetricField kEndErrorPct{"end_error_pct", &RunMetrics::end_error_pct, &MetricDistributions::end_error_pct};
inline constexpr MetricField kEndErrorM{"end_error_m", &RunMetrics::end_error_m, &MetricDistributions::end_error_m};
inline constexpr MetricField kMaxErrorM{"max_error_m", &RunMetrics::max_error_m, &MetricDistributions::max_error_m};
inline constexpr MetricField kOutageRmseM{"outage_rmse_m", &RunMetrics::outage_rmse_m, &MetricDistributions::outage_rmse_m};
inline constexpr MetricField kRmseGpsM{"rmse_gps_m", &RunMetrics::rmse_gps_m, &MetricDistributions::rmse_gps_m};
inline constexpr MetricField kMetricFields[] = {kEndErrorPct, kEndErrorM, kMaxErrorM, kOutageRmseM, kRmseGpsM};
// The columns results.csv and summary.csv added after their first ones.
inline constexpr MetricField kForwardAdded[] = {kMaxErrorM, kOutageRmseM};

// Shortest text that reads back as the same double ("" for none).
std::string Fmt(std::optional<double> v);
// A CSV field, quoted where it must be.
std::string Csv(const std::string& s);
// A file to write; throws std::runtime_error naming it.
std::ofstream Open(const std::filesystem::path& file);
// "name n, name n" ("-" for none).
std::string CountsText(const std::map<std::string, int64_t>& counts);
// "median,p90,max" (",," without values) and its header "NAME_median,...".
std::string CsvTriple(const Distribution& d);
std::string TripleHeader(const std::string& name);
double Round(double v, int digits);
// "median / p90 / max" rounded, "-" without values.
std::string MdTriple(const Distribution& d, int digits);

}  // namespace locaid::sweep::summary_text
