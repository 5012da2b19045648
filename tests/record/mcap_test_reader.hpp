// A deliberately small MCAP reader for the writer's tests, written from the
// format description and sharing no code with record/ (its own CRC-32, its own
// little-endian parsing), so the tests do not check the writer against itself.
// Every inconsistency throws std::runtime_error saying where it is.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::record::testing {

std::string ReadFileBytes(const std::filesystem::path& path);
// Bit-at-a-time CRC-32 (reflected 0xEDB88320, pre- and post-inverted).
uint32_t ReferenceCrc32(std::string_view bytes);

struct RawRecord {
  uint8_t op = 0;
  uint64_t offset = 0;       // of the opcode byte, from the start of the file or chunk records
  std::string_view content;  // without opcode and length
  uint64_t length() const { return 1 + 8 + content.size(); }
};

struct Message {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time = 0, publish_time = 0;
  std::string data;
};

// What reading the data section from the start finds, as a streaming reader
// would: complete chunks only, stopping quietly where the file is cut short.
struct StreamScan {
  std::string header_profile, header_library;
  uint64_t chunk_count = 0;
  std::vector<Message> messages;
  std::map<uint16_t, std::string> channel_topics;
  std::map<uint16_t, std::string> schema_names;
  std::vector<std::string> chunk_compressions;
  bool data_end_seen = false;
  bool truncated = false;  // ended inside a record
};
StreamScan ScanStream(std::string_view file);

// The summary as the footer and summary offsets describe it, after checking
// footer, Data End, both CRCs, every Summary Offset group, every Chunk Index
// (chunk position and length, message indexes pointing at the right messages).
struct Summary {
  uint64_t summary_start = 0, summary_offset_start = 0;
  std::vector<uint8_t> summary_offset_opcodes;
  std::map<uint8_t, int> records_per_opcode;
  uint64_t message_count = 0;
  uint16_t schema_count = 0;
  uint32_t channel_count = 0, chunk_count = 0;
  uint64_t start_time = 0, end_time = 0;
  std::map<uint16_t, uint64_t> channel_message_counts;
  uint64_t chunk_index_count = 0;
};
Summary CheckSummary(std::string_view file);

}  // namespace locaid::record::testing
