// `locaid-sweep run MANIFEST --out DIR`: plan, leave out what is done, run the
// rest on an engine, report.
#pragma once

#include "sweep/apps/slurm_engine.hpp"

#include <string>

namespace locaid::sweep {

// What `locaid-sweep run` is given on its command line (PlanCommandOptions:
// what `plan` is given).
struct RunCommandOptions {
  std::string manifest, out;
  std::string engine = "local";  // local | slurm | k8s (plan only)
  int jobs = 0;                  // local: 0 = the number of cores
  // slurm, k8s: filter runs per array task, "auto" or K (the local engine
  // ignores it); VO runs are batched only to keep the array under the cap.
  std::string runs_per_task = "auto";
  SlurmOptions slurm;
};

// The plan of MANIFEST for DIR with the locaid-replay next to this program.
// Throws ManifestError / std::runtime_error.
Plan PlanFor(const std::string& manifest, const std::string& dir);

// Exit status: 0 every run done (or submitted, for slurm without --wait), 1
// some failed, 2 a bad manifest or a refused DIR, 130 interrupted.
int RunSweep(const RunCommandOptions& options);

}  // namespace locaid::sweep
