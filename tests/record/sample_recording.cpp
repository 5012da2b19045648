#include "sample_recording.hpp"

#include <cmath>
#include <cstdio>

namespace locaid::record::testing {
namespace {

constexpr uint64_t kTickNs = 10'000'000;  // 100 Hz

// Enough of foxglove.PoseInFrame's JSON Schema for viewers to name the fields.
constexpr const char* kPoseSchema = R"({"type":"object","properties":{
  "timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},
  "frame_id":{"type":"string"},
  "pose":{"type":"object","properties":{
    "position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},
    "orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}})";
constexpr const char* kStatusSchema =
    R"({"type":"object","properties":{"tracked":{"type":"integer"},"note":{"type":"string"}}})";

}  // namespace

std::string SamplePayload(const std::string& topic, uint64_t i) {
  char text[256];
  const double t = static_cast<double>(i) * 0.01;
  std::snprintf(text, sizeof text,
                R"({"topic":"%s","i":%llu,"pose":{"position":{"x":%.6f,"y":%.6f,"z":%.6f},"yaw":%.9f}})", topic.c_str(),
                static_cast<unsigned long long>(i), 12.5 * t, 3.0 * std::sin(t), 0.01 * std::cos(3 * t),
                std::fmod(0.37 * t, 6.283185307));
  return text;
}

SampleRecording WriteSampleRecording(const std::filesystem::path& path, const McapOptions& options, int seconds,
                                     size_t large_message_bytes) {
  McapWriter writer(path, options);
  const uint16_t pose_schema = writer.AddSchema("foxglove.PoseInFrame", "jsonschema", kPoseSchema);
  const uint16_t status_schema = writer.AddSchema("locaid.VoStatus", "jsonschema", kStatusSchema);
  const uint16_t pose = writer.AddChannel(pose_schema, "/locaid/pose", "json", {{"frame", "enu"}});
  const uint16_t gps = writer.AddChannel(0, "/locaid/gps", "json");
  const uint16_t status = writer.AddChannel(status_schema, "/locaid/vo_status", "json");
  writer.AddChannel(0, "/locaid/unused", "json");

  SampleRecording sample;
  std::map<uint16_t, uint32_t> sequence;
  auto write = [&](uint16_t channel, const std::string& topic, uint64_t t_ns, const std::string& payload) {
    writer.Write(channel, t_ns, t_ns - 1000, payload, sequence[channel]++);
    ++sample.messages_per_topic[topic];
    ++sample.message_count;
  };
  const uint64_t ticks = static_cast<uint64_t>(seconds) * 100;
  for (uint64_t i = 0; i < ticks; ++i) {
    const uint64_t t_ns = kSampleStartNs + i * kTickNs;
    write(pose, "/locaid/pose", t_ns, SamplePayload("/locaid/pose", i));
    if (i % 10 == 0) write(gps, "/locaid/gps", t_ns, SamplePayload("/locaid/gps", i));
    if (i % 100 == 0) {
      std::string note = (i == 0) ? std::string(large_message_bytes, 'x') : "ok";
      write(status, "/locaid/vo_status", t_ns,
            R"({"tracked":)" + std::to_string(200 + i % 37) + R"(,"note":")" + note + "\"}");
    }
  }
  writer.Close();
  sample.start_time_ns = kSampleStartNs;
  sample.end_time_ns = kSampleStartNs + (ticks - 1) * kTickNs;
  return sample;
}

}  // namespace locaid::record::testing
