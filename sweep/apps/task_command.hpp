// `locaid-sweep task DIR --stage vo|filter [--index N]`: one array task of
// the plan in DIR, the one code path every engine runs (the local pool starts
// it as a child, a Slurm array task or a Kubernetes Indexed Job pod runs it).
// Without --index it takes SLURM_ARRAY_TASK_ID, else JOB_COMPLETION_INDEX.
//
// Array task N runs the plan's batch N (runs_per_task consecutive entries of
// the stage's array; one for the local engine), one after the other, each as
// its own locaid-replay child with the planned arguments, and stores each
// run's result (runs/<id>.json) or failure (runs/<id>.failed.json)
// atomically. A failed run does not stop the others; a run already done with
// its key (a task run again: a requeue, a retried pod) is skipped.
// SIGTERM (scancel, a time limit) is passed to the running locaid-replay,
// which is recorded as that run's failure; the batch's later runs are not
// started and stay pending. SIGINT (the local engine stopping) is passed on
// and nothing is stored: the run stays pending.
#pragma once

#include "sweep/plan.hpp"

#include <filesystem>
#include <optional>

namespace locaid::sweep {

// Exit status: 0 every run of the batch done, 1 some failed (stored), 2 no
// such task / no plan, 130 interrupted (SIGINT), 143 stopped by SIGTERM.
int RunTask(const std::filesystem::path& dir, Stage stage, std::optional<size_t> index);

}  // namespace locaid::sweep
