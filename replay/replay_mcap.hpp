// locaid-replay --out-mcap: the replayed poses as the MCAP recording a live
// session gives (`locaid subscribe --format mcap`): same channels, schemas and
// PoseUpdate contents (output/pose_message.hpp), ground truth included.
// locaid-replay --out-bag: the same PoseUpdates as a ROS 2 bag
// (output/ros2_recording.hpp), with the drive's own camera mount on /tf_static.
#pragma once

#include "output/mcap_recording.hpp"
#include "output/ros2_recording.hpp"
#include "pipeline/frame_loop.hpp"

#include <Eigen/Geometry>

#include <filesystem>
#include <utility>

namespace locaid::pipeline {

// The PoseUpdate a session would publish for one pose of the frame loop
// (kind kPose), ground truth included; session id "replay".
locaid::v1::PoseUpdate ReplayPoseUpdate(const StepResult& step, uint64_t sequence);

// A recording (output::McapRecording, output::Ros2Recording) fed with the
// frame loop's poses, numbered as a session numbers them.
template <typename Recording>
class ReplayRecording {
 public:
  template <typename... Options>
  explicit ReplayRecording(const std::filesystem::path& path, Options&&... options)
      : recording_(path, std::forward<Options>(options)...) {}
  // One pose of the frame loop (kind kPose), ground truth included.
  void Add(const StepResult& step) { recording_.Add(ReplayPoseUpdate(step, sequence_++)); }
  void Close() { recording_.Close(); }
  uint64_t poses() const { return recording_.poses(); }

 private:
  Recording recording_;
  uint64_t sequence_ = 0;
};

using ReplayMcap = ReplayRecording<output::McapRecording>;

class ReplayBag : public ReplayRecording<output::Ros2Recording> {
 public:
  // T_cam0_imu: the drive's calibration (kitti::StereoDataset::T_cam0_imu).
  ReplayBag(const std::filesystem::path& path, const Eigen::Isometry3d& T_cam0_imu)
      : ReplayRecording(path, output::Ros2RecordingOptions{{}, T_cam0_imu.inverse()}) {}
};

}  // namespace locaid::pipeline
