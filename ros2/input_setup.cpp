#include "ros2/input_setup.hpp"

#include "output/live_source.hpp"
#include "ros/cdr.hpp"
#include "ros/sensor_setup.hpp"

#include <stdexcept>

namespace locaid::ros2 {
namespace {

constexpr const char* kRoleKeys[kInputRoleCount] = {"left_image", "right_image", "left_info", "right_info",
                                                    "imu",        "gps",         "speed",     "tf_static"};
constexpr const char* kTfStaticTopic = "/tf_static";

size_t Index(InputRole r) { return static_cast<size_t>(r); }

// bag::ChooseTopics speaks of the bag's flag; the file here is --inputs.
std::string ForInputs(std::string text) {
  for (size_t at = text.find("--bag-topics FILE"); at != std::string::npos; at = text.find("--bag-topics FILE", at))
    text.replace(at, 17, "--inputs FILE");
  for (size_t at = text.find("in the bag"); at != std::string::npos; at = text.find("in the bag", at))
    text.replace(at, 10, "among the publications");
  return text;
}

bool Given(const std::string& topic) { return !topic.empty(); }

}  // namespace

const char* InputRoleKey(InputRole role) { return kRoleKeys[Index(role)]; }

v1::LiveSource InputRig::live() const {
  v1::LiveSource l = output::LiveSourceOf(rectified->camera, T_cam0_imu);
  for (int i = 0; i < 3; ++i) l.add_gps_antenna_body_m(lever_arm_body_m[i]);
  l.set_no_imu(!has_imu);
  return l;
}

InputSetup::InputSetup(bag::BagTopics given, InputSetupOptions options)
    : given_(std::move(given)), options_(options) {}

void InputSetup::AddPublication(const std::string& topic, const std::string& type) {
  publications_.emplace(topic, type);
}

std::map<std::string, std::string> InputSetup::WantedTopics() const {
  std::map<std::string, std::string> out;
  if (!chosen_) {
    for (const auto& [topic, type] : publications_)
      if (type == ros::kCameraInfo) out.emplace(topic, type);
    for (const std::string* named : {&given_.left_info, &given_.right_info})
      if (Given(*named)) out.emplace(*named, std::string(ros::kCameraInfo));
    return out;
  }
  for (size_t i = 0; i < kInputRoleCount; ++i)
    if (!topics_.topic[i].empty()) out.emplace(topics_.topic[i], topics_.type[i]);
  return out;
}

void InputSetup::AddMessage(const std::string& topic, std::string_view cdr) {
  try {
    const auto type = TypeOf(topic, "");
    if (type == ros::kCameraInfo) {
      if (!infos_.count(topic)) infos_.emplace(topic, ros::DecodeCameraInfo(cdr));
    } else if (type == ros::kTfMessage) {
      for (auto& t : ros::DecodeTfMessage(cdr)) static_transforms_.push_back(std::move(t));
    } else if (!frames_.count(topic) && (type == ros::kImu || type == ros::kNavSatFix)) {
      frames_.emplace(topic, ros::DecodeHeader(cdr).frame_id);
    }
  } catch (const ros::CdrError&) {
    // Counted once the session runs; here the next message will do.
  }
}

std::string InputSetup::TypeOf(const std::string& topic, const std::string& fallback) const {
  if (topic == kTfStaticTopic) return std::string(ros::kTfMessage);
  const auto it = publications_.find(topic);
  if (it != publications_.end()) return it->second;
  if (topic == given_.left_info || topic == given_.right_info) return std::string(ros::kCameraInfo);
  if (topic == given_.imu) return std::string(ros::kImu);
  if (topic == given_.gps) return std::string(ros::kNavSatFix);
  for (size_t i = 0; i < kInputRoleCount; ++i)
    if (topics_.topic[i] == topic) return topics_.type[i];
  return fallback;
}

bool InputSetup::Choose(double elapsed_s, std::string* missing) {
  const bool all_named = Given(given_.left_image) && Given(given_.left_info) && Given(given_.right_image) &&
                         Given(given_.right_info) && Given(given_.imu) && Given(given_.gps) && Given(given_.speed);
  if (!all_named && elapsed_s < options_.discovery_s) {
    *missing = "looking for topics (" + std::to_string(publications_.size()) + " publications discovered)";
    return false;
  }
  bag::BagInventory inv;  // what discovery saw; never complete (publishers come and go)
  for (const auto& [topic, type] : publications_) {
    bag::TopicSummary& s = inv.topics[topic];
    s.topic = topic;
    s.type = type;
    s.count = 1;
    if (const auto it = infos_.find(topic); it != infos_.end()) s.camera_info = it->second;
  }
  bag::BagTopics chosen;
  try {
    chosen = bag::ChooseTopics(inv, given_);
  } catch (const std::runtime_error& e) {
    const std::string why = ForInputs(e.what());
    if (elapsed_s < options_.setup_timeout_s) {
      *missing = "choosing topics: " + why;
      return false;
    }
    throw std::runtime_error("cannot choose the input topics: " + why);
  }
  const auto set = [&](InputRole r, const std::string& topic, const std::string& guessed_type) {
    const auto discovered = publications_.find(topic);
    topics_.topic[Index(r)] = topic;
    topics_.type[Index(r)] = topic.empty() ? "" : discovered != publications_.end() ? discovered->second : guessed_type;
  };
  const auto image_type = [](const std::string& topic) {
    return std::string(topic.size() > 11 && topic.substr(topic.size() - 11) == "/compressed" ? ros::kCompressedImage
                                                                                             : ros::kImage);
  };
  set(InputRole::kLeftImage, chosen.left_image, image_type(chosen.left_image));
  set(InputRole::kRightImage, chosen.right_image, image_type(chosen.right_image));
  set(InputRole::kLeftInfo, chosen.left_info, std::string(ros::kCameraInfo));
  set(InputRole::kRightInfo, chosen.right_info, std::string(ros::kCameraInfo));
  set(InputRole::kImu, chosen.imu, std::string(ros::kImu));
  set(InputRole::kGps, chosen.gps, std::string(ros::kNavSatFix));
  set(InputRole::kSpeed, chosen.speed, std::string(ros::kTwistStamped));
  set(InputRole::kTfStatic, kTfStaticTopic, std::string(ros::kTfMessage));
  chosen_ = true;
  chosen_at_s_ = elapsed_s;
  return true;
}

std::optional<InputRig> InputSetup::TryFinish(double elapsed_s, std::string* missing) {
  if (!chosen_ && !Choose(elapsed_s, missing)) return std::nullopt;
  const bool timed_out = elapsed_s >= options_.setup_timeout_s;
  const auto wait_for = [&](const std::string& what) -> std::optional<InputRig> {
    *missing = what;
    if (timed_out) {
      throw std::runtime_error(what + " within " + std::to_string(static_cast<int>(options_.setup_timeout_s)) +
                               " s (--setup-timeout-s)");
    }
    return std::nullopt;
  };
  const std::string& left_topic = topics_.topic_of(InputRole::kLeftInfo);
  const std::string& right_topic = topics_.topic_of(InputRole::kRightInfo);
  for (const std::string* t : {&left_topic, &right_topic}) {
    if (!infos_.count(*t)) return wait_for("no CameraInfo on " + *t);
  }
  const std::string& imu_topic = topics_.topic_of(InputRole::kImu);
  if (!imu_topic.empty() && !frames_.count(imu_topic)) {
    return wait_for("no message on " + imu_topic + " (the IMU's frame_id is the body frame)");
  }
  InputRig rig;
  rig.left_info = infos_.at(left_topic);
  rig.right_info = infos_.at(right_topic);
  const std::string& cam_frame = rig.left_info.header.frame_id;
  if (!imu_topic.empty()) {
    const std::string& imu_frame = frames_.at(imu_topic);
    const auto T = ros::CameraImuExtrinsic(rig.left_info, static_transforms_, imu_frame);
    if (!T) {
      return wait_for("/tf_static does not connect the IMU frame '" + imu_frame + "' and the left camera frame '" +
                      cam_frame + "' (the camera-IMU extrinsic): publish it, or set imu: none in --inputs FILE");
    }
    rig.T_cam0_imu = *T;
    rig.has_imu = true;
    rig.notes.push_back("camera-IMU extrinsic from /tf_static: " + imu_frame + " -> " + cam_frame);
  } else {
    rig.T_cam0_imu = ros::CameraBodyWithoutImu();
    rig.notes.push_back("no IMU topic: the body frame is the rectified left camera turned x forward");
  }
  const std::string& gps_topic = topics_.topic_of(InputRole::kGps);
  if (!gps_topic.empty()) {
    if (!frames_.count(gps_topic)) {
      if (elapsed_s < chosen_at_s_ + options_.discovery_s) return wait_for("no NavSatFix yet on " + gps_topic);
      rig.notes.push_back("no NavSatFix on " + gps_topic + " before the session: antenna lever arm taken as zero");
    } else if (const auto arm = ros::GpsLeverArm(rig.left_info, static_transforms_, rig.T_cam0_imu,
                                                 frames_.at(gps_topic))) {
      rig.lever_arm_body_m = *arm;
      rig.notes.push_back("GPS antenna lever arm from /tf_static: " + frames_.at(gps_topic));
    } else {
      rig.notes.push_back("no /tf_static transform to the GPS frame '" + frames_.at(gps_topic) +
                          "': antenna lever arm taken as zero");
    }
  }
  try {
    auto rectified = std::make_shared<ros::RectifiedStereo>(ros::MakeRectifiedStereo(rig.left_info, rig.right_info));
    rig.notes.push_back(rectified->note);
    rig.rectified = std::move(rectified);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(left_topic + " / " + right_topic + ": " + e.what());
  }
  missing->clear();
  return rig;
}

}  // namespace locaid::ros2
