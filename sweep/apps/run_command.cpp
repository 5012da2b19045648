#include "sweep/apps/run_command.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/apps/estimate.hpp"
#include "sweep/apps/local_engine.hpp"
#include "sweep/apps/report_command.hpp"
#include "sweep/batching.hpp"
#include "sweep/result_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <thread>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

// One `run` per DIR at a time: an flock on DIR/.lock, released when the
// process ends however it ends.
class DirLock {
 public:
  explicit DirLock(const fs::path& dir) {
    fd_ = ::open((dir / ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0 || ::flock(fd_, LOCK_EX | LOCK_NB) != 0)
      throw std::runtime_error(dir.string() + " is in use by another locaid-sweep run");
  }
  ~DirLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;

 private:
  int fd_ = -1;
};

// The tasks left to do: not done with the current key. A VO run whose cache
// is gone runs again if a filter run still needs the cache.
void MarkPending(Plan& plan) {
  plan.vo_array.clear();
  plan.filter_array.clear();
  std::vector<bool> vo_needed(plan.vo.size(), false);
  for (size_t i = 0; i < plan.filter.size(); ++i) {
    const FilterTask& t = plan.filter[i];
    if (ReadResult(plan.dir, t.id, t.key).state == RunState::kDone) continue;
    plan.filter_array.push_back(i);
    if (t.vo_task >= 0) vo_needed[static_cast<size_t>(t.vo_task)] = true;
  }
  for (size_t i = 0; i < plan.vo.size(); ++i) {
    const bool done = ReadResult(plan.dir, plan.vo[i].id, plan.vo[i].key).state == RunState::kDone;
    if (!done || (vo_needed[i] && !fs::exists(plan.vo[i].cache))) plan.vo_array.push_back(i);
  }
}

// How many runs each array task of a Slurm array or Indexed Job carries
// (sweep/batching.hpp); false with `error` set when the arrays would be too
// large for the cluster.
bool ChooseBatching(Plan& plan, const RunCommandOptions& o, std::string& error) {
  std::optional<long> max_array_size;
  if (o.engine == "slurm") max_array_size = SlurmMaxArraySize();
  const size_t cap = ArrayTaskCap(max_array_size);
  const std::string cap_note =
      o.engine == "k8s" ? std::string("at most 1000 tasks per Indexed Job")
      : max_array_size  ? "this cluster's MaxArraySize " + std::to_string(*max_array_size)
                        : std::string("MaxArraySize 1001 (Slurm's default) assumed: scontrol did not answer");
  // A VO run takes seconds to minutes and the whole filter stage waits for the
  // VO array: VO runs share a task only when there are more than the cap.
  plan.vo_runs_per_task = std::max<size_t>(1, (plan.vo_array.size() + cap - 1) / cap);
  const size_t n = plan.filter_array.size();
  const std::optional<size_t> fixed = ParseRunsPerTask(o.runs_per_task);
  std::optional<RunCostEstimate> estimate;
  if (!fixed) estimate = EstimatePendingFilterRun(plan);
  const Batching b = fixed ? FixedBatching(n, *fixed)
                           : AutoBatching(n, estimate ? std::optional(estimate->cpu_s) : std::nullopt, cap);
  if (b.tasks > cap && o.engine == "slurm") {
    error = "--runs-per-task " + std::to_string(b.runs_per_task) + " makes a filter array of " +
            std::to_string(b.tasks) + " tasks, more than " + std::to_string(cap) + " (" + cap_note +
            "); use --runs-per-task " + std::to_string((n + cap - 1) / cap) + " or more, or auto";
    return false;
  }
  plan.filter_runs_per_task = b.runs_per_task;
  if (!plan.vo_array.empty())
    std::cout << "VO stage: " << plan.vo_array.size() << " runs in " << plan.array_tasks(Stage::kVo)
              << " array tasks" << (plan.vo_runs_per_task > 1 ? " of up to " + std::to_string(plan.vo_runs_per_task) +
                                                                   " runs (" + cap_note + ")"
                                                             : std::string(" (one run each)"))
              << "\n";
  if (n > 0)
    std::cout << "filter stage: " << n << " runs in " << b.tasks << " array tasks of up to " << b.runs_per_task
              << " runs (" << b.why << (estimate ? ", from " + estimate->source : std::string()) << "; "
              << cap_note << ")\n";
  return true;
}

}  // namespace

