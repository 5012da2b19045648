#include "output/json_schemas.hpp"

#include <nlohmann/json.hpp>

#include <initializer_list>
#include <string>
#include <vector>

namespace locaid::output::schemas {
namespace {

using nlohmann::json;

json Number(const char* description) { return {{"type", "number"}, {"description", description}}; }
json Text(const char* description) { return {{"type", "string"}, {"description", description}}; }

// An object schema; every listed property is required.
json Object(const char* title, const char* description, json properties) {
  std::vector<std::string> required;
  for (const auto& [name, _] : properties.items()) required.push_back(name);
  return {{"title", title},
          {"description", description},
          {"type", "object"},
          {"properties", std::move(properties)},
          {"required", required}};
}

json Time(const char* description) {
  json t = {{"type", "object"},
            {"title", "time"},
            {"description", description},
            {"properties",
             {{"sec", {{"type", "integer"}, {"minimum", 0}}},
              {"nsec", {{"type", "integer"}, {"minimum", 0}, {"maximum", 999999999}}}}},
            {"required", {"sec", "nsec"}}};
  return t;
}

json Components(const char* title, const char* description, std::initializer_list<const char*> names) {
  json properties = json::object();
  for (const char* n : names) properties[n] = Number(n);
  return Object(title, description, std::move(properties));
}

json Pose(const char* description) {
  return Object("foxglove.Pose", description,
                {{"position", Components("foxglove.Vector3", "position, m", {"x", "y", "z"})},
                 {"orientation", Components("foxglove.Quaternion", "orientation", {"x", "y", "z", "w"})}});
}

std::string Finish(json schema) {
  schema["$comment"] = "written for locaid (foxglove/json_schemas.cpp)";
  return schema.dump();
}

}  // namespace

std::string PoseInFrame() {
  return Finish(Object("foxglove.PoseInFrame", "A timestamped pose in a named frame",
                       {{"timestamp", Time("time of the pose")},
                        {"frame_id", Text("frame the pose is given in")},
                        {"pose", Pose("pose of the body in frame_id")}}));
}

std::string PosesInFrame() {
  return Finish(Object("foxglove.PosesInFrame", "Timestamped poses in a named frame",
                       {{"timestamp", Time("time of the newest pose")},
                        {"frame_id", Text("frame the poses are given in")},
                        {"poses", {{"type", "array"}, {"items", Pose("one pose")}, {"description", "poses"}}}}));
}

std::string FrameTransforms() {
  json transform = Object("foxglove.FrameTransform", "Pose of a child frame in its parent frame",
                          {{"timestamp", Time("time of the transform")},
                           {"parent_frame_id", Text("parent frame")},
                           {"child_frame_id", Text("child frame")},
                           {"translation", Components("foxglove.Vector3", "child origin in the parent, m",
                                                      {"x", "y", "z"})},
                           {"rotation", Components("foxglove.Quaternion", "child axes in the parent",
                                                   {"x", "y", "z", "w"})}});
  return Finish(Object("foxglove.FrameTransforms", "Transforms between frames",
                       {{"transforms", {{"type", "array"}, {"items", transform}, {"description", "transforms"}}}}));
}

std::string LocationFix() {
  // "type" besides "oneOf": viewers that do not read enums still see an integer.
  json covariance_type = {{"title", "foxglove.PositionCovarianceType"},
                          {"type", "integer"},
                          {"description", "what position_covariance holds"},
                          {"oneOf",
                           {{{"title", "UNKNOWN"}, {"const", 0}},
                            {{"title", "APPROXIMATED"}, {"const", 1}},
                            {{"title", "DIAGONAL_KNOWN"}, {"const", 2}},
                            {{"title", "KNOWN"}, {"const", 3}}}}};
  json schema = Object(
      "foxglove.LocationFix", "A WGS84 position with its uncertainty",
      {{"timestamp", Time("time of the fix")},
       {"frame_id", Text("frame whose origin the position is")},
       {"latitude", Number("latitude, degrees")},
       {"longitude", Number("longitude, degrees")},
       {"altitude", Number("altitude, m")},
       {"position_covariance",
        {{"type", "array"},
         {"items", {{"type", "number"}}},
         {"minItems", 9},
         {"maxItems", 9},
         {"description", "3x3 covariance in East, North, Up (m^2), row-major"}}},
       {"position_covariance_type", covariance_type}});
  // Optional: how the Map panel draws the fix, and what the filter did with it.
  schema["properties"]["color"] = Components("foxglove.Color", "colour of the fix on the map, 0..1", {"r", "g", "b", "a"});
  schema["properties"]["metadata"] = {
      {"type", "array"},
      {"description", "key/value pairs"},
      {"items", Object("foxglove.KeyValuePair", "a key and its value",
                       {{"key", Text("key")}, {"value", Text("value")}})}};
  return Finish(std::move(schema));
}

std::string Status() {
  // Plain "number" although the value may be null: Foxglove's JSON Schema
  // reader takes one type per field, and a null simply plots as a gap.
  json nullable_number = {{"type", "number"}};
  json schema = Object(
      "locaid.Status", "Filter state of one pose (see PoseUpdate in localization.proto)",
      {{"timestamp", Time("sensor time of the pose")},
       {"session_id", Text("session")},
       {"sequence", {{"type", "integer"}}},
       {"frame_index", {{"type", "integer"}}},
       {"mode", Text("GPS_FUSED, GPS_DEGRADED, VO_ONLY, DEAD_RECKONING or LOST")},
       {"vo_status", Text("OK, DEGRADED or LOST")},
       {"vo_inliers", {{"type", "integer"}}},
       {"vo_health", Text("TRACKING, DARK, FROZEN, LOST or NO_IMAGES: what the cameras gave VO")},
       {"speed_samples_used", {{"type", "integer"}}},
       {"speed_scale_error", Number("estimated speed sensor scale error")},
       {"vo_noise_scale", {{"type", "array"},
                           {"items", {{"type", "number"}}},
                           {"description", "learned VO noise, variance multiple of the model: tx ty tz rx ry rz"}}},
       {"gps_noise_scale_horizontal", Number("learned GPS noise, variance multiple of the stated one")},
       {"gps_noise_scale_vertical", Number("learned GPS noise, variance multiple of the stated one")},
       {"vo_noise_learning", {{"type", "boolean"}}},
       {"seconds_since_gps", nullable_number},
       {"gps_outage_active", {{"type", "boolean"}}},
       {"gps_used", {{"type", "integer"}}},
       {"gps_rejected", {{"type", "integer"}}},
       {"gps_resets", {{"type", "integer"}}},
       {"has_truth", {{"type", "boolean"}}},
       {"horizontal_error_m", nullable_number},
       {"processing_latency_ms", Number("server time spent on the frame")},
       {"behind_real_time_s", Number("paced sessions: how late this pose was published, s (0: on time)")},
       {"falling_behind", {{"type", "boolean"}}}});
  schema["properties"]["seconds_since_gps"]["description"] = "since the last accepted fix; null before the first";
  schema["properties"]["horizontal_error_m"]["description"] = "fused vs true position; null without truth";
  return Finish(std::move(schema));
}

}  // namespace locaid::output::schemas
