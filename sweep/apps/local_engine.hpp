// The local engine: the tasks of a plan as `locaid-sweep task` child
// processes, at most `jobs` at once. A filter task starts once its
// recording's VO task has ended. Progress goes to stderr: one updating line
// on a terminal, a plain line every 15 s otherwise.
//
// SIGINT or SIGTERM to locaid-sweep: no new task starts, the running ones get
// SIGINT (each in its own process group; they store nothing and stay
// pending), every finished result is kept.
#pragma once

#include "sweep/plan.hpp"

#include <string>

namespace locaid::sweep {

struct LocalOutcome {
  size_t done = 0, failed = 0, left = 0;
  bool interrupted = false;
};

LocalOutcome RunLocal(const Plan& plan, const std::string& self_exe, int jobs);

// Set by the SIGINT / SIGTERM handler that RunLocal installs while it runs.
bool LocalStopRequested();

}  // namespace locaid::sweep
