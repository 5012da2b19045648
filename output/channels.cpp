#include "output/channels.hpp"

#include "output/enum_names.hpp"
#include "output/json_schemas.hpp"
#include "output/static_transforms.hpp"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <cmath>
#include <functional>
#include <limits>
#include <set>
#include <string_view>
#include <utility>

namespace locaid::output {
namespace {

using nlohmann::json;

constexpr const char* kEnuFrame = "enu";
constexpr const char* kBodyFrame = "base_link";

ChannelSpec JsonChannel(const char* topic, const char* schema_name, std::string schema) {
  return {topic, "json", schema_name, "jsonschema", std::move(schema)};
}

// Bodies are refilled for every pose: each Put* reuses the member already
// there (assigning a number in place allocates nothing), so converting a
// pose builds no JSON trees after the first one. The first call on an empty
// body creates the member; every body's shape is fixed per schema, so no
// member of an earlier pose is ever left behind.
json& Member(json& object, std::string_view key) {
  if (auto it = object.find(key); it != object.end()) return *it;
  return object[std::string(key)];
}
void Put(json& object, std::string_view key, double value) { Member(object, key) = value; }
void PutInt(json& object, std::string_view key, int64_t value) { Member(object, key) = value; }
void PutUint(json& object, std::string_view key, uint64_t value) { Member(object, key) = value; }
void PutBool(json& object, std::string_view key, bool value) { Member(object, key) = value; }
// JSON has no infinity: +Infinity (no fix yet) and NaN become null.
void PutFiniteOrNull(json& object, std::string_view key, double value) {
  json& m = Member(object, key);
  if (std::isfinite(value)) {
    m = value;
  } else {
    m = nullptr;
  }
}
// A string member is reassigned in place (its buffer reused).
void PutString(json& object, std::string_view key, std::string_view value) {
  json& m = Member(object, key);
  if (m.is_string()) {
    m.get_ref<std::string&>().assign(value);
  } else {
    m = std::string(value);
  }
}
// Element k of an array member, growing it on the first fill.
json& Element(json& array, size_t k) {
  if (!array.is_array()) array = json::array();
  while (array.size() <= k) array.push_back(nullptr);
  return array[k];
}

void PutXyz(json& object, std::string_view key, double x, double y, double z) {
  json& m = Member(object, key);
  Put(m, "x", x);
  Put(m, "y", y);
  Put(m, "z", z);
}
void PutVector3(json& object, std::string_view key, const v1::Vector3& v) { PutXyz(object, key, v.x(), v.y(), v.z()); }
void PutQuaternion(json& object, std::string_view key, double x, double y, double z, double w) {
  json& m = Member(object, key);
  Put(m, "x", x);
  Put(m, "y", y);
  Put(m, "z", z);
  Put(m, "w", w);
}
void PutQuaternion(json& object, std::string_view key, const v1::Quaternion& q) {
  PutQuaternion(object, key, q.x(), q.y(), q.z(), q.w());
}
void PutPose(json& object, std::string_view key, const v1::Vector3& position, const v1::Quaternion& orientation) {
  json& m = Member(object, key);
  PutVector3(m, "position", position);
  PutQuaternion(m, "orientation", orientation);
}
void PutTime(json& object, int64_t t_ns) { TimeJson(t_ns, Member(object, "timestamp")); }

struct Rgba {
  double r, g, b;
};
void PutColor(json& object, Rgba c) {
  json& m = Member(object, "color");
  Put(m, "r", c.r);
  Put(m, "g", c.g);
  Put(m, "b", c.b);
  Put(m, "a", 1.0);
}

void PutLocationFix(json& body, int64_t t_ns, const char* frame_id, double lat, double lon, double alt,
                    const std::array<double, 9>& covariance, int covariance_type, Rgba color) {
  PutTime(body, t_ns);
  PutString(body, "frame_id", frame_id);
  Put(body, "latitude", lat);
  Put(body, "longitude", lon);
  Put(body, "altitude", alt);
  json& c = Member(body, "position_covariance");
  for (size_t k = 0; k < covariance.size(); ++k) Element(c, k) = covariance[k];
  PutInt(body, "position_covariance_type", covariance_type);
  PutColor(body, color);
}

OutMessage Json(Topic topic, int64_t t_ns, const json& body) {
  return {topic, static_cast<uint64_t>(std::max<int64_t>(t_ns, 0)), body.dump()};
}

}  // namespace

const std::vector<ChannelSpec>& Channels() {
  static const std::vector<ChannelSpec> table = [] {
    std::vector<ChannelSpec> t(static_cast<size_t>(Topic::kCount));
    auto set = [&t](Topic topic, ChannelSpec spec) { t[static_cast<size_t>(topic)] = std::move(spec); };
    set(Topic::kPose, JsonChannel("/locaid/pose", "foxglove.PoseInFrame", schemas::PoseInFrame()));
    set(Topic::kTf, JsonChannel("/tf", "foxglove.FrameTransforms", schemas::FrameTransforms()));
    set(Topic::kFix, JsonChannel("/locaid/fix", "foxglove.LocationFix", schemas::LocationFix()));
    set(Topic::kGps, JsonChannel("/locaid/gps", "foxglove.LocationFix", schemas::LocationFix()));
    set(Topic::kTruth, JsonChannel("/locaid/truth", "foxglove.PoseInFrame", schemas::PoseInFrame()));
    set(Topic::kTruthFix, JsonChannel("/locaid/truth_fix", "foxglove.LocationFix", schemas::LocationFix()));
    set(Topic::kPath, JsonChannel("/locaid/path", "foxglove.PosesInFrame", schemas::PosesInFrame()));
    set(Topic::kStatus, JsonChannel("/locaid/status", "locaid.Status", schemas::Status()));
    set(Topic::kUpdate, {"/locaid/update", "protobuf", v1::PoseUpdate::descriptor()->full_name(), "protobuf",
                         PoseUpdateDescriptorSet()});
    return t;
  }();
  return table;
}

const ChannelSpec& Channel(Topic topic) { return Channels().at(static_cast<size_t>(topic)); }

std::string PoseUpdateDescriptorSet() {
  google::protobuf::FileDescriptorSet set;
  std::set<std::string> added;
  // Dependencies first, each file once, as protobuf descriptor pools expect.
  std::function<void(const google::protobuf::FileDescriptor*)> add = [&](const google::protobuf::FileDescriptor* f) {
    if (!added.insert(f->name()).second) return;
    for (int i = 0; i < f->dependency_count(); ++i) add(f->dependency(i));
    f->CopyTo(set.add_file());
  };
  add(v1::PoseUpdate::descriptor()->file());
  return set.SerializeAsString();
}

void TimeJson(int64_t t_ns, json& body) {
  const int64_t t = std::max<int64_t>(t_ns, 0);
  PutInt(body, "sec", t / 1'000'000'000);
  PutInt(body, "nsec", t % 1'000'000'000);
}

std::array<double, 9> PositionCovarianceEnu(const v1::PoseUpdate& p) {
  std::array<double, 9> c{};
  if (p.covariance_size() != 36) return c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c[static_cast<size_t>(r * 3 + k)] = p.covariance(r * 6 + k);
  }
  return c;
}

void PoseInFrameJson(int64_t t_ns, const v1::Vector3& position, const v1::Quaternion& orientation, json& body) {
  PutTime(body, t_ns);
  PutString(body, "frame_id", kEnuFrame);
  PutPose(body, "pose", position, orientation);
}

void FrameTransformsJson(const v1::PoseUpdate& p, json& body) {
  json& transforms = Member(body, "transforms");
  json& vehicle = Element(transforms, 0);
  PutTime(vehicle, p.t_ns());
  PutString(vehicle, "parent_frame_id", kEnuFrame);
  PutString(vehicle, "child_frame_id", kBodyFrame);
  PutVector3(vehicle, "translation", p.position_enu_m());
  PutQuaternion(vehicle, "rotation", p.orientation_enu_body());
  // The camera mount is static; it rides along with every update so a
  // viewer that joins late (or seeks in a recording) always has it.
  const StaticTransform& cam = BaseLinkToCam0();
  json& camera = Element(transforms, 1);
  PutTime(camera, p.t_ns());
  PutString(camera, "parent_frame_id", kBodyFrame);
  PutString(camera, "child_frame_id", "cam0");
  PutXyz(camera, "translation", cam.translation[0], cam.translation[1], cam.translation[2]);
  PutQuaternion(camera, "rotation", cam.rotation_xyzw[0], cam.rotation_xyzw[1], cam.rotation_xyzw[2],
                cam.rotation_xyzw[3]);
}

void FusedFixJson(const v1::PoseUpdate& p, json& body) {
  const bool known = p.covariance_size() == 36;
  PutLocationFix(body, p.t_ns(), kBodyFrame, p.latitude_deg(), p.longitude_deg(), p.altitude_m(),
                 PositionCovarianceEnu(p), known ? 3 : 0, {0.1, 0.4, 1.0});
}

void GpsFixJson(const v1::GpsFixSeen& fix, json& body) {
  const double h2 = fix.sigma_horizontal_m() * fix.sigma_horizontal_m();
  const double v2 = fix.sigma_vertical_m() * fix.sigma_vertical_m();
  // Green: fused by the filter; red: refused by its gate (or before it ran).
  PutLocationFix(body, fix.t_ns(), "gps", fix.latitude_deg(), fix.longitude_deg(), fix.altitude_m(),
                 {h2, 0, 0, 0, h2, 0, 0, 0, v2}, 2, fix.used() ? Rgba{0.1, 0.8, 0.2} : Rgba{0.9, 0.1, 0.1});
  const std::pair<const char*, std::string> entries[] = {{"used", fix.used() ? "true" : "false"},
                                                         {"rejected_vertical", fix.rejected_vertical() ? "true" : "false"},
                                                         {"nis", std::to_string(fix.nis())},
                                                         {"gate", std::to_string(fix.gate())}};
  json& metadata = Member(body, "metadata");
  for (size_t k = 0; k < std::size(entries); ++k) {
    json& entry = Element(metadata, k);
    PutString(entry, "key", entries[k].first);
    PutString(entry, "value", entries[k].second);
  }
}

void TruthFixJson(const v1::PoseUpdate& p, json& body) {
  PutLocationFix(body, p.t_ns(), kBodyFrame, p.truth_latitude_deg(), p.truth_longitude_deg(), p.truth_altitude_m(), {},
                 0, {1.0, 0.6, 0.0});
}

void StatusJson(const v1::PoseUpdate& p, json& body) {
  PutTime(body, p.t_ns());
  PutString(body, "session_id", p.session_id());
  PutUint(body, "sequence", p.sequence());
  PutInt(body, "frame_index", p.frame_index());
  PutString(body, "mode", ModeName(p.mode()));
  PutString(body, "vo_status", VoStatusName(p.vo_status()));
  PutInt(body, "vo_inliers", p.vo_inliers());
  PutString(body, "vo_health", VoHealthName(p.vo_health()));
  PutUint(body, "speed_samples_used", p.speed_samples_used());
  Put(body, "speed_scale_error", p.speed_scale_error());
  Member(body, "vo_noise_scale") = std::vector<double>(p.noise().vo_scale().begin(), p.noise().vo_scale().end());
  Put(body, "gps_noise_scale_horizontal", p.noise().gps_horizontal_scale());
  Put(body, "gps_noise_scale_vertical", p.noise().gps_vertical_scale());
  PutBool(body, "vo_noise_learning", p.noise().vo_learning());
  PutFiniteOrNull(body, "seconds_since_gps", p.seconds_since_gps());
  PutBool(body, "gps_outage_active", p.gps_outage_active());
  PutUint(body, "gps_used", p.gps_used());
  PutUint(body, "gps_rejected", p.gps_rejected());
  PutUint(body, "gps_resets", p.gps_resets());
  PutBool(body, "has_truth", p.has_truth());
  PutFiniteOrNull(body, "horizontal_error_m",
                  p.has_truth() ? p.horizontal_error_m() : std::numeric_limits<double>::quiet_NaN());
  Put(body, "processing_latency_ms", p.processing_latency_ms());
  Put(body, "behind_real_time_s", p.behind_real_time_s());
  PutBool(body, "falling_behind", p.falling_behind());
}

PoseConverter::PoseConverter(PathOptions options) : options_(options) { Reset(); }

void PoseConverter::Reset() {
  path_.clear();
  path_text_.clear();
  spacing_ns_ = options_.spacing_ns;
  last_path_t_ns_ = 0;
  last_path_sent_ns_ = 0;
}

std::vector<OutMessage> PoseConverter::Convert(const v1::PoseUpdate& p) {
  std::vector<OutMessage> out;
  out.reserve(static_cast<size_t>(Topic::kCount) + static_cast<size_t>(p.gps_fixes_size()));
  const int64_t t = p.t_ns();
  auto body = [this](Topic topic) -> json& { return bodies_[static_cast<size_t>(topic)]; };
  // LOST: the filter has no position yet (or only a prediction), so the map
  // and the track leave it out; pose, tf and status still show the state.
  const bool has_position = p.mode() != v1::MODE_LOST;
  PoseInFrameJson(t, p.position_enu_m(), p.orientation_enu_body(), body(Topic::kPose));
  out.push_back(Json(Topic::kPose, t, body(Topic::kPose)));
  FrameTransformsJson(p, body(Topic::kTf));
  out.push_back(Json(Topic::kTf, t, body(Topic::kTf)));
  if (has_position) {
    FusedFixJson(p, body(Topic::kFix));
    out.push_back(Json(Topic::kFix, t, body(Topic::kFix)));
  }
  for (const auto& fix : p.gps_fixes()) {
    GpsFixJson(fix, body(Topic::kGps));
    out.push_back(Json(Topic::kGps, fix.t_ns(), body(Topic::kGps)));
  }
  if (p.has_truth()) {
    PoseInFrameJson(t, p.truth_position_enu_m(), p.truth_orientation_enu_body(), body(Topic::kTruth));
    out.push_back(Json(Topic::kTruth, t, body(Topic::kTruth)));
    TruthFixJson(p, body(Topic::kTruthFix));
    out.push_back(Json(Topic::kTruthFix, t, body(Topic::kTruthFix)));
  }
  if (has_position && GrowPath(p) && PathDue(p.t_ns())) {
    out.push_back({Topic::kPath, static_cast<uint64_t>(std::max<int64_t>(t, 0)), PathText(t)});
    last_path_sent_ns_ = p.t_ns();
  }
  StatusJson(p, body(Topic::kStatus));
  out.push_back(Json(Topic::kStatus, t, body(Topic::kStatus)));
  out.push_back({Topic::kUpdate, static_cast<uint64_t>(std::max<int64_t>(t, 0)), p.SerializeAsString()});
  return out;
}

bool PoseConverter::GrowPath(const v1::PoseUpdate& p) {
  if (!path_.empty() && p.t_ns() - last_path_t_ns_ < spacing_ns_) return false;
  if (path_.size() >= options_.max_poses) {
    // Keep poses 0, 2, 4, ...: the same shape at half the density.
    size_t kept = 0;
    for (size_t i = 0; i < path_.size(); i += 2) path_[kept++] = std::move(path_[i]);
    path_.resize(kept);
    spacing_ns_ *= 2;
    path_text_.clear();
    for (const std::string& pose : path_) AppendPathText(pose);
  }
  json pose;
  PutVector3(pose, "position", p.position_enu_m());
  PutQuaternion(pose, "orientation", p.orientation_enu_body());
  path_.push_back(pose.dump());
  AppendPathText(path_.back());
  last_path_t_ns_ = p.t_ns();
  return true;
}

void PoseConverter::AppendPathText(const std::string& pose) {
  if (!path_text_.empty()) path_text_ += ',';
  path_text_ += pose;
}

bool PoseConverter::PathDue(int64_t t_ns) const {
  // The whole track goes out each time, so it goes out less often as it
  // grows: at most every path_size x 10 ms of sensor time (a 3600-pose track
  // every 36 s). That bounds its cost to ~100 poses of JSON per second of
  // drive, live and in recordings, whatever the drive's length.
  const auto interval_ns = std::max<int64_t>(options_.spacing_ns, static_cast<int64_t>(path_.size()) * 10'000'000);
  return last_path_sent_ns_ == 0 || t_ns - last_path_sent_ns_ >= interval_ns;
}

std::string PoseConverter::PathText(int64_t t_ns) const {
  // Each pose is serialized (by nlohmann) once, when it joins the track; the
  // message is those texts inside the PosesInFrame object, so sending the
  // track costs a copy, not a serialization of every pose again.
  json time;
  TimeJson(t_ns, time);
  std::string text = R"({"frame_id":")";
  text += kEnuFrame;
  text += R"(","poses":[)";
  text += path_text_;
  text += R"(],"timestamp":)";
  text += time.dump();
  text += '}';
  return text;
}

}  // namespace locaid::output
