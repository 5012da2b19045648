// report.md of a sweep: the links, the plots, the tables of summary.cpp's
// groups, the forward against the smoothed errors, the failed runs.
#include "sweep/summary.hpp"
#include "sweep/summary_text.hpp"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;

namespace locaid::sweep {

using namespace summary_text;

void WriteReportMd(const Plan& plan, const std::vector<ResultRow>& rows, const std::vector<GroupSummary>& groups,
                   const std::vector<std::string>& plots, const std::string& plot_note, const fs::path& file) {
  size_t done = 0, failed = 0;
  for (const auto& r : rows) {
    done += r.state == RunState::kDone;
    failed += r.state == RunState::kFailed;
  }
  auto out = Open(file);
  out << "# Sweep report\n\n"
      << "Manifest `" << plan.manifest << "`, locaid " << plan.locaid_version << ": " << plan.recordings.size()
      << " recordings, " << rows.size() << " filter runs: " << done << " done, " << failed << " failed, "
      << rows.size() - done - failed << " pending.\n\n"
      << "- [results.csv](results.csv): one row per run (end_error_pct: the first outage's, % of the distance "
         "driven in it; empty without an outage"
      << (plan.smooth ? "; *_smoothed: the same of the smoothed trajectory" : "") << ")\n"
      << "- [summary.csv](summary.csv), [summary.json](summary.json): per recording x scenario x IMU\n\n";
  if (!plots.empty()) {
    out << "## End-of-outage error\n\n";
    for (const auto& p : plots) out << "![" << p << "](" << p << ")\n\n";
  } else {
    out << "No plots: " << plot_note << "\n\n";
  }
  out << "## Summary\n\n"
      << "| recording | scenario | IMU | done / runs | failed | end error % median / p90 / max | RMSE m median | "
         "NEES > 99 % bound |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& g : groups) {
    const auto& d = g.forward;
    out << "| " << fs::path(g.recording).filename().string() << " | " << g.scenario << " | "
        << (g.imu ? "on" : "off") << " | " << g.done << " / " << g.runs << " | " << g.failed << " | "
        << MdTriple(d.end_error_pct, 2) << " | "
        << (d.rmse_gps_m.n ? Fmt(Round(d.rmse_gps_m.median, 3)) : std::string("-")) << " | "
        << Fmt(Round(g.nees_over_bound_share * 100, 1)) << " % |\n";
  }
  out << "\n## Every outage, consistency and the gates\n\n"
      << "Median / p90 / max over the done runs. End and added error: every outage (% of the distance driven in "
         "it; added: beyond the error it started with); reconvergence: from an outage's end to the first pose "
         "within 2 sigma_h of the truth (never: not before the drive ended); NEES: each run's mean over its 99 % "
         "bound; GPS: fixes refused by the horizontal / vertical gate against what each refuses at its nominal "
         "rate, the longest run of refusals, position resets; VO gated: VO updates the filter's gate refused, "
         "per run.\n\n"
      << "| recording | scenario | IMU | end error % | added error % | reconverge s (never) | NEES / bound "
         "(runs over) | max vertical error m | GPS rejected H / V of fixes (nominal each) | longest run | resets | "
         "VO gated |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& g : groups) {
    out << "| " << fs::path(g.recording).filename().string() << " | " << g.scenario << " | "
        << (g.imu ? "on" : "off") << " | " << MdTriple(g.end_error_pct_every, 2) << " | "
        << MdTriple(g.added_error_pct, 2) << " | " << MdTriple(g.reconverge_s, 2) << " ("
        << g.reconverge_never << ") | " << MdTriple(g.nees_mean_over_bound, 2) << " ("
        << g.nees_over_bound_seeds.size() << ") | " << MdTriple(g.max_vertical_error_m, 2) << " | "
        << g.gps_rejected << " / " << g.gps_rejected_vertical << " of " << g.gps_fixes << " ("
        << Fmt(Round(g.gps_expected_false_alarms, 1)) << ") | " << g.gps_longest_rejection_run << " | "
        << g.gps_resets << " | " << Fmt(Round(g.vo_rejected_per_run, 1)) << " |\n";
  }
  out << "\nPoses per mode and per VO health, summed over the done runs; the speed sensor's scale error "
         "(median / p90 / max, runs that fused speed readings):\n\n";
  for (const auto& g : groups) {
    out << "- " << fs::path(g.recording).filename().string() << ", " << g.scenario << ", IMU "
        << (g.imu ? "on" : "off") << ": modes " << CountsText(g.modes) << "; VO health " << CountsText(g.vo_health)
        << "; speed scale error " << MdTriple(g.speed_scale_error, 4) << "\n";
  }
  if (plan.smooth) {
    // The same runs' errors, forward filter against the smoothed trajectory.
    static const std::pair<MetricField, const char*> kCompared[] = {{kEndErrorPct, "end error % (first outage)"},
                                                                    {kMaxErrorM, "max error in the outage, m"},
                                                                    {kOutageRmseM, "RMSE in the outage, m"},
                                                                    {kRmseGpsM, "RMSE while GPS, m"}};
    out << "\n## Forward | smoothed\n\n"
        << "Median / p90 / max over the done runs; the ratio is the smoothed median over the forward one.\n\n"
        << "| recording | scenario | IMU | error | forward | smoothed | smoothed / forward |\n"
           "|---|---|---|---|---|---|---|\n";
    for (const auto& g : groups)
      for (const auto& [f, label] : kCompared) {
        const Distribution& fw = g.forward.*f.distribution;
        const Distribution& sm = g.smoothed.*f.distribution;
        if (fw.n == 0 && sm.n == 0) continue;  // no outage in the scenario, or nothing done yet
        const int digits = f.value == &RunMetrics::end_error_pct ? 2 : 3;
        out << "| " << fs::path(g.recording).filename().string() << " | " << g.scenario << " | "
            << (g.imu ? "on" : "off") << " | " << label << " | " << MdTriple(fw, digits) << " | "
            << MdTriple(sm, digits) << " | "
            << (fw.n && sm.n && fw.median > 0 ? Fmt(Round(sm.median / fw.median, 3)) : std::string("-")) << " |\n";
      }
  }
  if (failed > 0) {
    out << "\n## Failed runs\n\n";
    for (const auto& r : rows)
      if (r.state == RunState::kFailed) out << "- `" << r.id << "`: " << r.error << "\n";
  }
}

}  // namespace locaid::sweep
