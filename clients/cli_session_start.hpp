// `locaid session start`: its options (a KITTI drive, a ROS 2 bag, a
// synthetic drive, or live cameras the server reads through GStreamer) and
// the StartSessionRequest they make; `FillScenario` for it and for
// `locaid scenario`.
#pragma once

#include "locaid/v1/localization.pb.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace locaid::clients {

struct StartOptions {
  std::string kitti_path;
  int64_t first_frame = 0, last_frame = -1;
  std::string bag_path, bag_topics_file;  // a ROS 2 bag on the server; its topics as locaid-replay reads them
  bool synthetic = false;                 // --synthetic given
  uint64_t synth_seed = 0;
  uint32_t synth_frames = 0, history = 0;
  std::string scenario_name, scenario_file, vo_method;
  double rate = 0;
  bool fixed_vo_noise = false, fixed_gps_noise = false;  // StartSessionRequest.noise
  // --live: the server reads its cameras through GStreamer (LiveSource.cameras).
  bool live = false;
  std::string camera_left, camera_right, camera_stereo, camera_info_left, camera_info_right, gpsd;
  bool no_imu = false;  // LiveSource.no_imu
};

// Adds every option of `session start` to `start`, filling `so`.
void AddStartOptions(CLI::App& start, StartOptions& so);

// The request the options make; throws std::invalid_argument (no source
// given, a malformed --gpsd) or std::runtime_error (a file that cannot be
// read), each naming the option.
locaid::v1::StartSessionRequest StartSessionRequest(const StartOptions& o);

// A built-in scenario by name or a YAML file sent as text (neither:
// unchanged). A name that looks like a file (ends in .yaml/.yml, or holds a
// '/') is read as `file` is.
void FillScenario(const std::string& name, const std::string& file, locaid::v1::Scenario* out);

}  // namespace locaid::clients
