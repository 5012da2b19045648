// A session's poses on ROS 2 topics, live: the messages a ROS 2 bag of the
// poses holds (output/ros2_messages.hpp, byte for byte), each header.stamp
// the pose's t_ns exactly as the gRPC stream gives it.
//
//   odometry     /locaid/odometry  nav_msgs/msg/Odometry                every pose
//   fix          /locaid/fix       sensor_msgs/msg/NavSatFix            every pose not LOST
//   tf           /tf               tf2_msgs/msg/TFMessage               map -> body, every pose
//   tf_static    /tf_static        tf2_msgs/msg/TFMessage               body -> camera, once per session
//   gps          /locaid/gps       sensor_msgs/msg/NavSatFix            each fix the filter saw
//   diagnostics  /diagnostics      diagnostic_msgs/msg/DiagnosticArray  the pose's "locaid" status and
//                                                                       the caller's (input health)
//
// Defaults as a ROS 2 user expects them: reliable, volatile, keep last 10;
// /tf_static transient local, keep last 1 (a late subscriber gets the rig).
// Topic names (empty: not published), frame ids, QoS and the diagnostics
// period are options. Any thread; calls are serialized.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "output/cdr_writer.hpp"
#include "output/ros2_messages.hpp"
#include "ros2/graph.hpp"

#include <Eigen/Geometry>

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace locaid::ros2 {

enum class PoseTopic : size_t { kOdometry, kFix, kTf, kTfStatic, kGps, kDiagnostics, kCount };
inline constexpr size_t kPoseTopicCount = static_cast<size_t>(PoseTopic::kCount);
// "odometry", "fix", "tf", "tf_static", "gps", "diagnostics".
const char* PoseTopicKey(PoseTopic topic);
// The key's topic; throws std::invalid_argument listing the keys.
PoseTopic PoseTopicOfKey(const std::string& key);

struct PosePublisherOptions {
  std::array<std::string, kPoseTopicCount> topics{"/locaid/odometry", "/locaid/fix", "/tf", "/tf_static",
                                                 "/locaid/gps", "/diagnostics"};
  std::array<Qos, kPoseTopicCount> qos{Qos{}, Qos{}, Qos{},
                                       Qos{Reliability::kReliable, Durability::kTransientLocal, 1}, Qos{}, Qos{}};
  output::Ros2Frames frames;
  // The rig on /tf_static (body -> camera); unset: nothing on /tf_static.
  std::optional<Eigen::Isometry3d> T_body_cam0;
  // Diagnostics at most this often (wall seconds); 0: with every pose.
  double diagnostics_period_s = 1.0;
  // Statuses published beside the pose's (input health); may be empty.
  std::function<std::vector<output::DiagnosticStatus>()> extra_status;
};

// Applies "KEY=VALUE" to the options: VALUE is a topic name (or "" to turn
// it off) for --topic, a QoS (ros2/dds.hpp ParseQos) for --qos, a frame id
// for --frame (keys map, body, camera, gps). Throws std::invalid_argument
// naming the flag and what is wrong.
void SetTopicOption(PosePublisherOptions& o, const std::string& key_value);
void SetQosOption(PosePublisherOptions& o, const std::string& key_value);
void SetFrameOption(PosePublisherOptions& o, const std::string& key_value);

class PosePublisher {
 public:
  PosePublisher(Node& node, PosePublisherOptions options);

  // A new session is followed: its first pose publishes /tf_static again.
  void NewSession();
  void Publish(const v1::PoseUpdate& pose);
  // Diagnostics when none went out for a period (no poses): the last
  // pose's status (if any) and the extra ones, stamped with the last pose's
  // time, or the system clock before the first pose.
  void Tick();

  struct Stats {
    uint64_t poses = 0, messages = 0;
  };
  Stats stats() const;
  const std::string& topic(PoseTopic t) const { return options_.topics[static_cast<size_t>(t)]; }
  // Subscribers matched with the topic's writer now (0 when not published).
  int matched(PoseTopic t) const;

 private:
  void Write(PoseTopic t);  // mu_ held; cdr_ holds the message
  void PublishDiagnostics(int64_t t_ns);  // mu_ held

  PosePublisherOptions options_;
  std::array<std::unique_ptr<Writer>, kPoseTopicCount> writers_;
  mutable std::mutex mu_;
  output::CdrWriter cdr_;
  bool rig_sent_ = false;
  std::optional<v1::PoseUpdate> last_;
  std::chrono::steady_clock::time_point last_diagnostics_{};
  Stats stats_;
};

}  // namespace locaid::ros2
