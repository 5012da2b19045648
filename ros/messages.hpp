// The ROS 2 messages locaid reads (a bag's; a live camera's CameraInfo),
// decoded from CDR (cdr.hpp) into plain structs. Layouts are the ROS 2
// (Humble and later) definitions of sensor_msgs, geometry_msgs, tf2_msgs and
// std_msgs; each decoder reads the fields in declaration order and throws
// CdrError on a truncated or lying message. Image payloads stay views into
// the message bytes.
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::ros {

// The ROS 2 type names (as a bag's schema names them) this file decodes.
inline constexpr std::string_view kImage = "sensor_msgs/msg/Image";
inline constexpr std::string_view kCompressedImage = "sensor_msgs/msg/CompressedImage";
inline constexpr std::string_view kCameraInfo = "sensor_msgs/msg/CameraInfo";
inline constexpr std::string_view kImu = "sensor_msgs/msg/Imu";
inline constexpr std::string_view kNavSatFix = "sensor_msgs/msg/NavSatFix";
inline constexpr std::string_view kTfMessage = "tf2_msgs/msg/TFMessage";
inline constexpr std::string_view kTwistStamped = "geometry_msgs/msg/TwistStamped";

struct Header {
  int64_t stamp_ns = 0;  // builtin_interfaces/Time: sec * 1e9 + nanosec
  std::string frame_id;
};

struct Image {
  Header header;
  uint32_t height = 0, width = 0;
  std::string encoding;  // sensor_msgs/image_encodings: mono8, mono16, rgb8, bgr8, bayer_rggb8, ...
  bool big_endian = false;
  uint32_t step = 0;      // bytes per row
  std::string_view data;  // step * height bytes (at least)
};

struct CompressedImage {
  Header header;
  std::string format;  // "png", "jpeg", or image_transport's "mono8; png compressed" style
  std::string_view data;
};

struct CameraInfo {
  Header header;
  uint32_t height = 0, width = 0;
  std::string distortion_model;  // plumb_bob, rational_polynomial, equidistant
  std::vector<double> d;
  std::array<double, 9> k{}, r{};
  std::array<double, 12> p{};
  uint32_t binning_x = 0, binning_y = 0;
  uint32_t roi_x_offset = 0, roi_y_offset = 0, roi_height = 0, roi_width = 0;
  bool roi_do_rectify = false;
};

struct Imu {
  Header header;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  std::array<double, 9> orientation_covariance{};  // [0] = -1: no orientation
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  std::array<double, 9> angular_velocity_covariance{};
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();
  std::array<double, 9> linear_acceleration_covariance{};
};

struct NavSatFix {
  // NavSatStatus.status and position_covariance_type values.
  static constexpr int8_t kNoFix = -1;
  static constexpr uint8_t kCovUnknown = 0, kCovApproximated = 1, kCovDiagonalKnown = 2, kCovKnown = 3;
  Header header;
  int8_t status = kNoFix;
  uint16_t service = 0;
  double latitude = 0, longitude = 0, altitude = 0;
  std::array<double, 9> position_covariance{};  // ENU, row-major, m^2
  uint8_t position_covariance_type = kCovUnknown;
};

struct TransformStamped {
  Header header;  // frame_id: the parent
  std::string child_frame_id;
  Eigen::Isometry3d T_parent_child = Eigen::Isometry3d::Identity();
};

struct TwistStamped {
  Header header;
  Eigen::Vector3d linear = Eigen::Vector3d::Zero(), angular = Eigen::Vector3d::Zero();
};

// Each takes a whole CDR message (encapsulation header included).
// The std_msgs/Header every stamped type above starts with (not TFMessage).
Header DecodeHeader(std::string_view cdr);
Image DecodeImage(std::string_view cdr);
CompressedImage DecodeCompressedImage(std::string_view cdr);
CameraInfo DecodeCameraInfo(std::string_view cdr);
Imu DecodeImu(std::string_view cdr);
NavSatFix DecodeNavSatFix(std::string_view cdr);
std::vector<TransformStamped> DecodeTfMessage(std::string_view cdr);
TwistStamped DecodeTwistStamped(std::string_view cdr);

// Decodes `cdr` as `type` (one of the names above) and discards the result:
// true when the type is one of them (what the fuzz target exercises).
bool DecodeAny(std::string_view type, std::string_view cdr);

}  // namespace locaid::ros
