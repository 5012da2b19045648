// A small stereo car's ROS 2 messages for the locaid-ros2 tests, built as
// Fast DDS's generated types (idl/) and serialized by them: the bytes
// locaid's decoders read in the tests come from the other vendor's code.
// A 96x64 px camera pair (f 60 px, baseline 0.5 m), an IMU in imu_link
// (x forward, y left, z up), a GPS antenna 1.2 m ahead of it, /tf_static.
#pragma once

#include "fast_peer.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <string>

namespace locaid::ros2::testing {

inline constexpr int kCamW = 96, kCamH = 64;
inline constexpr double kCamF = 60.0, kBaseline = 0.5;
inline constexpr int64_t kT0 = 1'700'000'000'000'000'000;  // a Unix time, ns

// The CDR of a generated message (encapsulation header included).
template <class PubSub>
std::string Cdr(typename PubSub::type msg) {
  PubSub type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&msg)());
  if (!type.serialize(&msg, &payload)) throw std::runtime_error("Fast DDS: serialize failed");
  return std::string(reinterpret_cast<const char*>(payload.data), payload.length);
}

inline std_msgs::msg::dds_::Header_ RosHeader(int64_t t_ns, const std::string& frame) {
  std_msgs::msg::dds_::Header_ h;
  h.stamp().sec(static_cast<int32_t>(t_ns / 1'000'000'000));
  h.stamp().nanosec(static_cast<uint32_t>(t_ns % 1'000'000'000));
  h.frame_id(frame);
  return h;
}

// `tx`: P[3], -fx * baseline for the right camera, 0 for the left.
inline sensor_msgs::msg::dds_::CameraInfo_ MakeCameraInfo(int64_t t, const std::string& frame, double tx,
                                                          int width = kCamW, int height = kCamH) {
  sensor_msgs::msg::dds_::CameraInfo_ m;
  m.header(RosHeader(t, frame));
  m.width(static_cast<uint32_t>(width));
  m.height(static_cast<uint32_t>(height));
  m.distortion_model("plumb_bob");
  m.d({0, 0, 0, 0, 0});
  const double cx = width / 2.0, cy = height / 2.0;
  m.k({kCamF, 0, cx, 0, kCamF, cy, 0, 0, 1});
  m.r({1, 0, 0, 0, 1, 0, 0, 0, 1});
  m.p({kCamF, 0, cx, tx, 0, kCamF, cy, 0, 0, 0, 1, 0});
  return m;
}

// mono8 noise (the same seed: the same picture).
inline sensor_msgs::msg::dds_::Image_ MakeImage(int64_t t, const std::string& frame, uint64_t seed,
                                                int width = kCamW, int height = kCamH) {
  sensor_msgs::msg::dds_::Image_ m;
  m.header(RosHeader(t, frame));
  m.width(static_cast<uint32_t>(width));
  m.height(static_cast<uint32_t>(height));
  m.encoding("mono8");
  m.is_bigendian(0);
  m.step(static_cast<uint32_t>(width));
  cv::Mat noise(height, width, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  m.data(std::vector<uint8_t>(noise.data, noise.data + noise.total()));
  return m;
}

inline sensor_msgs::msg::dds_::Imu_ MakeImu(int64_t t, double ax = 0, double wz = 0) {
  sensor_msgs::msg::dds_::Imu_ m;
  m.header(RosHeader(t, "imu_link"));
  m.orientation().w(1);
  m.orientation_covariance()[0] = -1;
  m.linear_acceleration().x(ax);
  m.linear_acceleration().z(9.81);
  m.angular_velocity().z(wz);
  return m;
}

inline sensor_msgs::msg::dds_::NavSatFix_ MakeFix(int64_t t, double lat = 49.0, double lon = 8.4, int8_t status = 0) {
  sensor_msgs::msg::dds_::NavSatFix_ m;
  m.header(RosHeader(t, "gps_link"));
  m.status().status(status);
  m.status().service(1);
  m.latitude(lat);
  m.longitude(lon);
  m.altitude(110);
  m.position_covariance({4, 0, 0, 0, 4, 0, 0, 0, 9});
  m.position_covariance_type(2);  // DIAGONAL_KNOWN
  return m;
}

inline geometry_msgs::msg::dds_::TwistStamped_ MakeTwist(int64_t t, double speed_mps) {
  geometry_msgs::msg::dds_::TwistStamped_ m;
  m.header(RosHeader(t, "base_link"));
  m.twist().linear().x(speed_mps);
  return m;
}

// imu_link -> camera_left (the optical frame: z forward, x right, y down)
// and imu_link -> gps_link (1.2 m ahead).
inline tf2_msgs::msg::dds_::TFMessage_ MakeTfStatic(int64_t t) {
  tf2_msgs::msg::dds_::TFMessage_ m;
  geometry_msgs::msg::dds_::TransformStamped_ cam;
  cam.header(RosHeader(t, "imu_link"));
  cam.child_frame_id("camera_left");
  cam.transform().rotation().x(-0.5);
  cam.transform().rotation().y(0.5);
  cam.transform().rotation().z(-0.5);
  cam.transform().rotation().w(0.5);
  geometry_msgs::msg::dds_::TransformStamped_ gps;
  gps.header(RosHeader(t, "imu_link"));
  gps.child_frame_id("gps_link");
  gps.transform().translation().x(1.2);
  gps.transform().rotation().w(1);
  m.transforms({cam, gps});
  return m;
}

}  // namespace locaid::ros2::testing
