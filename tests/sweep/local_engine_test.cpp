// The local engine on a rendered drive, as a user runs it: results equal a
// direct locaid-replay of the same run (bit for bit, minus the two timing
// fields), a second run starts nothing, changed inputs rerun only their runs,
// Ctrl-C keeps every finished result and a second run does only the rest, a
// corrupt recording fails only its own runs, with its error; a smoothed
// sweep tabulates forward and smoothed errors side by side. The real KITTI
// excerpt and a ROS 2 bag of it the same way when ../shared is there.
#include "needs_tool.hpp"
#include "process.hpp"
#include "sweep_support.hpp"
#include "temp_dir.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <thread>

namespace locaid::sweep_test {
namespace {

using locaid::test_support::ScopedTempDir;

class SweepLocal : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<ScopedTempDir>("sweep_local");
    drive_ = RenderDrive(dir_->path() / "synth", 7);
    WriteFile(dir_->path() / "outage.yaml", kOutageScenario);
  }
  static void TearDownTestSuite() { dir_.reset(); }

  // A manifest in the test's folder over the rendered drive.
  fs::path Manifest(const std::string& body) {
    const fs::path f = tmp_ / "sweep.yaml";
    WriteFile(f, "recordings:\n  - path: " + drive_.string() + "\n" + body);
    fs::copy_file(dir_->path() / "outage.yaml", tmp_ / "outage.yaml", fs::copy_options::overwrite_existing);
    return f;
  }
  CommandResult Sweep(const std::string& args) { return RunCommand(kSweep + " " + args); }

  static inline std::unique_ptr<ScopedTempDir> dir_;
  static inline fs::path drive_;
  ScopedTempDir tmp_{"sweep_local_run"};
};

std::map<std::string, fs::file_time_type> ResultTimes(const fs::path& dir) {
  std::map<std::string, fs::file_time_type> t;
  for (const auto& e : fs::directory_iterator(dir / "runs")) t[e.path().filename()] = fs::last_write_time(e.path());
  return t;
}

// Every done result of DIR against locaid-replay run directly with its arguments.
void ExpectEqualToDirectReplay(const fs::path& dir, size_t expected_runs) {
  const auto results = DoneResults(dir);
  EXPECT_EQ(results.size(), expected_runs);
  for (const auto& [id, r] : results) {
    SCOPED_TRACE(id);
    EXPECT_EQ(sweep::DeterministicMetrics(r["metrics"]).dump(), sweep::DeterministicMetrics(DirectReplay(r)).dump());
  }
}

TEST_F(SweepLocal, ResultsEqualADirectReplayAndASecondRunStartsNothing) {
  ASSERT_FALSE(drive_.empty());
  const fs::path m = Manifest("scenarios: [open-sky, outage.yaml]\nseeds: [1, 2]\nimu: [on, off]\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("1 VO runs and 8 filter runs to do"), std::string::npos) << run.out;
  ExpectEqualToDirectReplay(out, 8);

  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 0) << status.out;
  EXPECT_NE(status.out.find("filter runs: 8 done, 0 failed, 0 pending of 8"), std::string::npos) << status.out;

  // The table: one row per run; end_error_pct only where there is an outage.
  const auto rows = Lines(ReadText(out / "results.csv"));
  ASSERT_EQ(rows.size(), 9u);
  EXPECT_EQ(rows[0].rfind("recording,scenario,seed,imu,status,end_error_pct,rmse_gps_m,nees_mean", 0), 0u);
  EXPECT_EQ(rows[1].rfind(drive_.string() + ",open-sky,1,on,done,,", 0), 0u) << rows[1];
  EXPECT_EQ(rows[5].rfind(drive_.string() + ",outage-mid,1,on,done,", 0), 0u) << rows[5];
  EXPECT_NE(rows[5].find(",outage-mid,1,on,done,,"), 0u) << rows[5];
  EXPECT_NE(rows[0].find(",max_error_m,outage_rmse_m"), std::string::npos) << rows[0];  // forward: always
  EXPECT_EQ(rows[0].find("_smoothed"), std::string::npos) << rows[0];  // not a smoothed sweep
  const auto summary = ReadJson(out / "summary.json");
  ASSERT_EQ(summary.size(), 4u);
  EXPECT_EQ(summary[2]["end_error_pct"]["n"], 2);
  EXPECT_TRUE(summary[0]["end_error_pct"].is_null());  // open-sky: no outage
  EXPECT_TRUE(fs::exists(out / "report.md"));
  EXPECT_TRUE(fs::exists(out / "end_error_by_scenario.png"));
  EXPECT_TRUE(fs::exists(out / "end_error_by_recording.png"));

  // Again: nothing to do, no result rewritten.
  const auto before = ResultTimes(out);
  const auto again = Sweep("run " + m.string() + " --out " + out.string());
  EXPECT_EQ(again.exit_code, 0) << again.out;
  EXPECT_NE(again.out.find("every run of the sweep is done (8 filter runs, 1 VO runs): nothing started"),
            std::string::npos)
      << again.out;
  EXPECT_EQ(ResultTimes(out), before);

  // A changed scenario file changes the key of its runs only.
  WriteFile(tmp_ / "outage.yaml", std::string(kOutageScenario) + "# tuned\n");
  const auto changed = Sweep("run " + m.string() + " --out " + out.string());
  EXPECT_EQ(changed.exit_code, 0) << changed.out;
  EXPECT_NE(changed.out.find("0 VO runs and 4 filter runs to do (5 of 9 already done)"), std::string::npos)
      << changed.out;
}

