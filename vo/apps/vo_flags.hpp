// The VO command-line flags shared by locaid-vo and vo_bench: the method, the
// frames tracked, the timing clock and the default method's knobs. One place
// for their names, help, range checks and the DriveRunConfig they make.
#pragma once

#include "vo/apps/drive_runner.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace locaid::vo {

struct VoFlags {
  std::string method = "default";
  size_t max_frames = 0;       // 0: all
  bool cpu_time = false;       // per-stage timings on the thread CPU clock
  int window_keyframes = -1;   // -1: the method's default
  std::string klt_guess;       // "full" | "rotation" | "" (the method's default)
  size_t frame_step = 1;
};

// Adds --method (one of `methods`), --max-frames, --cpu-time,
// --window-keyframes, --klt-guess and --frame-step, bound to `flags`.
void AddVoFlags(CLI::App& app, VoFlags& flags, const std::vector<std::string>& methods);

// After parsing: a flag of the default method given while `runs` (the
// methods that will run) lacks it, as a message for the user; empty when the
// flags fit together.
std::string VoFlagsProblem(const VoFlags& flags, const std::vector<std::string>& runs);

// The run of one method with these flags.
DriveRunConfig MakeDriveRunConfig(const VoFlags& flags, const std::string& method);

// "thread_cpu" or "wall": the clock of the stage timings, as the JSON says it.
const char* StageClockName(const VoFlags& flags);

// The run's counts and timings as locaid-vo --json and vo_bench print them:
// frames, failed_frames, degraded_frames, ms_per_frame_{median,p95,mean},
// cpu_ms_per_frame_{median,p95}, stage_median_ms, stage_clock.
void AddRunSummaryJson(nlohmann::json& j, const TimingSummary& s, const VoFlags& flags);

}  // namespace locaid::vo
