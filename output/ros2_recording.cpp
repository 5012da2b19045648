#include "output/ros2_recording.hpp"

#include "output/ros2_schemas.hpp"
#include "output/static_transforms.hpp"

#include <algorithm>
#include <map>
#include <string>
#include <utility>

namespace locaid::output {
namespace {

// offered_qos_profiles as rosbag2 (Humble) records them for a publisher:
// history and depth unknown to the recorder, infinite durations (a
// sequence of one profile, in YAML). durability 2 = volatile, 1 =
// transient_local; reliability 1 = reliable.
std::string QosProfiles(bool transient_local) {
  const std::string infinite = "    sec: 9223372036\n    nsec: 854775807\n";
  return std::string("- history: 3\n  depth: 0\n  reliability: 1\n  durability: ") + (transient_local ? "1" : "2") +
         "\n  deadline:\n" + infinite + "  lifespan:\n" + infinite + "  liveliness: 1\n  liveliness_lease_duration:\n" +
         infinite + "  avoid_ros_namespace_conventions: false";
}

uint64_t LogTime(int64_t t_ns) { return static_cast<uint64_t>(std::max<int64_t>(t_ns, 0)); }

}  // namespace

Eigen::Isometry3d KittiRigTBodyCam0() {
  const StaticTransform& cam = BaseLinkToCam0();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(cam.rotation_xyzw[3], cam.rotation_xyzw[0], cam.rotation_xyzw[1], cam.rotation_xyzw[2])
                   .normalized()
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(cam.translation[0], cam.translation[1], cam.translation[2]);
  return T;
}

Ros2Recording::Ros2Recording(const std::filesystem::path& path, Ros2RecordingOptions options)
    : writer_(path, [&] {
        record::McapOptions mcap = options.mcap;
        mcap.profile = "ros2";
        return mcap;
      }()),
      T_body_cam0_(options.T_body_cam0) {
  struct Spec {
    Channel channel;
    const char* topic;
    const char* type;
    bool transient_local;
  };
  const Spec specs[] = {{kOdometry, "/locaid/odometry", "nav_msgs/msg/Odometry", false},
                        {kFix, "/locaid/fix", "sensor_msgs/msg/NavSatFix", false},
                        {kTf, "/tf", "tf2_msgs/msg/TFMessage", false},
                        {kTfStatic, "/tf_static", "tf2_msgs/msg/TFMessage", true},
                        {kGps, "/locaid/gps", "sensor_msgs/msg/NavSatFix", false},
                        {kStatus, "/locaid/status", "diagnostic_msgs/msg/DiagnosticArray", false}};
  std::map<std::string, uint16_t> schema_ids;  // one Schema record per type
  for (const Spec& s : specs) {
    auto [it, added] = schema_ids.emplace(s.type, 0);
    if (added) it->second = writer_.AddSchema(s.type, "ros2msg", Ros2FullDefinition(s.type));
    channel_ids_[s.channel] =
        writer_.AddChannel(it->second, s.topic, "cdr", {{"offered_qos_profiles", QosProfiles(s.transient_local)}});
  }
}

void Ros2Recording::Write(Channel channel, int64_t t_ns) {
  writer_.Write(channel_ids_[channel], LogTime(t_ns), LogTime(t_ns), cdr_.data(), sequences_[channel]++);
}

void Ros2Recording::Add(const v1::PoseUpdate& p) {
  const int64_t t = p.t_ns();
  const Ros2Frames frames;
  if (poses_ == 0 && T_body_cam0_) {
    EncodeCameraTf(t, *T_body_cam0_, frames, cdr_);
    Write(kTfStatic, t);
  }
  EncodeOdometry(p, frames, cdr_);
  Write(kOdometry, t);
  EncodeTf(p, frames, cdr_);
  Write(kTf, t);
  if (EncodeFusedFix(p, frames, cdr_)) Write(kFix, t);
  for (const v1::GpsFixSeen& f : p.gps_fixes()) {
    EncodeGpsFixSeen(f, frames, cdr_);
    Write(kGps, f.t_ns());
  }
  EncodeDiagnosticArray(t, {PoseStatus(p)}, cdr_);
  Write(kStatus, t);
  ++poses_;
}

void Ros2Recording::Close() { writer_.Close(); }

}  // namespace locaid::output
