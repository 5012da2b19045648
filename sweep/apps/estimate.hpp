// `locaid-sweep plan MANIFEST [--out DIR]`: what a sweep holds and what it
// will cost, without running it. The CPU time comes from measured runs:
// those already in DIR (the median of their CPU time), else one VO run and
// one filter run of the first recording, made now in a temporary folder
// through the same task code the engines run.
#pragma once

#include "sweep/plan.hpp"

#include <optional>
#include <string>

namespace locaid::sweep {

struct PlanCommandOptions {
  std::string manifest, out;
  bool measure = true;
  int jobs = 0;  // for the wall time on this machine (0: its cores)
};

// With --out DIR, a measurement made now is kept in DIR/costs.json for
// `run --runs-per-task auto`.
int PrintPlan(const PlanCommandOptions& options);

// The estimated CPU time of one of the plan's pending filter runs (the mean
// over its filter array): from the medians of the runs done in its DIR,
// else (for what those do not tell) from DIR/costs.json, which `plan --out
// DIR` writes. nullopt when neither tells.
struct RunCostEstimate {
  double cpu_s = 0;
  std::string source;
};
std::optional<RunCostEstimate> EstimatePendingFilterRun(const Plan& plan);

}  // namespace locaid::sweep
