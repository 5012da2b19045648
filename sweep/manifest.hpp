// A sweep manifest (YAML): which recordings, scenarios, seeds and IMU
// settings to run, and the locaid-replay arguments every run gets.
//
//   recordings:                  # KITTI drive folders and ROS 2 bags; globs allowed
//     - path: /data/kitti/2011_09_26/2011_09_26_drive_0005_sync
//     - path: /data/bags/*.mcap
//       bag_topics: topics.yaml  # optional, as locaid-replay --bag-topics
//   scenarios: [open-sky, urban-canyon, scenarios/outage-10s-middle.yaml]
//   seeds: {from: 1, to: 20}     # or a list: [1, 2, 3]
//   imu: [on, off]               # optional, default [on]
//   replay_args: ["--vehicle-constraints", "auto"]   # optional, passed to every run
//   smooth: true                 # optional, default false: every run also smooths (locaid-replay --smooth)
//
// A relative path is relative to the manifest's folder. Everything is
// checked here, before any run: an error names the file, the line and the
// key ("sweep.yaml:4: recordings[1].path: /data/bags/*.mcap matches nothing").
#pragma once

#include "sweep/recording.hpp"

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace locaid::sweep {

class ManifestError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Recording {
  std::filesystem::path path;        // canonical
  RecordingKind kind = RecordingKind::kDrive;
  std::filesystem::path bag_topics;  // canonical, or empty
};

struct ScenarioRef {
  std::string arg;   // what --scenario gets: a built-in name, or the YAML file's canonical path
  std::string name;  // the scenario's name (built-in name, the YAML's `name:` or the file's stem)
  bool builtin = true;
  bool camera_faults = false;  // runs VO itself: locaid-replay refuses --vo-cache for it
};

struct Manifest {
  std::filesystem::path file;  // canonical
  std::vector<Recording> recordings;  // in manifest order, each path once
  std::vector<ScenarioRef> scenarios;
  std::vector<int64_t> seeds;
  std::vector<bool> imu;  // true: with IMU
  std::vector<std::string> replay_args;
  bool smooth = false;  // each filter run gets --smooth: its result gains "smoothed"
};

// Throws ManifestError ("FILE:LINE: KEY: reason"; a file that cannot be read
// or is not YAML: "FILE: ..." / "FILE:LINE: ...").
Manifest LoadManifest(const std::filesystem::path& file);

// The locaid-replay options a sweep sets itself or that would make runs
// write over each other; replay_args may not hold them.
bool IsReservedReplayArg(const std::string& arg);

}  // namespace locaid::sweep
