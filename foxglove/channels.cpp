#include "foxglove/channels.hpp"

#include "foxglove/json_schemas.hpp"
#include "foxglove/static_transforms.hpp"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <cmath>
#include <functional>
#include <set>

namespace locaid::foxglove {
namespace {

using nlohmann::json;

constexpr const char* kEnuFrame = "enu";
constexpr const char* kBodyFrame = "base_link";

ChannelSpec JsonChannel(const char* topic, const char* schema_name, std::string schema) {
  return {topic, "json", schema_name, "jsonschema", std::move(schema)};
}

json Vector3Json(const v1::Vector3& v) { return {{"x", v.x()}, {"y", v.y()}, {"z", v.z()}}; }
json QuaternionJson(const v1::Quaternion& q) { return {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}}; }
json PoseJson(const v1::Vector3& position, const v1::Quaternion& orientation) {
  return {{"position", Vector3Json(position)}, {"orientation", QuaternionJson(orientation)}};
}

json Color(double r, double g, double b) { return {{"r", r}, {"g", g}, {"b", b}, {"a", 1.0}}; }

json LocationFixJson(int64_t t_ns, const char* frame_id, double lat, double lon, double alt,
                     const std::array<double, 9>& covariance, int covariance_type, json color) {
  return {{"timestamp", TimeJson(t_ns)},
          {"frame_id", frame_id},
          {"latitude", lat},
          {"longitude", lon},
          {"altitude", alt},
          {"position_covariance", covariance},
          {"position_covariance_type", covariance_type},
          {"color", std::move(color)}};
}

// JSON has no infinity: +Infinity (no fix yet) and NaN become null.
json FiniteOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// The enum value's name without its prefix: MODE_GPS_FUSED -> GPS_FUSED.
std::string EnumName(const std::string& full, const std::string& prefix) {
  return full.rfind(prefix, 0) == 0 ? full.substr(prefix.size()) : full;
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

json TimeJson(int64_t t_ns) {
  const int64_t t = std::max<int64_t>(t_ns, 0);
  return {{"sec", t / 1'000'000'000}, {"nsec", t % 1'000'000'000}};
}

std::array<double, 9> PositionCovarianceEnu(const v1::PoseUpdate& p) {
  std::array<double, 9> c{};
  if (p.covariance_size() != 36) return c;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c[static_cast<size_t>(r * 3 + k)] = p.covariance(r * 6 + k);
  }
  return c;
}

json PoseInFrameJson(int64_t t_ns, const v1::Vector3& position, const v1::Quaternion& orientation) {
  return {{"timestamp", TimeJson(t_ns)}, {"frame_id", kEnuFrame}, {"pose", PoseJson(position, orientation)}};
}

json FrameTransformsJson(const v1::PoseUpdate& p) {
  const StaticTransform& cam = BaseLinkToCam0();
  json body = {{"timestamp", TimeJson(p.t_ns())},
               {"parent_frame_id", kEnuFrame},
               {"child_frame_id", kBodyFrame},
               {"translation", Vector3Json(p.position_enu_m())},
               {"rotation", QuaternionJson(p.orientation_enu_body())}};
  // The camera mount is static; it rides along with every update so a
  // viewer that joins late (or seeks in a recording) always has it.
  json camera = {{"timestamp", TimeJson(p.t_ns())},
                 {"parent_frame_id", kBodyFrame},
                 {"child_frame_id", "cam0"},
                 {"translation", {{"x", cam.translation[0]}, {"y", cam.translation[1]}, {"z", cam.translation[2]}}},
                 {"rotation",
                  {{"x", cam.rotation_xyzw[0]},
                   {"y", cam.rotation_xyzw[1]},
                   {"z", cam.rotation_xyzw[2]},
                   {"w", cam.rotation_xyzw[3]}}}};
  return {{"transforms", {std::move(body), std::move(camera)}}};
}

json FusedFixJson(const v1::PoseUpdate& p) {
  const bool known = p.covariance_size() == 36;
  return LocationFixJson(p.t_ns(), kBodyFrame, p.latitude_deg(), p.longitude_deg(), p.altitude_m(),
                         PositionCovarianceEnu(p), known ? 3 : 0, Color(0.1, 0.4, 1.0));
}

json GpsFixJson(const v1::GpsFixSeen& fix) {
  const double h2 = fix.sigma_horizontal_m() * fix.sigma_horizontal_m();
  const double v2 = fix.sigma_vertical_m() * fix.sigma_vertical_m();
  // Green: fused by the filter; red: refused by its gate (or before it ran).
  json j = LocationFixJson(fix.t_ns(), "gps", fix.latitude_deg(), fix.longitude_deg(), fix.altitude_m(),
                           {h2, 0, 0, 0, h2, 0, 0, 0, v2}, 2, fix.used() ? Color(0.1, 0.8, 0.2) : Color(0.9, 0.1, 0.1));
  j["metadata"] = {{{"key", "used"}, {"value", fix.used() ? "true" : "false"}},
                   {{"key", "rejected_vertical"}, {"value", fix.rejected_vertical() ? "true" : "false"}},
                   {{"key", "nis"}, {"value", std::to_string(fix.nis())}},
                   {{"key", "gate"}, {"value", std::to_string(fix.gate())}}};
  return j;
}

json TruthFixJson(const v1::PoseUpdate& p) {
  return LocationFixJson(p.t_ns(), kBodyFrame, p.truth_latitude_deg(), p.truth_longitude_deg(), p.truth_altitude_m(),
                         {}, 0, Color(1.0, 0.6, 0.0));
}

json StatusJson(const v1::PoseUpdate& p) {
  return {{"timestamp", TimeJson(p.t_ns())},
          {"session_id", p.session_id()},
          {"sequence", p.sequence()},
          {"frame_index", p.frame_index()},
          {"mode", EnumName(v1::Mode_Name(p.mode()), "MODE_")},
          {"vo_status", EnumName(v1::VoStatus_Name(p.vo_status()), "VO_STATUS_")},
          {"vo_inliers", p.vo_inliers()},
          {"seconds_since_gps", FiniteOrNull(p.seconds_since_gps())},
          {"gps_outage_active", p.gps_outage_active()},
          {"gps_used", p.gps_used()},
          {"gps_rejected", p.gps_rejected()},
          {"gps_resets", p.gps_resets()},
          {"has_truth", p.has_truth()},
          {"horizontal_error_m", p.has_truth() ? FiniteOrNull(p.horizontal_error_m()) : json(nullptr)},
          {"processing_latency_ms", p.processing_latency_ms()}};
}

PoseConverter::PoseConverter(PathOptions options) : options_(options) { Reset(); }

void PoseConverter::Reset() {
  path_.clear();
  spacing_ns_ = options_.spacing_ns;
  last_path_t_ns_ = 0;
  last_path_sent_ns_ = 0;
}

std::vector<OutMessage> PoseConverter::Convert(const v1::PoseUpdate& p) {
  std::vector<OutMessage> out;
  const int64_t t = p.t_ns();
  // LOST: the filter has no position yet (or only a prediction), so the map
  // and the track leave it out; pose, tf and status still show the state.
  const bool has_position = p.mode() != v1::MODE_LOST;
  out.push_back(Json(Topic::kPose, t, PoseInFrameJson(t, p.position_enu_m(), p.orientation_enu_body())));
  out.push_back(Json(Topic::kTf, t, FrameTransformsJson(p)));
  if (has_position) out.push_back(Json(Topic::kFix, t, FusedFixJson(p)));
  for (const auto& fix : p.gps_fixes()) out.push_back(Json(Topic::kGps, fix.t_ns(), GpsFixJson(fix)));
  if (p.has_truth()) {
    out.push_back(Json(Topic::kTruth, t, PoseInFrameJson(t, p.truth_position_enu_m(), p.truth_orientation_enu_body())));
    out.push_back(Json(Topic::kTruthFix, t, TruthFixJson(p)));
  }
  if (has_position && GrowPath(p) && PathDue(p.t_ns())) {
    out.push_back(Json(Topic::kPath, t, PathJson(t)));
    last_path_sent_ns_ = p.t_ns();
  }
  out.push_back(Json(Topic::kStatus, t, StatusJson(p)));
  out.push_back({Topic::kUpdate, static_cast<uint64_t>(std::max<int64_t>(t, 0)), p.SerializeAsString()});
  return out;
}

bool PoseConverter::GrowPath(const v1::PoseUpdate& p) {
  if (!path_.empty() && p.t_ns() - last_path_t_ns_ < spacing_ns_) return false;
  if (path_.size() >= options_.max_poses) {
    // Keep poses 0, 2, 4, ...: the same shape at half the density.
    size_t kept = 0;
    for (size_t i = 0; i < path_.size(); i += 2) path_[kept++] = path_[i];
    path_.resize(kept);
    spacing_ns_ *= 2;
  }
  path_.push_back({p.position_enu_m(), p.orientation_enu_body()});
  last_path_t_ns_ = p.t_ns();
  return true;
}

bool PoseConverter::PathDue(int64_t t_ns) const {
  // The whole track goes out each time, so it goes out less often as it
  // grows: at most every path_size x 10 ms of sensor time (a 3600-pose track
  // every 36 s). That bounds its cost to ~100 poses of JSON per second of
  // drive, live and in recordings, whatever the drive's length.
  const auto interval_ns = std::max<int64_t>(options_.spacing_ns, static_cast<int64_t>(path_.size()) * 10'000'000);
  return last_path_sent_ns_ == 0 || t_ns - last_path_sent_ns_ >= interval_ns;
}

json PoseConverter::PathJson(int64_t t_ns) const {
  json poses = json::array();
  for (const auto& pose : path_) poses.push_back(PoseJson(pose.position, pose.orientation));
  return {{"timestamp", TimeJson(t_ns)}, {"frame_id", kEnuFrame}, {"poses", std::move(poses)}};
}

}  // namespace locaid::foxglove