// results.csv as column -> value, one map per row.
std::vector<std::map<std::string, std::string>> CsvRows(const fs::path& file) {
  auto split = [](const std::string& line) {  // the rows here quote nothing
    std::vector<std::string> cells;
    std::istringstream in(line);
    for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.emplace_back();
    return cells;
  };
  const auto lines = Lines(ReadText(file));
  std::vector<std::map<std::string, std::string>> rows;
  if (lines.empty()) return rows;
  const auto header = split(lines[0]);
  for (size_t i = 1; i < lines.size(); ++i) {
    const auto cells = split(lines[i]);
    EXPECT_EQ(cells.size(), header.size()) << lines[i];
    auto& row = rows.emplace_back();
    for (size_t c = 0; c < header.size() && c < cells.size(); ++c) row[header[c]] = cells[c];
  }
  return rows;
}

double FiniteNumber(const std::map<std::string, std::string>& row, const std::string& column) {
  const auto it = row.find(column);
  if (it == row.end()) {
    ADD_FAILURE() << "no column " << column;
    return std::nan("");
  }
  double v = std::nan("");
  try {
    v = std::stod(it->second);
  } catch (const std::exception&) {
  }
  EXPECT_TRUE(std::isfinite(v)) << column << " = '" << it->second << "'";
  return v;
}

// smooth: true: each run smooths (its result equals a direct locaid-replay
// --smooth), results.csv has the smoothed columns next to the forward ones,
// and the report puts forward and smoothed side by side.
TEST_F(SweepLocal, ASmoothedSweepTabulatesForwardAndSmoothed) {
  ASSERT_FALSE(drive_.empty());
  const fs::path m = Manifest("scenarios: [outage.yaml]\nseeds: [1]\nsmooth: true\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto plan = PlanJson(out);
  EXPECT_EQ(plan["smooth"], true);
  const auto& args = plan["filter_tasks"][0]["args"];
  EXPECT_NE(std::find(args.begin(), args.end(), "--smooth"), args.end()) << args;
  ExpectEqualToDirectReplay(out, 1);
  EXPECT_TRUE(DoneResults(out).begin()->second["metrics"].contains("smoothed"));

  const auto rows = CsvRows(out / "results.csv");
  ASSERT_EQ(rows.size(), 1u);
  const auto& row = rows[0];
  EXPECT_EQ(row.at("status"), "done");
  for (const char* column : {"end_error_pct", "end_error_pct_smoothed", "max_error_m", "max_error_m_smoothed",
                             "outage_rmse_m", "outage_rmse_m_smoothed", "rmse_gps_m_smoothed"})
    FiniteNumber(row, column);
  const double rmse = FiniteNumber(row, "rmse_gps_m"), rmse_smoothed = FiniteNumber(row, "rmse_gps_m_smoothed");
  EXPECT_LE(rmse_smoothed, rmse);
  EXPECT_GT(rmse_smoothed, 0);

  const auto summary = ReadJson(out / "summary.json");
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0]["smoothed"]["end_error_pct"]["n"], 1);
  EXPECT_EQ(summary[0]["smoothed"]["rmse_gps_m"]["median"], rmse_smoothed);
  EXPECT_EQ(summary[0]["max_error_m"]["n"], 1);
  EXPECT_NE(Lines(ReadText(out / "summary.csv"))[0].find(",rmse_gps_m_smoothed_median,"), std::string::npos);
  const std::string report = ReadText(out / "report.md");
  EXPECT_NE(report.find("## Forward | smoothed"), std::string::npos) << report;
  for (const char* label : {"| end error % (first outage) |", "| max error in the outage, m |",
                            "| RMSE in the outage, m |", "| RMSE while GPS, m |"})
    EXPECT_NE(report.find(label), std::string::npos) << label << "\n" << report;
  EXPECT_TRUE(fs::exists(out / "end_error_by_scenario.png"));
}

