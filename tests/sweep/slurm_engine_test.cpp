// The Slurm engine through a real single-node Slurm (slurm_cluster.hpp):
// a sweep of two recordings (one a ROS 2 bag when ../shared is there, else a
// second rendered drive) plus a corrupt one gives the local engine's metrics
// and a direct locaid-replay's, bit for bit; the corrupt recording's runs
// fail with its error; scancel of a running array task leaves that run not
// done and the next `run` submits only it; a completed sweep submits nothing.
// Batched (--runs-per-task 3): ceil(N/3) array tasks, the local engine's
// metrics; scancel of a batch leaves its unfinished runs not done and the
// next `run` does only those.
#include "needs_tool.hpp"
#include "slurm_cluster.hpp"
#include "sweep_support.hpp"
#include "temp_dir.hpp"

#include <chrono>
#include <cstdio>
#include <map>
#include <thread>

namespace locaid::sweep_test {
namespace {

using locaid::test_support::HaveCommand;
using locaid::test_support::ScopedTempDir;

class SweepSlurm : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!HaveCommand("slurmctld") || !HaveCommand("munged") || ::geteuid() != 0) return;
    dir_ = std::make_unique<ScopedTempDir>("sweep_slurm");
    fs::permissions(dir_->path(), fs::perms::group_exec | fs::perms::others_exec, fs::perm_options::add);
    cluster_ = std::make_unique<SlurmCluster>(dir_->path() / "slurm");
  }
  static void TearDownTestSuite() {
    cluster_.reset();  // before the folder it runs in
    dir_.reset();
  }
  void SetUp() override {
    LOCAID_NEEDS_TOOL(HaveCommand("slurmctld") && HaveCommand("munged"),
                      "slurm-wlm or munge not installed (deploy/install-deps.sh installs them)");
    if (::geteuid() != 0) GTEST_SKIP() << "the test Slurm runs as root";
    ASSERT_TRUE(cluster_ && cluster_->ready()) << (cluster_ ? cluster_->error() : "no cluster");
    // The test folder must be traversable by the daemons' children: it is where results go.
    fs::permissions(tmp_.path(), fs::perms::owner_all | fs::perms::group_exec | fs::perms::others_exec);
  }
  CommandResult Sweep(const std::string& args) { return RunCommand(kSweep + " " + args); }

  static inline std::unique_ptr<ScopedTempDir> dir_;
  static inline std::unique_ptr<SlurmCluster> cluster_;
  ScopedTempDir tmp_{"sweep_slurm_run"};
};

// A ROS 2 bag of the real excerpt's first 40 frames; empty without the data.
fs::path RealBag(const fs::path& out) {
  if (!fs::exists(kRealDrive) || !HaveCommand("node") || !HaveCommand("npm")) return {};
  const std::string js = LOCAID_SWEEP_JS_DIR;
  if (RunCommand("bash " + std::string(LOCAID_SOURCE_DIR) + "/tests/record/js/setup.sh " + js + " " +
                 LOCAID_SOURCE_DIR + "/tests/rosbag/js").exit_code != 0)
    return {};
  const auto r = RunCommand("node " + js + "/kitti_to_bag.mjs --drive " + kRealDrive.string() + " --out " +
                            out.string() + " --max-frames 40");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return out;
}

