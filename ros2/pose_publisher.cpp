#include "ros2/pose_publisher.hpp"

#include <stdexcept>

namespace locaid::ros2 {
namespace {

constexpr const char* kKeys[kPoseTopicCount] = {"odometry", "fix", "tf", "tf_static", "gps", "diagnostics"};
constexpr const char* kTypes[kPoseTopicCount] = {"nav_msgs/msg/Odometry",  "sensor_msgs/msg/NavSatFix",
                                                 "tf2_msgs/msg/TFMessage", "tf2_msgs/msg/TFMessage",
                                                 "sensor_msgs/msg/NavSatFix", "diagnostic_msgs/msg/DiagnosticArray"};

size_t Index(PoseTopic t) { return static_cast<size_t>(t); }

// "KEY=VALUE" split at the first '='; throws naming the flag.
std::pair<std::string, std::string> KeyValue(const std::string& flag, const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw std::invalid_argument(flag + " '" + text + "': expected KEY=VALUE");
  }
  return {text.substr(0, eq), text.substr(eq + 1)};
}

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

const char* PoseTopicKey(PoseTopic t) { return kKeys[Index(t)]; }

PoseTopic PoseTopicOfKey(const std::string& key) {
  for (size_t i = 0; i < kPoseTopicCount; ++i) {
    if (key == kKeys[i]) return static_cast<PoseTopic>(i);
  }
  throw std::invalid_argument("'" + key + "' is none of odometry, fix, tf, tf_static, gps, diagnostics");
}

void SetTopicOption(PosePublisherOptions& o, const std::string& key_value) {
  const auto [key, value] = KeyValue("--topic", key_value);
  const PoseTopic t = PoseTopicOfKey(key);
  if (!value.empty()) (void)DdsTopicName(value);  // throws for a name ROS does not take
  o.topics[Index(t)] = value;
}

void SetQosOption(PosePublisherOptions& o, const std::string& key_value) {
  const auto [key, value] = KeyValue("--qos", key_value);
  const PoseTopic t = PoseTopicOfKey(key);
  o.qos[Index(t)] = ParseQos(value, o.qos[Index(t)]);
}

void SetFrameOption(PosePublisherOptions& o, const std::string& key_value) {
  const auto [key, value] = KeyValue("--frame", key_value);
  if (value.empty()) throw std::invalid_argument("--frame " + key + ": the frame id is empty");
  if (key == "map") {
    o.frames.map = value;
  } else if (key == "body") {
    o.frames.body = value;
  } else if (key == "camera") {
    o.frames.camera = value;
  } else if (key == "gps") {
    o.frames.gps = value;
  } else {
    throw std::invalid_argument("--frame '" + key + "' is none of map, body, camera, gps");
  }
}

PosePublisher::PosePublisher(Node& node, PosePublisherOptions options) : options_(std::move(options)) {
  for (size_t i = 0; i < kPoseTopicCount; ++i) {
    if (options_.topics[i].empty()) continue;
    if (i == Index(PoseTopic::kTfStatic) && !options_.T_body_cam0) continue;  // nothing to say
    writers_[i] = node.CreatePublisher(options_.topics[i], kTypes[i], options_.qos[i]);
  }
}

void PosePublisher::NewSession() {
  std::lock_guard lock(mu_);
  rig_sent_ = false;
  last_.reset();
}

void PosePublisher::Write(PoseTopic t) {
  const auto& writer = writers_[Index(t)];
  if (!writer) return;
  writer->Write(cdr_.data());
  ++stats_.messages;
}

void PosePublisher::Publish(const v1::PoseUpdate& p) {
  std::lock_guard lock(mu_);
  const output::Ros2Frames& frames = options_.frames;
  if (!rig_sent_ && options_.T_body_cam0 && writers_[Index(PoseTopic::kTfStatic)]) {
    output::EncodeCameraTf(p.t_ns(), *options_.T_body_cam0, frames, cdr_);
    Write(PoseTopic::kTfStatic);
    rig_sent_ = true;
  }
  if (writers_[Index(PoseTopic::kOdometry)]) {
    output::EncodeOdometry(p, frames, cdr_);
    Write(PoseTopic::kOdometry);
  }
  if (writers_[Index(PoseTopic::kTf)]) {
    output::EncodeTf(p, frames, cdr_);
    Write(PoseTopic::kTf);
  }
  if (writers_[Index(PoseTopic::kFix)] && output::EncodeFusedFix(p, frames, cdr_)) Write(PoseTopic::kFix);
  if (writers_[Index(PoseTopic::kGps)]) {
    for (const v1::GpsFixSeen& f : p.gps_fixes()) {
      output::EncodeGpsFixSeen(f, frames, cdr_);
      Write(PoseTopic::kGps);
    }
  }
  last_ = p;
  ++stats_.poses;
  const auto now = std::chrono::steady_clock::now();
  if (options_.diagnostics_period_s <= 0 ||
      now - last_diagnostics_ >= std::chrono::duration<double>(options_.diagnostics_period_s)) {
    PublishDiagnostics(p.t_ns());
  }
}

void PosePublisher::Tick() {
  std::lock_guard lock(mu_);
  const auto now = std::chrono::steady_clock::now();
  const double period_s = options_.diagnostics_period_s > 0 ? options_.diagnostics_period_s : 1.0;
  if (now - last_diagnostics_ < std::chrono::duration<double>(period_s)) return;
  PublishDiagnostics(last_ ? last_->t_ns() : UnixNowNs());
}

void PosePublisher::PublishDiagnostics(int64_t t_ns) {
  last_diagnostics_ = std::chrono::steady_clock::now();
  if (!writers_[Index(PoseTopic::kDiagnostics)]) return;
  std::vector<output::DiagnosticStatus> statuses;
  if (last_) statuses.push_back(output::PoseStatus(*last_));
  if (options_.extra_status) {
    for (auto& s : options_.extra_status()) statuses.push_back(std::move(s));
  }
  if (statuses.empty()) return;
  output::EncodeDiagnosticArray(t_ns, statuses, cdr_);
  Write(PoseTopic::kDiagnostics);
}

int PosePublisher::matched(PoseTopic t) const {
  const auto& writer = writers_[Index(t)];
  return writer ? writer->matched() : 0;
}

PosePublisher::Stats PosePublisher::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

}  // namespace locaid::ros2