// A VO run whose cache is gone runs again when a filter run still needs the
// cache (its result alone is not enough), and only then.
TEST_F(SweepLocal, AVoCacheDeletedIsRebuiltWhenAFilterRunNeedsIt) {
  ASSERT_FALSE(drive_.empty());
  const fs::path m = Manifest("scenarios: [open-sky]\nseeds: [1, 2]\n");
  const fs::path out = tmp_ / "out";
  ASSERT_EQ(Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2").exit_code, 0);
  const auto plan = PlanJson(out);
  const fs::path cache = plan["vo_tasks"][0]["cache"].get<std::string>();
  ASSERT_TRUE(fs::exists(cache));
  fs::remove(cache);
  fs::remove(out / "runs" / (plan["filter_tasks"][1]["id"].get<std::string>() + ".json"));
  const auto again = Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2");
  EXPECT_EQ(again.exit_code, 0) << again.out;
  EXPECT_NE(again.out.find("1 VO runs and 1 filter runs to do (1 of 3 already done)"), std::string::npos)
      << again.out;
  EXPECT_TRUE(fs::exists(cache));
  EXPECT_EQ(Sweep("status " + out.string()).exit_code, 0);
}

TEST_F(SweepLocal, CtrlCKeepsFinishedResultsAndTheNextRunDoesOnlyTheRest) {
  ASSERT_FALSE(drive_.empty());
  const fs::path m = Manifest("scenarios: [open-sky, outage.yaml]\nseeds: {from: 1, to: 10}\n");
  const fs::path out = tmp_ / "out";
  Background sweep({kSweep, "run", m.string(), "--out", out.string(), "--jobs", "1"}, (tmp_ / "log").string());
  ASSERT_TRUE(sweep.started());
  // Interrupt once a few runs are done (20 filter runs of about 0.2 s each).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline &&
         (!fs::exists(out / "plan.json") || DoneResults(out).size() < 3))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  sweep.Signal(SIGINT);
  EXPECT_EQ(sweep.Wait(), 130) << ReadText(tmp_ / "log");
  const std::string log = ReadText(tmp_ / "log");
  EXPECT_NE(log.find("interrupted: "), std::string::npos) << log;
  EXPECT_NE(log.find("run the same command again to do only those"), std::string::npos) << log;
  const auto kept = DoneResults(out);
  ASSERT_GE(kept.size(), 3u);
  ASSERT_LT(kept.size(), 20u) << "the sweep ended before the interrupt: nothing was tested";
  for (const auto& e : fs::directory_iterator(out / "runs"))  // an interrupted run stays pending
    EXPECT_EQ(e.path().string().find(".failed.json"), std::string::npos) << e.path();
  const auto times = ResultTimes(out);
  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 1) << status.out;

  const auto resume = Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2");
  ASSERT_EQ(resume.exit_code, 0) << resume.out;
  EXPECT_NE(resume.out.find("0 VO runs and " + std::to_string(20 - kept.size()) + " filter runs to do (" +
                            std::to_string(kept.size() + 1) + " of 21 already done)"),
            std::string::npos)
      << resume.out;
  for (const auto& [file, t] : times) EXPECT_EQ(fs::last_write_time(out / "runs" / file), t) << file;
  EXPECT_EQ(DoneResults(out).size(), 20u);
}

