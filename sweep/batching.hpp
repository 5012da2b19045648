// How many runs one array task carries (Slurm job arrays, Kubernetes Indexed
// Jobs). A filter run from a VO cache takes a fraction of a second; an array
// task costs the scheduler seconds to start, and an array may not have more
// than MaxArraySize - 1 tasks (Slurm's default MaxArraySize is 1001). So an
// array task runs K consecutive entries of its stage's array in plan.json,
// each still its own locaid-replay child with its own result.
//
// `auto`: the smallest K that keeps the array within min(1000, MaxArraySize -
// 1) tasks, raised so that each task carries at least ~30 s of estimated work
// when a cost estimate exists (the median CPU time of the sweep's finished
// runs, or the measurement `locaid-sweep plan --out DIR` kept in DIR). Without
// an estimate K only respects the cap: 1 for sweeps of up to 1000 runs.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace locaid::sweep {

inline constexpr size_t kMaxArrayTasks = 1000;   // even where MaxArraySize allows more
inline constexpr long kDefaultMaxArraySize = 1001;  // Slurm's default
inline constexpr double kMinTaskWorkS = 30;      // auto: the least estimated work per task

// min(1000, MaxArraySize - 1); nullopt (Slurm not reachable, or Kubernetes):
// Slurm's default 1001.
size_t ArrayTaskCap(std::optional<long> max_array_size);

// MaxArraySize from `scontrol show config`'s output ("MaxArraySize = 1001");
// nullopt when absent.
std::optional<long> ParseMaxArraySize(const std::string& scontrol_show_config);

struct Batching {
  size_t runs_per_task = 1;
  size_t tasks = 0;  // ceil(runs / runs_per_task)
  std::string why;   // one line for the user
};

// `runs` entries of an array; `cpu_s_per_run`: the estimated CPU time of one.
Batching AutoBatching(size_t runs, std::optional<double> cpu_s_per_run, size_t cap);
// A K the user gave (--runs-per-task K).
Batching FixedBatching(size_t runs, size_t runs_per_task);

// "auto" -> nullopt; a positive integer -> it; else std::invalid_argument.
std::optional<size_t> ParseRunsPerTask(const std::string& text);

}  // namespace locaid::sweep
