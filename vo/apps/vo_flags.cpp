#include "vo/apps/vo_flags.hpp"

#include <algorithm>

namespace locaid::vo {

void AddVoFlags(CLI::App& app, VoFlags& flags, const std::vector<std::string>& methods) {
  std::string names;
  for (const std::string& m : methods) names += (names.empty() ? "" : " | ") + m;
  app.add_option("--method", flags.method, "VO method: " + names)->check(CLI::IsMember(methods));
  app.add_option("--max-frames", flags.max_frames, "process at most N frames (0: all)");
  app.add_flag("--cpu-time", flags.cpu_time, "per-stage timings on the thread CPU clock instead of wall time");
  app.add_option("--window-keyframes", flags.window_keyframes,
                 "default method: sliding bundle-adjustment window in keyframes (0: off; "
                 "unset: the method's default)")
      ->check(CLI::Range(0, 50));
  app.add_option("--klt-guess", flags.klt_guess,
                 "default method: KLT start from the full constant-velocity prediction (full, the default) "
                 "or from its rotation only (rotation)")
      ->check(CLI::IsMember({"full", "rotation"}));
  app.add_option("--frame-step", flags.frame_step,
                 "track frames 0, N, 2N, ... only (a lower frame rate: more motion between frames)")
      ->check(CLI::Range(size_t{1}, size_t{100}));
}

std::string VoFlagsProblem(const VoFlags& flags, const std::vector<std::string>& runs) {
  if (std::find(runs.begin(), runs.end(), "default") != runs.end()) return {};
  const std::string got = " (got --method " + flags.method + ")";
  if (flags.window_keyframes >= 0) return "--window-keyframes applies to --method default only" + got;
  if (!flags.klt_guess.empty()) return "--klt-guess applies to --method default only" + got;
  return {};
}

DriveRunConfig MakeDriveRunConfig(const VoFlags& flags, const std::string& method) {
  DriveRunConfig config;
  config.method = method;
  config.max_frames = flags.max_frames;
  config.clock = flags.cpu_time ? TimingClock::kThreadCpu : TimingClock::kWall;
  config.window_keyframes = flags.window_keyframes;
  if (!flags.klt_guess.empty()) config.klt_guess_translation = flags.klt_guess == "full";
  config.frame_step = flags.frame_step;
  return config;
}

const char* StageClockName(const VoFlags& flags) { return flags.cpu_time ? "thread_cpu" : "wall"; }

void AddRunSummaryJson(nlohmann::json& j, const TimingSummary& s, const VoFlags& flags) {
  j["frames"] = s.frames;
  j["failed_frames"] = s.lost_frames;
  j["degraded_frames"] = s.degraded_frames;
  j["ms_per_frame_median"] = s.ms_per_frame_median;
  j["ms_per_frame_p95"] = s.ms_per_frame_p95;
  j["ms_per_frame_mean"] = s.ms_per_frame_mean;
  j["cpu_ms_per_frame_median"] = s.cpu_ms_per_frame_median;
  j["cpu_ms_per_frame_p95"] = s.cpu_ms_per_frame_p95;
  j["stage_median_ms"] = s.stage_median_ms;
  j["stage_clock"] = StageClockName(flags);
}

}  // namespace locaid::vo