TEST_F(SweepLocal, ACorruptRecordingFailsOnlyItsRunsWithItsError) {
  ASSERT_FALSE(drive_.empty());
  fs::copy(drive_.parent_path(), tmp_ / "bad", fs::copy_options::recursive);
  const fs::path bad = tmp_ / "bad" / drive_.filename();
  WriteFile(bad / "oxts/data/0000000005.txt", "garbage\n");
  const fs::path m = Manifest("  - path: " + bad.string() + "\nscenarios: [outage.yaml]\nseeds: [1, 2]\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + m.string() + " --out " + out.string() + " --jobs 2");
  EXPECT_EQ(run.exit_code, 1) << run.out;
  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 1) << status.out;
  EXPECT_NE(status.out.find("VO runs: 1 done, 1 failed"), std::string::npos) << status.out;
  EXPECT_NE(status.out.find("filter runs: 2 done, 2 failed, 0 pending of 4"), std::string::npos) << status.out;
  const std::string why = "oxts/data/0000000005.txt:1: 1 fields, expected 30";
  size_t failures = 0;
  for (const auto& line : Lines(status.out))
    if (line.rfind("failed ", 0) == 0) {
      ++failures;
      EXPECT_NE(line.find(why), std::string::npos) << line;  // the filter runs name their VO run's error
    }
  EXPECT_EQ(failures, 3u) << status.out;
  const auto failed = ReadJson(out / "runs" / (PlanJson(out)["vo_tasks"][1]["id"].get<std::string>() + ".failed.json"));
  EXPECT_EQ(failed["status"], "failed");
  EXPECT_EQ(failed["exit_code"], 1);
  EXPECT_FALSE(failed["stderr_tail"].empty());
  for (const auto& row : Lines(ReadText(out / "results.csv")))
    if (row.find(bad.string()) == 0) {
      EXPECT_NE(row.find(",failed,"), std::string::npos) << row;
    }
}

// The real KITTI excerpt and a ROS 2 bag of it (written by the reference
// writer, tests/rosbag/js), 60 frames each.
TEST_F(SweepLocal, RealExcerptAndItsBag) {
  if (!fs::exists(kRealDrive)) GTEST_SKIP() << "shared real KITTI excerpt absent: " << kRealDrive;
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("node") && test_support::HaveCommand("npm"),
                    "node/npm not installed (the bag writer runs on them)");
  const std::string js = LOCAID_SWEEP_JS_DIR;
  const auto setup = RunCommand("bash " + std::string(LOCAID_SOURCE_DIR) + "/tests/record/js/setup.sh " + js + " " +
                                LOCAID_SOURCE_DIR + "/tests/rosbag/js");
  ASSERT_EQ(setup.exit_code, 0) << setup.out;
  const fs::path bag = tmp_ / "excerpt.mcap";
  const auto convert = RunCommand("node " + js + "/kitti_to_bag.mjs --drive " + kRealDrive.string() + " --out " +
                                  bag.string() + " --max-frames 60");
  ASSERT_EQ(convert.exit_code, 0) << convert.out;
  fs::copy_file(dir_->path() / "outage.yaml", tmp_ / "outage.yaml");
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + kRealDrive.string() + "\n  - path: excerpt.mcap\n"
                                  "scenarios: [open-sky, outage.yaml]\nseeds: [1, 2, 3]\n"
                                  "replay_args: [--max-frames, '60']\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() + " --jobs 2");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  ExpectEqualToDirectReplay(out, 12);
  const auto rows = Lines(ReadText(out / "results.csv"));
  EXPECT_EQ(rows.size(), 13u);
  EXPECT_NE(rows.back().find(bag.string()), std::string::npos) << rows.back();
}

}  // namespace
}  // namespace locaid::sweep_test