Plan PlanFor(const std::string& manifest_path, const std::string& dir) {
  const Manifest manifest = LoadManifest(manifest_path);
  const fs::path replay = fs::path(SelfExe()).parent_path() / "locaid-replay";
  return BuildPlan(manifest, fs::absolute(dir), replay, LOCAID_VERSION);
}

int RunSweep(const RunCommandOptions& o) {
  Plan plan;
  try {
    plan = PlanFor(o.manifest, o.out);
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep: " << e.what() << "\n";
    return 2;
  }
  const std::string self = SelfExe();
  fs::create_directories(plan.dir);
  std::optional<DirLock> lock;
  try {
    lock.emplace(plan.dir);
    if (o.engine == "slurm") {
      const auto queued = QueuedJobs(plan.dir);
      if (!queued.empty()) {
        std::string ids;
        for (const auto& j : queued) ids += " " + j;
        throw std::runtime_error("Slurm jobs of this sweep are still queued or running (" + ids.substr(1) +
                                 "); wait for them (`locaid-sweep status " + plan.dir + "`) or scancel them");
      }
    }
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep: " << e.what() << "\n";
    return 2;
  }

  MarkPending(plan);
  const size_t todo = plan.vo_array.size() + plan.filter_array.size();
  if (todo == 0) {
    WritePlan(plan);
    std::cout << "locaid-sweep: every run of the sweep is done (" << plan.filter.size() << " filter runs, "
              << plan.vo.size() << " VO runs): nothing " << (o.engine == "slurm" ? "submitted" : "started") << "\n";
    WriteReport(plan, self);
    return 0;
  }
  std::cout << "locaid-sweep: " << plan.vo_array.size() << " VO runs and " << plan.filter_array.size()
            << " filter runs to do (" << plan.runs() - todo << " of " << plan.runs() << " already done) in "
            << plan.dir << "\n";
  if (o.engine != "local") {
    std::string error;
    if (!ChooseBatching(plan, o, error)) {
      std::cerr << "locaid-sweep: " << error << "\n";
      return 2;
    }
  }
  WritePlan(plan);

  if (o.engine == "k8s") {
    // Kubernetes Indexed Jobs run the same tasks; the user applies them
    // (deploy/k8s/sweep-job.yaml) with these completions.
    std::cout << "plan written: " << plan.dir << "/plan.json\n"
              << "locaid-sweep-vo completions: " << plan.array_tasks(Stage::kVo) << "\n"
              << "locaid-sweep-filter completions: " << plan.array_tasks(Stage::kFilter) << "\n"
              << "apply the VO Job, wait for it, then the filter Job (docs/sweeps.md, \"Kubernetes\")\n";
    return 0;
  }
  if (o.engine == "slurm") {
    SlurmJobs jobs;
    try {
      jobs = SubmitSlurm(plan, self, o.slurm);
    } catch (const std::exception& e) {
      std::cerr << "locaid-sweep: " << e.what() << "\n";
      return 2;
    }
    std::cout << "submitted:" << (jobs.vo.empty() ? "" : " VO array job " + jobs.vo + " (" +
                                                              std::to_string(plan.array_tasks(Stage::kVo)) + " tasks)")
              << (jobs.filter.empty() ? "" : " filter array job " + jobs.filter + " (" +
                                                 std::to_string(plan.array_tasks(Stage::kFilter)) + " tasks" +
                                                 (jobs.vo.empty() ? "" : ", after " + jobs.vo) + ")")
              << "\n";
    lock.reset();  // status and report may run while the jobs do
    if (!o.slurm.wait) {
      std::cout << "follow with `locaid-sweep status " << plan.dir << "`; logs in " << plan.dir << "/slurm/logs\n";
      return 0;
    }
    WaitForJobs(jobs, o.slurm.poll_s);
    const size_t not_done = WriteReport(plan, self);
    return not_done == 0 ? 0 : 1;
  }

  const int jobs = o.jobs > 0 ? o.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const LocalOutcome outcome = RunLocal(plan, self, jobs);
  WriteReport(plan, self);
  if (outcome.interrupted) {
    std::cerr << "locaid-sweep: interrupted: " << outcome.done << " runs done and kept, " << outcome.left
              << " left; run the same command again to do only those\n";
    return 130;
  }
  return outcome.failed == 0 ? 0 : 1;
}

}  // namespace locaid::sweep
