// A ROS 2 bag of a session's poses: an MCAP file with profile "ros2", one
// Schema per message type ("ros2msg": the .msg definitions as rosbag2 stores
// them, output/ros2_schemas.hpp) and CDR messages (output/cdr_writer.hpp),
// so `ros2 bag info/play`, RViz (through play) and Foxglove read it without
// locaid. docs/api.md "ROS 2 output" maps every field.
//
//   /locaid/odometry  nav_msgs/msg/Odometry          map -> base_link, pose + twist
//   /locaid/fix       sensor_msgs/msg/NavSatFix      fused lat/lon/alt (not while LOST)
//   /tf               tf2_msgs/msg/TFMessage         map -> base_link per pose
//   /tf_static        tf2_msgs/msg/TFMessage         base_link -> camera_left, once
//   /locaid/gps       sensor_msgs/msg/NavSatFix      each GPS fix the filter saw
//   /locaid/status    diagnostic_msgs/msg/DiagnosticArray  mode, VO, GPS gate, ...
//
// Frames (REP-103/105): `map` is the filter's ENU frame (origin = the first
// accepted GPS fix), `base_link` the body/IMU frame (x forward, y left, z
// up), `camera_left` the left rectified camera (optical: x right, y down,
// z forward), `gps` the GPS antenna. Messages are stamped and logged at the
// sensor time of what they describe (PoseUpdate.t_ns, GpsFixSeen.t_ns;
// negative times become 0); the messages are output/ros2_messages.hpp's.
// Errors are McapWriter's (std::system_error naming the file).
#pragma once

#include "locaid/v1/localization.pb.h"
#include "output/cdr_writer.hpp"
#include "output/ros2_messages.hpp"
#include "record/mcap_writer.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>

namespace locaid::output {

struct Ros2RecordingOptions {
  // Chunking and compression; the profile is always "ros2".
  record::McapOptions mcap;
  // Pose of the left rectified camera in the body frame (T_body_cam0 =
  // T_cam0_imu^-1), written once on /tf_static as base_link -> camera_left.
  // PoseUpdate does not carry the rig; unset: /tf_static gets no message.
  std::optional<Eigen::Isometry3d> T_body_cam0;
};

// T_body_cam0 of the KITTI 2011_09_26 rig (output/static_transforms.hpp),
// what `locaid subscribe --format ros2-mcap` writes: a session does not
// report its rig, and the Foxglove channels use the same constant.
Eigen::Isometry3d KittiRigTBodyCam0();

class Ros2Recording {
 public:
  explicit Ros2Recording(const std::filesystem::path& path, Ros2RecordingOptions options = {});
  void Add(const v1::PoseUpdate& pose);
  // Writes the summary and footer; the destructor does it too (swallowing errors).
  void Close();
  uint64_t poses() const { return poses_; }
  uint64_t messages() const { return writer_.messages_written(); }

 private:
  enum Channel : size_t { kOdometry, kFix, kTf, kTfStatic, kGps, kStatus, kChannelCount };
  void Write(Channel channel, int64_t t_ns);

  record::McapWriter writer_;
  std::optional<Eigen::Isometry3d> T_body_cam0_;
  std::array<uint16_t, kChannelCount> channel_ids_{};
  std::array<uint32_t, kChannelCount> sequences_{};
  CdrWriter cdr_;  // reused for every message
  uint64_t poses_ = 0;
};

}  // namespace locaid::output
