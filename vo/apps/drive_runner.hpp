// Runs a VO method over a whole StereoDataset and chains the relative motions
// into cam0 poses (world = cam0 at the first tracked frame). Shared by the
// locaid-vo program and the VO benchmark.
#pragma once

#include "kitti/dataset.hpp"
#include "vo/stereo_odometry.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace locaid::vo {

struct DriveRunConfig {
  std::string method = "default";
  size_t max_frames = 0;  // 0: all frames
  TimingClock clock = TimingClock::kWall;  // of the per-stage timings
  // "default" only: the sliding-window size (DefaultConfig::window_keyframes);
  // -1 keeps the method's default.
  int window_keyframes = -1;
  // "default" only: DefaultConfig::klt_guess_translation; unset keeps the default.
  std::optional<bool> klt_guess_translation;
  // Track frames 0, step, 2 step, ... only (a lower frame rate, so more motion
  // between frames); 1 tracks every frame.
  size_t frame_step = 1;
};

struct FrameResult {
  size_t index = 0;
  int64_t t_ns = 0;
  double tum_time_s = 0;
  bool missing = false;  // an image is absent or unreadable: Track was not called
  std::string missing_reason;
  RelativeMotion motion;  // default-constructed when missing
  double track_cpu_ms = 0;  // thread CPU time of Track (robust to other load on the machine)
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  // held when missing
};

struct DriveRun {
  std::string method;
  std::vector<FrameResult> frames;  // one per visited frame index (every frame_step-th), in order
};

using DriveProgress = std::function<void(const FrameResult& frame, size_t total)>;

DriveRun RunOnDataset(const kitti::StereoDataset& dataset, const DriveRunConfig& config,
                      const DriveProgress& progress = {});

// One pose per entry of run.frames (every frame index when frame_step is 1);
// a missing frame gets the pose interpolated in time
// (along the relative motion that bridges it) between its tracked neighbours,
// or the last pose when no tracked frame follows.
std::vector<Eigen::Isometry3d> PosesPerFrame(const DriveRun& run);

struct TimingSummary {
  int frames = 0;         // frames Track was called on
  int missing_frames = 0;
  int lost_frames = 0;    // status LOST
  int degraded_frames = 0;
  double ms_per_frame_median = 0, ms_per_frame_p95 = 0, ms_per_frame_mean = 0;  // wall
  double cpu_ms_per_frame_median = 0, cpu_ms_per_frame_p95 = 0;                  // thread CPU
  std::map<std::string, double> stage_median_ms;  // per stage name
};

TimingSummary Summarize(const DriveRun& run);

}  // namespace locaid::vo