TEST_F(SweepSlurm, SameMetricsAsLocalCorruptRecordingFailsCompletedSweepSubmitsNothing) {
  const fs::path drive = RenderDrive(tmp_ / "synth", 7);
  fs::path second = RealBag(tmp_ / "excerpt.mcap");
  if (second.empty()) {
    std::cout << "[ NOTE ] no shared KITTI excerpt or node: the second recording is a rendered drive, not a bag\n";
    second = RenderDrive(tmp_ / "synth2", 9);
  }
  fs::copy(drive.parent_path(), tmp_ / "bad", fs::copy_options::recursive);
  const fs::path bad = tmp_ / "bad" / drive.filename();
  WriteFile(bad / "oxts/data/0000000005.txt", "garbage\n");
  WriteFile(tmp_ / "outage.yaml", kOutageScenario);
  const std::string common = "scenarios: [open-sky, outage.yaml]\nseeds: [1, 2, 3]\nreplay_args: [--max-frames, '40']\n";
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + drive.string() + "\n  - path: " + second.string() +
                                     "\n  - path: " + bad.string() + "\n" + common);

  const fs::path out = tmp_ / "slurm_out";
  const auto run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                         " --engine slurm --wait --poll-s 0.5 --max-running 2");
  EXPECT_EQ(run.exit_code, 1) << run.out;  // the corrupt recording's runs failed
  EXPECT_NE(run.out.find("submitted: VO array job "), std::string::npos) << run.out;
  EXPECT_TRUE(fs::exists(out / "slurm/vo.sbatch"));
  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 1) << status.out;
  EXPECT_NE(status.out.find("filter runs: 12 done, 6 failed, 0 pending of 18"), std::string::npos) << status.out;
  for (const auto& line : Lines(status.out))
    if (line.rfind("failed ", 0) == 0) {
      EXPECT_NE(line.find("oxts/data/0000000005.txt:1: 1 fields, expected 30"), std::string::npos) << line;
    }

  // The same sweep on the local engine: the same metrics, run by run; both as a direct locaid-replay.
  const fs::path local = tmp_ / "local_out";
  const auto local_run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + local.string() + " --jobs 2");
  EXPECT_EQ(local_run.exit_code, 1) << local_run.out;
  const auto on_slurm = DoneResults(out), here = DoneResults(local);
  ASSERT_EQ(on_slurm.size(), 12u);
  ASSERT_EQ(here.size(), 12u);
  for (const auto& [id, r] : on_slurm) {
    SCOPED_TRACE(id);
    ASSERT_TRUE(here.count(id));
    EXPECT_TRUE(r.contains("slurm_job"));
    const std::string metrics = sweep::DeterministicMetrics(r["metrics"]).dump();
    EXPECT_EQ(metrics, sweep::DeterministicMetrics(here.at(id)["metrics"]).dump());
    EXPECT_EQ(metrics, sweep::DeterministicMetrics(DirectReplay(r)).dump());
  }

  // Without the corrupt recording the sweep is complete: nothing is submitted.
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + drive.string() + "\n  - path: " + second.string() +
                                     "\n" + common);
  const std::string jobs_before = ReadText(out / "slurm/jobs.json");
  const auto again = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() + " --engine slurm");
  EXPECT_EQ(again.exit_code, 0) << again.out;
  EXPECT_NE(again.out.find("every run of the sweep is done (12 filter runs, 2 VO runs): nothing submitted"),
            std::string::npos)
      << again.out;
  EXPECT_EQ(ReadText(out / "slurm/jobs.json"), jobs_before);
  EXPECT_EQ(RunCommand("squeue -h").out, "");
}

TEST_F(SweepSlurm, ScancelOfARunningTaskLeavesItNotDoneAndTheNextRunSubmitsOnlyIt) {
  // Runs that take a second or two: camera faults make every run do VO over 300 frames.
  const fs::path drive = RenderDrive(tmp_ / "synth", 8, 300);
  WriteFile(tmp_ / "dark.yaml", "name: dark\nbase: open-sky\ncamera: [{start_s: 1, duration_s: 1, fault: dark}]\n");
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + drive.string() + "\nscenarios: [dark.yaml]\n"
                                 "seeds: [1, 2, 3]\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                         " --engine slurm --max-running 1");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const std::string marker = "filter array job ";
  const auto at = run.out.find(marker);
  ASSERT_NE(at, std::string::npos) << run.out;
  const std::string job = run.out.substr(at + marker.size(), run.out.find(' ', at + marker.size()) - at - marker.size());

  std::string task;  // "<job>_<index>" once one runs
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (task.empty() && std::chrono::steady_clock::now() < deadline) {
    const auto r = RunCommand("squeue -h -t R -j " + job + " -o %i");
    if (!r.out.empty()) task = r.out.substr(0, r.out.find('\n'));
    else std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_FALSE(task.empty()) << "no task of job " << job << " ever ran";
  EXPECT_EQ(RunCommand("scancel " + task).exit_code, 0);
  for (int i = 0; i < 600 && !RunCommand("squeue -h -j " + job).out.empty(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(200));

  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 1) << status.out;
  const bool recorded = status.out.find("filter runs: 2 done, 1 failed, 0 pending of 3") != std::string::npos;
  const bool pending = status.out.find("filter runs: 2 done, 0 failed, 1 pending of 3") != std::string::npos;
  EXPECT_TRUE(recorded || pending) << status.out;  // killed mid-run: recorded; before it began: pending
  if (recorded) {
    EXPECT_NE(status.out.find("killed by signal 15"), std::string::npos) << status.out;
  }

  const auto again = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                           " --engine slurm --wait --poll-s 0.5");
  EXPECT_EQ(again.exit_code, 0) << again.out;
  EXPECT_NE(again.out.find("0 VO runs and 1 filter runs to do (2 of 3 already done)"), std::string::npos)
      << again.out;
  EXPECT_NE(again.out.find("(1 tasks)"), std::string::npos) << again.out;
  EXPECT_EQ(Sweep("status " + out.string()).exit_code, 0);
}

