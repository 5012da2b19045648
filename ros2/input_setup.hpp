// Before a live session fed from a car's ROS 2 topics can start: which
// topics are the stereo cameras, the IMU, the GPS receiver and the speed
// sensor, and the rig their first messages describe.
//
// Topics are named in a YAML file with the keys of `locaid-replay
// --bag-topics` (bag/bag_topics.hpp: left_image, left_info, right_image,
// right_info, imu, gps, speed; "none" turns a sensor off); keys left out are
// picked by type among the publications DDS discovers in the first
// `discovery_s`, exactly as a bag's are picked (bag::ChooseTopics; left and
// right from the camera_info's P[3]). The rig then comes from the first
// messages: both CameraInfo (rectification and the crop both cameras share,
// ros/camera_model.hpp), the IMU's frame and /tf_static for the camera-IMU
// extrinsic, the NavSatFix frame for the antenna's lever arm
// (ros/sensor_setup.hpp), as a bag's and a GStreamer camera's are.
//
// No DDS here: the caller feeds discovered publications and messages and
// creates the readers WantedTopics() names. Errors are std::runtime_error
// saying what is missing and which key to set.
#pragma once

#include "bag/bag_topics.hpp"
#include "locaid/v1/localization.pb.h"
#include "ros/camera_model.hpp"
#include "ros/messages.hpp"

#include <Eigen/Geometry>

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::ros2 {

enum class InputRole : size_t { kLeftImage, kRightImage, kLeftInfo, kRightInfo, kImu, kGps, kSpeed, kTfStatic, kCount };
inline constexpr size_t kInputRoleCount = static_cast<size_t>(InputRole::kCount);
// The YAML key of a role ("left_image" ... "speed"; "tf_static").
const char* InputRoleKey(InputRole role);

// The topic and ROS type of each role; an empty topic: not read.
struct InputTopics {
  std::array<std::string, kInputRoleCount> topic, type;
  const std::string& topic_of(InputRole r) const { return topic[static_cast<size_t>(r)]; }
  const std::string& type_of(InputRole r) const { return type[static_cast<size_t>(r)]; }
};

// What the session is started with.
struct InputRig {
  ros::CameraInfo left_info, right_info;
  std::shared_ptr<const ros::RectifiedStereo> rectified;  // both rectifiers, cropped; the camera VO sees
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  Eigen::Vector3d lever_arm_body_m = Eigen::Vector3d::Zero();
  bool has_imu = false;
  std::vector<std::string> notes;  // where the extrinsic and the lever arm came from, the crop
  // LiveSource of the session: the rectified camera, T_cam0_imu, the lever arm, no_imu.
  v1::LiveSource live() const;
};

struct InputSetupOptions {
  double discovery_s = 2.0;       // publications looked at before picking by type
  double setup_timeout_s = 30.0;  // then a missing message or topic is an error
};

class InputSetup {
 public:
  InputSetup(bag::BagTopics given, InputSetupOptions options);

  // A publication DDS discovered (ROS names: "/imu", "sensor_msgs/msg/Imu").
  void AddPublication(const std::string& topic, const std::string& type);
  // The topics to read now (ROS topic -> ROS type): while picking by type,
  // every discovered CameraInfo; once chosen, the chosen topics and
  // /tf_static.
  std::map<std::string, std::string> WantedTopics() const;
  // A message on one of them (CDR). Undecodable ones are skipped.
  void AddMessage(const std::string& topic, std::string_view cdr);

  // The rig once everything is there; nothing while something is still
  // awaited (`missing` says what). Throws std::runtime_error when the
  // topics cannot be chosen or a message did not come within
  // setup_timeout_s, or when what came does not fit (two cameras that are
  // no stereo pair, an IMU that /tf_static does not connect to the camera).
  std::optional<InputRig> TryFinish(double elapsed_s, std::string* missing);
  // The chosen topics (valid once TryFinish returned a rig, or after it
  // chose them).
  const InputTopics& topics() const { return topics_; }
  bool chosen() const { return chosen_; }

 private:
  bool Choose(double elapsed_s, std::string* missing);
  std::string TypeOf(const std::string& topic, const std::string& fallback) const;

  bag::BagTopics given_;
  InputSetupOptions options_;
  std::map<std::string, std::string> publications_;  // topic -> type (the first seen)
  std::map<std::string, ros::CameraInfo> infos_;       // first CameraInfo per topic
  std::map<std::string, std::string> frames_;          // first header.frame_id per topic (IMU, GPS)
  std::vector<ros::TransformStamped> static_transforms_;
  bool chosen_ = false;
  double chosen_at_s_ = 0;
  InputTopics topics_;
};

}  // namespace locaid::ros2
