#include "bag/bag_topics.hpp"

#include "bag/ros_bag.hpp"
#include "ros/cdr.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>

namespace locaid::bag {
namespace {

bool IsImage(const std::string& type) { return type == ros::kImage || type == ros::kCompressedImage; }

bool EndsWith(std::string_view s, std::string_view tail) {
  return s.size() >= tail.size() && s.substr(s.size() - tail.size()) == tail;
}

// The header of a message of a known stamped type (stamp 0 when none).
ros::Header HeaderOf(std::string_view type, std::string_view data) {
  if (type == ros::kTfMessage) {
    const auto tf = ros::DecodeTfMessage(data);
    return tf.empty() ? ros::Header{} : tf.front().header;
  }
  if (type == ros::kImage || type == ros::kCompressedImage || type == ros::kCameraInfo || type == ros::kImu ||
      type == ros::kNavSatFix || type == ros::kTwistStamped) {
    return ros::DecodeHeader(data);
  }
  return {};
}

// "/cam/left/image_raw/compressed" -> "/cam/left": the camera namespace of an
// image or camera_info topic.
std::string CameraNamespace(const std::string& topic, const std::string& type) {
  std::string t = topic;
  if (type == ros::kCompressedImage) t = t.substr(0, t.rfind('/'));
  const auto slash = t.rfind('/');
  return slash == std::string::npos ? std::string() : t.substr(0, slash);
}

std::vector<std::string> OfType(const BagInventory& inv, std::string_view type) {
  std::vector<std::string> out;
  for (const auto& [topic, s] : inv.topics)
    if (s.type == type) out.push_back(topic);
  return out;
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

void Check(const BagInventory& inv, const std::string& key, const std::string& topic,
           const std::vector<std::string_view>& types) {
  const auto it = inv.topics.find(topic);
  if (it == inv.topics.end()) {
    if (inv.complete) throw std::runtime_error(key + ": topic " + topic + " is not in the bag");
    return;  // a preview may not have reached it yet
  }
  if (std::find(types.begin(), types.end(), it->second.type) == types.end())
    throw std::runtime_error(key + ": topic " + topic + " has type " + it->second.type);
}

// The one topic of `type`, or "" when there is none; throws when several.
std::string Unique(const BagInventory& inv, std::string_view type, const std::string& key) {
  const auto topics = OfType(inv, type);
  if (topics.size() > 1) {
    throw std::runtime_error("several " + std::string(type) + " topics (" + Join(topics) + "): name the one to use as '" +
                             key + ":' in --bag-topics FILE (or 'none')");
  }
  return topics.empty() ? std::string() : topics.front();
}

}  // namespace

double TopicSummary::rate_hz() const {
  if (stamped < 2 || last_stamp_ns <= first_stamp_ns) return 0;
  return static_cast<double>(stamped - 1) / (static_cast<double>(last_stamp_ns - first_stamp_ns) * 1e-9);
}

BagInventory ScanBag(RosBag& bag, uint64_t max_log_span_ns, const std::function<void(double)>& progress) {
  BagInventory inv;
  BagMessage m;
  bool first = true;
  uint64_t t0 = 0, n = 0;
  for (;;) {
    if (!bag.Next(m)) {
      inv.complete = true;
      break;
    }
    if (first) t0 = m.log_time_ns, first = false;
    if (max_log_span_ns > 0 && m.log_time_ns > t0 + max_log_span_ns) break;
    TopicSummary& s = inv.topics[std::string(m.topic)];
    if (s.count == 0) s.topic = std::string(m.topic), s.type = std::string(m.type);
    ++s.count;
    try {
      const ros::Header header = HeaderOf(m.type, m.data);
      const int64_t stamp = header.stamp_ns;
      if (stamp != 0) {
        if (s.stamped == 0) s.frame_id = header.frame_id;
        if (s.stamped == 0 || stamp < s.first_stamp_ns) s.first_stamp_ns = stamp;
        s.last_stamp_ns = std::max(s.last_stamp_ns, stamp);
        ++s.stamped;
      }
      if (m.type == ros::kCameraInfo && !s.camera_info) s.camera_info = ros::DecodeCameraInfo(m.data);
      if (m.type == ros::kTfMessage && EndsWith(m.topic, "tf_static")) {
        for (auto& t : ros::DecodeTfMessage(m.data)) inv.static_transforms.push_back(std::move(t));
      }
    } catch (const ros::CdrError&) {
      ++s.undecodable;
    }
    if (progress && ++n % 2000 == 0 && bag.total_bytes() > 0)
      progress(static_cast<double>(bag.bytes_done()) / static_cast<double>(bag.total_bytes()));
  }
  inv.notes = bag.notes();
  return inv;
}

BagTopics LoadBagTopics(const std::filesystem::path& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path.string() + ": " + e.what());
  }
  BagTopics t;
  if (!root || root.IsNull()) return t;
  if (!root.IsMap()) throw std::runtime_error(path.string() + ": expected a map of topic names");
  const std::map<std::string, std::string*> keys = {
      {"left_image", &t.left_image}, {"left_info", &t.left_info}, {"right_image", &t.right_image},
      {"right_info", &t.right_info}, {"imu", &t.imu},             {"gps", &t.gps},
      {"speed", &t.speed}};
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>("");
    const auto it = keys.find(key);
    if (it == keys.end()) {
      std::string known;
      for (const auto& [k, v] : keys) known += (known.empty() ? "" : ", ") + k;
      throw std::runtime_error(path.string() + ": unknown key '" + key + "' (known: " + known + ")");
    }
    if (!kv.second.IsScalar() || kv.second.as<std::string>("").empty())
      throw std::runtime_error(path.string() + ": " + key + " must be a topic name (or none)");
    *it->second = kv.second.as<std::string>();
  }
  return t;
}

