// The Slurm engine: the plan's VO tasks and filter tasks as two job arrays
// (sbatch --array=0-N%K), the filter array after the VO array
// (--dependency=afterany: a recording whose VO failed fails only its own
// filter runs, which say so). Each array task runs `locaid-sweep task DIR
// --stage S`, which takes its index from SLURM_ARRAY_TASK_ID and runs that
// batch of the plan (runs_per_task consecutive runs); per-task logs go to
// DIR/slurm/logs/<job>_<index>.out/.err. The job ids are kept in
// DIR/slurm/jobs.json so that a second `run` while they are queued is
// refused (it would rewrite the index -> task map they read).
#pragma once

#include "sweep/plan.hpp"

#include <optional>
#include <string>
#include <vector>

namespace locaid::sweep {

struct SlurmOptions {
  std::string partition, time, mem;
  int cpus_per_task = 0;  // 0: the cluster's default
  int max_running = 0;    // the %K of --array; 0: no limit
  std::vector<std::string> sbatch_args;
  bool wait = false;
  double poll_s = 5;
};

struct SlurmJobs {
  std::string vo, filter;  // job ids, "" when that array was not needed
};

// The job ids of DIR's last submission that squeue still lists (empty: none,
// or no earlier submission). Throws std::runtime_error when squeue fails for
// another reason than unknown job ids.
std::vector<std::string> QueuedJobs(const std::string& dir);

// Writes DIR/slurm/{vo,filter}.sbatch, submits one array per stage of
// plan.array_tasks(stage) tasks, records the ids. Throws std::runtime_error with sbatch's message.
SlurmJobs SubmitSlurm(const Plan& plan, const std::string& self_exe, const SlurmOptions& options);

// MaxArraySize of the cluster (`scontrol show config`); nullopt when
// scontrol is missing or fails.
std::optional<long> SlurmMaxArraySize();

// Polls squeue until none of `jobs` is listed (no accounting needed).
void WaitForJobs(const SlurmJobs& jobs, double poll_s);

}  // namespace locaid::sweep