// "filter runs: D done, F failed, P pending of N" of `locaid-sweep status`.
struct Counts {
  int done = -1, failed = -1, pending = -1, total = -1;
};
Counts FilterCounts(const std::string& status) {
  Counts c;
  for (const auto& line : Lines(status))
    if (line.rfind("filter runs: ", 0) == 0)
      std::sscanf(line.c_str(), "filter runs: %d done, %d failed, %d pending of %d", &c.done, &c.failed, &c.pending,
                  &c.total);
  return c;
}

// The job id after `marker` ("filter array job ") in run's output.
std::string JobAfter(const std::string& out, const std::string& marker) {
  const auto at = out.find(marker);
  if (at == std::string::npos) return "";
  return out.substr(at + marker.size(), out.find(' ', at + marker.size()) - at - marker.size());
}

TEST_F(SweepSlurm, BatchesOfThreeRunsMakeCeilNOverThreeTasksWithTheLocalEnginesMetrics) {
  const fs::path drive = RenderDrive(tmp_ / "synth", 11);
  WriteFile(tmp_ / "outage.yaml", kOutageScenario);
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + drive.string() +
                                     "\nscenarios: [open-sky, outage.yaml]\nseeds: [1, 2, 3, 4]\n"
                                     "replay_args: [--max-frames, '40']\n");
  const fs::path out = tmp_ / "slurm_out";
  const auto run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                         " --engine slurm --runs-per-task 3 --wait --poll-s 0.5");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  // 8 filter runs in ceil(8 / 3) = 3 array tasks; the one VO run in one.
  EXPECT_NE(run.out.find("filter stage: 8 runs in 3 array tasks of up to 3 runs (--runs-per-task 3"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("VO array job "), std::string::npos) << run.out;
  const std::string filter_job = JobAfter(run.out, "filter array job ");
  EXPECT_NE(run.out.find("filter array job " + filter_job + " (3 tasks"), std::string::npos) << run.out;
  const auto plan = PlanJson(out);
  EXPECT_EQ(plan["runs_per_task"]["filter"], 3);
  EXPECT_EQ(plan["arrays"]["filter"].size(), 8u);
  EXPECT_EQ(Sweep("status " + out.string()).exit_code, 0);

  // Results stay one per run, each with the array task that ran it: 3, 3 and 2 runs.
  const auto on_slurm = DoneResults(out);
  ASSERT_EQ(on_slurm.size(), 8u);
  std::map<std::string, int> runs_of_task;
  for (const auto& [id, r] : on_slurm) ++runs_of_task[r.value("slurm_job", "")];
  EXPECT_EQ(runs_of_task, (std::map<std::string, int>{
                              {filter_job + "_0", 3}, {filter_job + "_1", 3}, {filter_job + "_2", 2}}));

  // The local engine ignores --runs-per-task; the metrics are the same, run by run.
  const fs::path local = tmp_ / "local_out";
  const auto local_run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + local.string() +
                               " --jobs 2 --runs-per-task 3");
  ASSERT_EQ(local_run.exit_code, 0) << local_run.out;
  EXPECT_EQ(PlanJson(local)["runs_per_task"]["filter"], 1);
  const auto here = DoneResults(local);
  ASSERT_EQ(here.size(), 8u);
  for (const auto& [id, r] : on_slurm) {
    SCOPED_TRACE(id);
    ASSERT_TRUE(here.count(id));
    EXPECT_EQ(sweep::DeterministicMetrics(r["metrics"]).dump(),
              sweep::DeterministicMetrics(here.at(id)["metrics"]).dump());
  }
  EXPECT_EQ(RunCommand("squeue -h").out, "");
}

