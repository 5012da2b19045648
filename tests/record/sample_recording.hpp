// A small synthetic drive recorded with McapWriter, shared by the byte-level
// and the official-reader tests: what was written, to compare with what is read.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

#include "record/mcap_writer.hpp"

namespace locaid::record::testing {

// /locaid/pose at 100 Hz (schema foxglove.PoseInFrame, jsonschema),
// /locaid/gps at 10 Hz (json, no schema), /locaid/vo_status at 1 Hz (schema
// locaid.VoStatus) whose first message is `large_message_bytes` long, and
// /locaid/unused, a channel with no messages. Each channel's sequence numbers
// run 0, 1, 2, ...
struct SampleRecording {
  std::map<std::string, uint64_t> messages_per_topic;
  uint64_t message_count = 0;
  uint64_t start_time_ns = 0, end_time_ns = 0;
};
inline constexpr uint64_t kSampleStartNs = 1'700'000'000'000'000'000ull;
inline constexpr int kSampleChannels = 4;
inline constexpr int kSampleSchemas = 2;
SampleRecording WriteSampleRecording(const std::filesystem::path& path, const McapOptions& options, int seconds,
                                     size_t large_message_bytes = 0);

// The test's payload bytes for message `i`: JSON with numbers that vary like a
// sensor's, so zstd has realistic work.
std::string SamplePayload(const std::string& topic, uint64_t i);

}  // namespace locaid::record::testing
