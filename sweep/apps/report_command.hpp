// `locaid-sweep report DIR`: results.csv, summary.csv, summary.json, the
// PNG plots (locaid-sweep-plot, next to the program) and report.md. Works
// while runs are still going: their rows say pending.
#pragma once

#include "sweep/plan.hpp"

#include <string>

namespace locaid::sweep {

// Returns the number of filter runs not done. Throws std::runtime_error.
size_t WriteReport(const Plan& plan, const std::string& self_exe, bool quiet = false);

// `locaid-sweep status DIR`: counts, each failure with its error; 0 only when
// every run is done.
int PrintStatus(const Plan& plan);

}  // namespace locaid::sweep