TEST_F(SweepSlurm, ScancelOfABatchLeavesItsUnfinishedRunsNotDoneAndTheNextRunDoesOnlyThose) {
  // Runs of a second or two (camera faults: VO over 300 frames in each), all six in one array task.
  const fs::path drive = RenderDrive(tmp_ / "synth", 12, 300);
  WriteFile(tmp_ / "dark.yaml", "name: dark\nbase: open-sky\ncamera: [{start_s: 1, duration_s: 1, fault: dark}]\n");
  WriteFile(tmp_ / "sweep.yaml", "recordings:\n  - path: " + drive.string() + "\nscenarios: [dark.yaml]\n"
                                 "seeds: [1, 2, 3, 4, 5, 6]\n");
  const fs::path out = tmp_ / "out";
  const auto run = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                         " --engine slurm --runs-per-task 6");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const std::string job = JobAfter(run.out, "filter array job ");
  ASSERT_FALSE(job.empty()) << run.out;
  EXPECT_NE(run.out.find("filter array job " + job + " (1 tasks)"), std::string::npos) << run.out;

  // Cancel the task once its first run is stored.
  auto done_files = [&] {
    size_t n = 0;
    if (fs::exists(out / "runs"))
      for (const auto& e : fs::directory_iterator(out / "runs")) {
        const std::string name = e.path().filename().string();
        n += name.size() > 5 && name.substr(name.size() - 5) == ".json" && name.find(".failed.") == std::string::npos;
      }
    return n;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(180);
  while (done_files() == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GT(done_files(), 0u) << "no run of job " << job << " ever finished";
  EXPECT_EQ(RunCommand("scancel " + job + "_0").exit_code, 0);
  for (int i = 0; i < 600 && !RunCommand("squeue -h -j " + job).out.empty(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(200));

  const auto status = Sweep("status " + out.string());
  EXPECT_EQ(status.exit_code, 1) << status.out;
  const Counts c = FilterCounts(status.out);
  ASSERT_EQ(c.total, 6) << status.out;
  EXPECT_GE(c.done, 1) << status.out;
  EXPECT_LE(c.failed, 1) << status.out;  // at most the run it was in: killed by signal 15
  EXPECT_GE(c.pending, 1) << status.out;  // the ones after it never started
  EXPECT_EQ(c.done + c.failed + c.pending, 6) << status.out;
  const std::string err_log = ReadText(out / "slurm/logs" / (job + "_0.err"));
  EXPECT_NE(err_log.find("left pending:"), std::string::npos) << err_log;
  std::map<std::string, fs::file_time_type> kept;
  for (const auto& [id, r] : DoneResults(out)) kept[id] = fs::last_write_time(out / "runs" / (id + ".json"));

  const auto again = Sweep("run " + (tmp_ / "sweep.yaml").string() + " --out " + out.string() +
                           " --engine slurm --runs-per-task 6 --wait --poll-s 0.5");
  EXPECT_EQ(again.exit_code, 0) << again.out;
  EXPECT_NE(again.out.find("0 VO runs and " + std::to_string(6 - c.done) + " filter runs to do (" +
                           std::to_string(c.done) + " of 6 already done)"),
            std::string::npos)
      << again.out;
  EXPECT_EQ(Sweep("status " + out.string()).exit_code, 0);
  for (const auto& [id, t] : kept) EXPECT_EQ(fs::last_write_time(out / "runs" / (id + ".json")), t) << id;
}

}  // namespace
}  // namespace locaid::sweep_test
