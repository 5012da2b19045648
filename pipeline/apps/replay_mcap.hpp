// locaid-replay --out-mcap: the replayed poses as the MCAP recording a live
// session gives (`locaid subscribe --format mcap`): same channels, schemas and
// PoseUpdate contents (server/pose_message.hpp), ground truth included.
#pragma once

#include "foxglove/mcap_recording.hpp"
#include "pipeline/localizer.hpp"

#include <Eigen/Geometry>

#include <filesystem>
#include <optional>

namespace locaid::pipeline {

class ReplayMcap {
 public:
  explicit ReplayMcap(const std::filesystem::path& path) : recording_(path) {}
  // One replayed frame; truth_enu: the ground-truth pose in the filter's ENU
  // frame (when known) and its WGS84 position.
  void Add(int64_t frame_index, const FrameResult& r, const std::optional<Eigen::Isometry3d>& truth_enu,
           double truth_lat, double truth_lon, double truth_alt);
  void Close() { recording_.Close(); }
  uint64_t poses() const { return recording_.poses(); }

 private:
  foxglove::McapRecording recording_;
  uint64_t sequence_ = 0;
};

}  // namespace locaid::pipeline
