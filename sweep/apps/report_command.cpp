#include "sweep/apps/report_command.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/apps/slurm_engine.hpp"
#include "sweep/summary.hpp"

#include <filesystem>
#include <iostream>
#include <sstream>

namespace fs = std::filesystem;

namespace locaid::sweep {

size_t WriteReport(const Plan& plan, const std::string& self_exe, bool quiet) {
  const fs::path dir = plan.dir;
  const auto rows = CollectRows(plan);
  const auto groups = Summarize(rows);
  WriteResultsCsv(rows, plan.smooth, dir / "results.csv");
  WriteSummaryCsv(groups, plan.smooth, dir / "summary.csv");
  WriteSummaryJson(groups, plan.smooth, dir / "summary.json");

  // The plots are matplotlib's (Debian's python3-matplotlib); without it the
  // tables are still written and report.md says why there is no picture.
  std::vector<std::string> plots;
  std::string note;
  const fs::path script = fs::path(self_exe).parent_path() / "locaid-sweep-plot";
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  try {
    std::string out, err;
    const ChildExit e = RunToEnd({"/usr/bin/env", python, script.string(), dir.string()}, out, err);
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);)
      if (!line.empty()) plots.push_back(line);
    if (e.exit_code != 0) note = script.string() + " failed (" + Describe(e) + "): " + err;
    else if (plots.empty()) note = "no run with an outage has finished yet";
  } catch (const std::exception& ex) {
    note = ex.what();
  }
  WriteReportMd(plan, rows, groups, plots, note, dir / "report.md");
  size_t not_done = 0;
  for (const auto& r : rows) not_done += r.state != RunState::kDone;
  if (!quiet) {
    std::cout << "report: " << (dir / "report.md").string() << " (results.csv, summary.csv, summary.json";
    for (const auto& p : plots) std::cout << ", " << p;
    std::cout << ")\n";
    if (!note.empty() && note.find("no run") == std::string::npos) std::cerr << "locaid-sweep: no plots: " << note;
  }
  return not_done;
}

int PrintStatus(const Plan& plan) {
  size_t counts[2][4] = {};  // stage x state
  for (const Stage stage : {Stage::kVo, Stage::kFilter})
    for (const RunState s : TaskStates(plan, stage)) ++counts[stage == Stage::kFilter][static_cast<int>(s)];
  auto line = [&](const char* what, int k, size_t total) {
    const size_t* c = counts[k];
    std::cout << what << ": " << c[static_cast<int>(RunState::kDone)] << " done, "
              << c[static_cast<int>(RunState::kFailed)] << " failed, "
              << c[static_cast<int>(RunState::kPending)] + c[static_cast<int>(RunState::kStale)] << " pending";
    if (c[static_cast<int>(RunState::kStale)] > 0)
      std::cout << " (" << c[static_cast<int>(RunState::kStale)] << " with a result of other inputs)";
    std::cout << " of " << total << "\n";
  };
  line("VO runs", 0, plan.vo.size());
  line("filter runs", 1, plan.filter.size());
  // Failures with their errors (VO first: a VO failure explains its filter runs').
  size_t shown = 0;
  for (const Stage stage : {Stage::kVo, Stage::kFilter}) {
    const size_t n = stage == Stage::kVo ? plan.vo.size() : plan.filter.size();
    for (size_t i = 0; i < n; ++i) {
      const std::string& id = stage == Stage::kVo ? plan.vo[i].id : plan.filter[i].id;
      const std::string& key = stage == Stage::kVo ? plan.vo[i].key : plan.filter[i].key;
      const StoredResult r = ReadResult(plan.dir, id, key);
      if (r.state != RunState::kFailed) continue;
      if (++shown <= 50) std::cout << "failed " << id << ": " << r.json.value("error", "") << "\n";
    }
  }
  if (shown > 50) std::cout << "... and " << shown - 50 << " more failures (results.csv after `report`)\n";
  try {
    const auto queued = QueuedJobs(plan.dir);
    if (!queued.empty()) {
      std::cout << "Slurm jobs still queued or running:";
      for (const auto& j : queued) std::cout << " " << j;
      std::cout << "\n";
    }
  } catch (const std::exception& e) {
    std::cout << "(Slurm queue unknown: " << e.what() << ")\n";
  }
  const size_t all_done = counts[0][static_cast<int>(RunState::kDone)] + counts[1][static_cast<int>(RunState::kDone)];
  return all_done == plan.runs() ? 0 : 1;
}

}  // namespace locaid::sweep
