// Byte-level pieces of the MCAP container format (major version 0): record
// opcodes, the CRC-32 the format uses, and little-endian appenders that build
// records in a std::string. McapWriter composes these; nothing here does I/O.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>
#include <utility>
#include <string_view>

namespace locaid::record::mcap {

// 0x89 "MCAP" '0' "\r\n": opens and closes every file.
inline constexpr std::string_view kMagic{"\x89MCAP0\r\n", 8};

enum class Op : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Opcode byte plus the uint64 content length that precede every record's content.
inline constexpr size_t kRecordPrefixBytes = 1 + 8;

// The CRC-32 MCAP uses (zlib's / Ethernet's: reflected polynomial
// 0xEDB88320, initial value and final XOR 0xFFFFFFFF), computed by zlib and
// fed in pieces.
class Crc32 {
 public:
  void Update(std::string_view bytes);
  uint32_t Value() const { return value_; }

 private:
  uint32_t value_ = 0;  // zlib's running value (pre- and post-conditioned)
};
uint32_t ComputeCrc32(std::string_view bytes);

// Little-endian appenders; the compound ones are the format's String (uint32
// byte length + bytes) and Map (uint32 byte length of all entries + entries).
void PutU8(std::string& out, uint8_t value);
void PutU16(std::string& out, uint16_t value);
void PutU32(std::string& out, uint32_t value);
void PutU64(std::string& out, uint64_t value);
void PutString(std::string& out, std::string_view value);
void PutStringMap(std::string& out, const std::map<std::string, std::string>& map);
// Entries in key order.
void PutU16U64Map(std::string& out, const std::vector<std::pair<uint16_t, uint64_t>>& map);

// Appends the opcode and a length placeholder; EndRecord fills the length in
// once the content is appended. BeginRecord returns what EndRecord needs.
// `content_bytes_elsewhere` counts content the caller writes after `out`
// without copying it in (a chunk's compressed records).
size_t BeginRecord(std::string& out, Op op);
void EndRecord(std::string& out, size_t record_start, uint64_t content_bytes_elsewhere = 0);

// Whole Schema and Channel records: they go both into chunks and into the summary.
void AppendSchemaRecord(std::string& out, uint16_t id, const std::string& name, const std::string& encoding,
                        const std::string& data);
void AppendChannelRecord(std::string& out, uint16_t id, uint16_t schema_id, const std::string& topic,
                         const std::string& message_encoding, const std::map<std::string, std::string>& metadata);

}  // namespace locaid::record::mcap