BagTopics ChooseTopics(const BagInventory& inv, BagTopics t) {
  const std::vector<std::string_view> image_types = {ros::kImage, ros::kCompressedImage};
  // Cameras: every camera_info topic with an image topic in its namespace.
  if (t.left_image.empty() || t.left_info.empty() || t.right_image.empty() || t.right_info.empty()) {
    struct Camera {
      std::string info, image;
      double tx = 0;
    };
    std::vector<Camera> cameras;
    std::vector<std::string> without_image;
    for (const auto& info_topic : OfType(inv, ros::kCameraInfo)) {
      const auto& s = inv.topics.at(info_topic);
      const std::string ns = CameraNamespace(info_topic, s.type);
      std::vector<std::string> images;
      for (const auto& [topic, is] : inv.topics)
        if (IsImage(is.type) && CameraNamespace(topic, is.type) == ns) images.push_back(topic);
      // image_transport records raw and compressed side by side: the raw one wins.
      if (images.size() > 1) {
        std::vector<std::string> raw;
        for (const auto& i : images)
          if (inv.topics.at(i).type == ros::kImage) raw.push_back(i);
        if (raw.size() == 1) images = raw;
      }
      if (images.size() > 1) {
        throw std::runtime_error("camera " + ns + " has several image topics (" + Join(images) +
                                 "): name them as left_image / right_image in --bag-topics FILE");
      }
      if (images.empty()) {
        without_image.push_back(info_topic);
        continue;
      }
      cameras.push_back({info_topic, images.front(), s.camera_info ? s.camera_info->p[3] : 0.0});
    }
    if (cameras.size() != 2) {
      std::string found;
      for (const auto& c : cameras) found += (found.empty() ? "" : "; ") + c.image + " + " + c.info;
      throw std::runtime_error(
          "found " + std::to_string(cameras.size()) + " camera(s) with an image and a camera_info topic (" +
          (found.empty() ? std::string("none") : found) + (without_image.empty() ? "" : "; camera_info without images: " + Join(without_image)) +
          "), need a stereo pair: name left_image, left_info, right_image, right_info in --bag-topics FILE");
    }
    // The right camera's P[3] = -fx * baseline < 0; the left's is 0.
    std::sort(cameras.begin(), cameras.end(), [](const Camera& a, const Camera& b) { return a.tx > b.tx; });
    if (!(cameras[1].tx < cameras[0].tx)) {
      throw std::runtime_error("cameras " + cameras[0].info + " and " + cameras[1].info +
                               " have the same P[3]: cannot tell left from right (name them in --bag-topics FILE)");
    }
    if (t.left_image.empty()) t.left_image = cameras[0].image;
    if (t.left_info.empty()) t.left_info = cameras[0].info;
    if (t.right_image.empty()) t.right_image = cameras[1].image;
    if (t.right_info.empty()) t.right_info = cameras[1].info;
  }
  Check(inv, "left_image", t.left_image, image_types);
  Check(inv, "right_image", t.right_image, image_types);
  Check(inv, "left_info", t.left_info, {ros::kCameraInfo});
  Check(inv, "right_info", t.right_info, {ros::kCameraInfo});
  const auto optional = [&](std::string& topic, std::string_view type, const char* key) {
    if (topic == "none") {
      topic.clear();
    } else if (topic.empty()) {
      topic = Unique(inv, type, key);
    } else {
      Check(inv, key, topic, {type});
    }
  };
  optional(t.imu, ros::kImu, "imu");
  optional(t.gps, ros::kNavSatFix, "gps");
  optional(t.speed, ros::kTwistStamped, "speed");
  return t;
}

