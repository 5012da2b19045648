// Which topics of a ROS 2 bag are the stereo cameras, the IMU, the GPS
// receiver and the vehicle speed: picked by message type when that is
// unambiguous, else named in a small YAML file (`--bag-topics FILE`):
//
//   left_image: /camera/left/image_raw      # sensor_msgs/Image or CompressedImage
//   left_info: /camera/left/camera_info     # sensor_msgs/CameraInfo
//   right_image: /camera/right/image_raw
//   right_info: /camera/right/camera_info
//   imu: /imu/data                          # sensor_msgs/Imu          (optional)
//   gps: /gps/fix                           # sensor_msgs/NavSatFix    (optional)
//   speed: /vehicle/speed                   # geometry_msgs/TwistStamped, twist.linear.x (optional)
//
// Any key may be left out and is then picked by type. "none" turns an
// optional sensor off. Left and right come from the sign of the right
// camera's P[3] (= -fx * baseline).
#pragma once

#include "ros/messages.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace locaid::bag {

class RosBag;

struct TopicSummary {
  std::string topic, type;
  uint64_t count = 0;
  uint64_t undecodable = 0;          // messages whose CDR did not decode as `type`
  int64_t first_stamp_ns = 0, last_stamp_ns = 0;  // header.stamp (0: none seen)
  uint64_t stamped = 0;              // messages with a header stamp
  std::string frame_id;              // header.frame_id of the first stamped message
  std::optional<ros::CameraInfo> camera_info;  // CameraInfo topics: the first message
  double rate_hz() const;
};

struct BagInventory {
  std::map<std::string, TopicSummary> topics;
  std::vector<std::string> notes;  // RosBag::notes() at the end of the scan
  // The transforms of every TFMessage on a topic named .../tf_static.
  std::vector<ros::TransformStamped> static_transforms;
  bool complete = false;           // the whole bag was scanned (else a preview)
};

// Reads `bag` and summarizes its topics; stops after `max_log_span_ns` of log
// time from the first message (0: to the end). `progress` (optional) gets
// the fraction of bytes done, now and then.
BagInventory ScanBag(RosBag& bag, uint64_t max_log_span_ns = 0,
                     const std::function<void(double)>& progress = {});

struct BagTopics {
  std::string left_image, left_info, right_image, right_info;
  std::string imu, gps, speed;  // empty: none
};

// The YAML map described above; throws std::runtime_error naming the file
// and the key for unknown keys or non-string values.
BagTopics LoadBagTopics(const std::filesystem::path& path);

// Fills every topic `given` leaves empty from `inventory`, and checks the
// named ones have the right type. Throws std::runtime_error explaining what
// is missing or ambiguous (with the candidates and the YAML key to set).
BagTopics ChooseTopics(const BagInventory& inventory, BagTopics given = {});

// What `locaid-replay --bag PATH --inspect` prints: topics, types, counts,
// rates, and the choice (or why there is none).
std::string DescribeInventory(const BagInventory& inventory, const BagTopics* choice, const std::string& why_not);

// Scans the whole bag at `path` and describes it with the choice ChooseTopics
// makes from `given` (or why it cannot).
std::string InspectBag(const std::filesystem::path& path, const BagTopics& given,
                       const std::function<void(double)>& progress = {});

}  // namespace locaid::bag
