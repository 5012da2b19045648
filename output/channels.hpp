// The channels locaid publishes to Foxglove (live over WebSocket and in MCAP
// recordings) and the conversion of one PoseUpdate into their messages.
//
// Frames: `enu` (the session's local East-North-Up frame, origin = first
// accepted GPS fix), `base_link` (the body/IMU frame, x forward, y left, z
// up), `cam0` (left rectified camera). Every message is stamped with the
// pose's sensor time t_ns ({sec, nsec}; negative times are clamped to 0
// because the foxglove time type is unsigned).
//
// All topics but /locaid/update carry JSON (foxglove schemas described by
// JSON Schema); /locaid/update is the PoseUpdate itself, protobuf-encoded,
// described by the FileDescriptorSet of localization.proto.
#pragma once

#include "locaid/v1/localization.pb.h"

#include <nlohmann/json.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace locaid::output {

namespace v1 = locaid::v1;

// Index of a channel in Channels(); stable, used as the channel's id.
enum class Topic : size_t {
  kPose,      // /locaid/pose       foxglove.PoseInFrame   fused T_enu_body
  kTf,        // /tf                foxglove.FrameTransforms enu->base_link, base_link->cam0
  kFix,       // /locaid/fix        foxglove.LocationFix   fused lat/lon/alt + ENU covariance
  kGps,       // /locaid/gps        foxglove.LocationFix   each GPS fix the filter saw
  kTruth,     // /locaid/truth      foxglove.PoseInFrame   ground truth (when the source has it)
  kTruthFix,  // /locaid/truth_fix  foxglove.LocationFix   ground truth lat/lon/alt
  kPath,      // /locaid/path       foxglove.PosesInFrame  fused track, ~1 Hz of sensor time
  kStatus,    // /locaid/status     locaid.Status (JSON)   mode, GPS counters, error
  kUpdate,    // /locaid/update     locaid.v1.PoseUpdate   the raw update (protobuf)
  kCount
};

struct ChannelSpec {
  std::string topic;
  std::string encoding;         // message encoding: "json" or "protobuf"
  std::string schema_name;      // e.g. "foxglove.PoseInFrame"
  std::string schema_encoding;  // "jsonschema" or "protobuf"
  // JSON Schema text, or (protobuf) the binary FileDescriptorSet: callers
  // that need text (the WebSocket advertise) base64-encode it.
  std::string schema;
};

// The table of every channel, indexed by Topic.
const std::vector<ChannelSpec>& Channels();
const ChannelSpec& Channel(Topic topic);

// Serialized google.protobuf.FileDescriptorSet holding localization.proto
// and everything it imports, dependencies first.
std::string PoseUpdateDescriptorSet();

// One message ready to publish or record.
struct OutMessage {
  Topic topic;
  uint64_t log_time_ns = 0;  // sensor time of what it describes
  std::string data;          // JSON text or protobuf bytes
};

// Message bodies, one per schema (exposed for the tests). Each fills `body`
// in place: on an empty body it builds the message; on a body it filled
// before it overwrites the values in place (numbers and strings reuse their
// members), which is how PoseConverter keeps the per-pose cost low
// (docs/benchmarks.md); the text serialized from it is a new string.
//
// {sec, nsec} of a nanosecond time (clamped to >= 0).
void TimeJson(int64_t t_ns, nlohmann::json& body);
// The 3x3 ENU position block of PoseUpdate.covariance (6x6 row-major),
// row-major; all zero when the update has no 36-value covariance.
std::array<double, 9> PositionCovarianceEnu(const v1::PoseUpdate& p);
void PoseInFrameJson(int64_t t_ns, const v1::Vector3& position, const v1::Quaternion& orientation,
                     nlohmann::json& body);
void FrameTransformsJson(const v1::PoseUpdate& p, nlohmann::json& body);
void FusedFixJson(const v1::PoseUpdate& p, nlohmann::json& body);
void GpsFixJson(const v1::GpsFixSeen& fix, nlohmann::json& body);
void TruthFixJson(const v1::PoseUpdate& p, nlohmann::json& body);
void StatusJson(const v1::PoseUpdate& p, nlohmann::json& body);

// How much of the fused track /locaid/path keeps. A pose joins the track
// when it is at least `spacing_ns` of sensor time after the previous one
// (and the filter is not LOST); the track is published each time it grows.
// When it holds `max_poses`, every second pose is dropped and the spacing
// doubles, so a long drive keeps its whole shape in bounded memory.
struct PathOptions {
  int64_t spacing_ns = 1'000'000'000;
  size_t max_poses = 3600;
};

// Converts a session's PoseUpdates in order; keeps the path between calls.
// Not thread-safe; Reset() when a new session starts.
class PoseConverter {
 public:
  explicit PoseConverter(PathOptions options = {});
  std::vector<OutMessage> Convert(const v1::PoseUpdate& p);
  void Reset();
  size_t path_size() const { return path_.size(); }
  int64_t path_spacing_ns() const { return spacing_ns_; }

 private:
  // Adds the pose to the track if due; true when the track changed.
  bool GrowPath(const v1::PoseUpdate& p);
  void AppendPathText(const std::string& pose);
  // Whether the track is sent with this pose (see channels.cpp).
  bool PathDue(int64_t t_ns) const;
  std::string PathText(int64_t t_ns) const;

  PathOptions options_;
  std::array<nlohmann::json, static_cast<size_t>(Topic::kCount)> bodies_;  // refilled per pose
  std::vector<std::string> path_;  // each track pose as foxglove.Pose JSON text
  std::string path_text_;          // path_ joined by commas
  int64_t spacing_ns_ = 0;
  int64_t last_path_t_ns_ = 0;
  int64_t last_path_sent_ns_ = 0;
};

}  // namespace locaid::output
