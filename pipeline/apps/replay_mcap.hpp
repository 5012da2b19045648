// locaid-replay --out-mcap: the replayed poses as the MCAP recording a live
// session gives (`locaid subscribe --format mcap`): same channels, schemas and
// PoseUpdate contents (output/pose_message.hpp), ground truth included.
#pragma once

#include "output/mcap_recording.hpp"
#include "pipeline/frame_loop.hpp"

#include <filesystem>

namespace locaid::pipeline {

class ReplayMcap {
 public:
  explicit ReplayMcap(const std::filesystem::path& path) : recording_(path) {}
  // One pose of the frame loop (kind kPose), ground truth included.
  void Add(const StepResult& step);
  void Close() { recording_.Close(); }
  uint64_t poses() const { return recording_.poses(); }

 private:
  output::McapRecording recording_;
  uint64_t sequence_ = 0;
};

}  // namespace locaid::pipeline