std::string DescribeInventory(const BagInventory& inv, const BagTopics* choice, const std::string& why_not) {
  std::ostringstream out;
  char line[512];
  std::snprintf(line, sizeof line, "%-40s %-34s %8s %9s %8s  %s\n", "topic", "type", "count", "rate Hz", "span s",
                "use");
  out << line;
  const std::map<std::string, std::string> roles =
      choice ? std::map<std::string, std::string>{{choice->left_image, "left image"}, {choice->left_info, "left camera_info"},
                                                  {choice->right_image, "right image"}, {choice->right_info, "right camera_info"},
                                                  {choice->imu, "imu"}, {choice->gps, "gps"}, {choice->speed, "speed"}}
             : std::map<std::string, std::string>{};
  for (const auto& [topic, s] : inv.topics) {
    const auto role = roles.find(topic);
    const double span = s.stamped > 1 ? static_cast<double>(s.last_stamp_ns - s.first_stamp_ns) * 1e-9 : 0;
    std::snprintf(line, sizeof line, "%-40s %-34s %8llu %9.2f %8.2f  %s%s\n", topic.c_str(), s.type.c_str(),
                  static_cast<unsigned long long>(s.count), s.rate_hz(), span,
                  role != roles.end() && !topic.empty() ? role->second.c_str() : "-",
                  s.undecodable ? (" (" + std::to_string(s.undecodable) + " undecodable)").c_str() : "");
    out << line;
  }
  for (const auto& note : inv.notes) out << "note: " << note << "\n";
  if (!inv.complete) out << "note: a preview of the bag's start, not the whole bag\n";
  if (!choice) out << "no topic choice: " << why_not << "\n";
  return out.str();
}

std::string InspectBag(const std::filesystem::path& path, const BagTopics& given,
                       const std::function<void(double)>& progress) {
  RosBag bag(path);
  const BagInventory inv = ScanBag(bag, 0, progress);
  std::string files;
  for (const auto& f : bag.files()) files += "file: " + f.string() + "\n";
  try {
    const BagTopics choice = ChooseTopics(inv, given);
    return files + DescribeInventory(inv, &choice, "");
  } catch (const std::runtime_error& e) {
    return files + DescribeInventory(inv, nullptr, e.what());
  }
}

}  // namespace locaid::bag
