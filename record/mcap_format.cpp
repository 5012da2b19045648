#include "record/mcap_format.hpp"

#include <zlib.h>

#include <limits>
#include <stdexcept>

namespace locaid::record::mcap {
namespace {

void PutLittleEndian(std::string& out, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((value >> (8 * i)) & 0xFFu));
}

// Overwrites `bytes` bytes at `at` (a length placeholder written earlier).
void PatchLittleEndian(std::string& out, size_t at, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out[at + i] = static_cast<char>((value >> (8 * i)) & 0xFFu);
}

// Every String, Map and Array length in the format is a uint32.
uint32_t CheckedU32Length(size_t length, const char* what) {
  if (length > std::numeric_limits<uint32_t>::max()) {
    throw std::length_error(std::string("MCAP ") + what + " of " + std::to_string(length) +
                            " bytes exceeds the format's 4 GiB limit");
  }
  return static_cast<uint32_t>(length);
}

// Writes the uint32 byte length of everything appended since `length_at`.
void PatchU32Length(std::string& out, size_t length_at, const char* what) {
  PatchLittleEndian(out, length_at, CheckedU32Length(out.size() - length_at - 4, what), 4);
}

// A Map is its entries behind their uint32 byte length.
template <typename Map, typename PutEntry>
void PutMap(std::string& out, const Map& map, PutEntry put_entry) {
  const size_t length_at = out.size();
  PutU32(out, 0);
  for (const auto& [key, value] : map) put_entry(key, value);
  PatchU32Length(out, length_at, "map");
}

}  // namespace

void Crc32::Update(std::string_view bytes) {
  // zlib's CRC-32 (the same CRC, table-sliced), with a size_t length.
  value_ = static_cast<uint32_t>(crc32_z(value_, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
}

uint32_t ComputeCrc32(std::string_view bytes) {
  Crc32 crc;
  crc.Update(bytes);
  return crc.Value();
}

void PutU8(std::string& out, uint8_t value) { out.push_back(static_cast<char>(value)); }
void PutU16(std::string& out, uint16_t value) { PutLittleEndian(out, value, 2); }
void PutU32(std::string& out, uint32_t value) { PutLittleEndian(out, value, 4); }
void PutU64(std::string& out, uint64_t value) { PutLittleEndian(out, value, 8); }

void PutString(std::string& out, std::string_view value) {
  PutU32(out, CheckedU32Length(value.size(), "string"));
  out.append(value);
}

void PutStringMap(std::string& out, const std::map<std::string, std::string>& map) {
  PutMap(out, map, [&out](const std::string& key, const std::string& value) {
    PutString(out, key);
    PutString(out, value);
  });
}

void PutU16U64Map(std::string& out, const std::vector<std::pair<uint16_t, uint64_t>>& map) {
  PutMap(out, map, [&out](uint16_t key, uint64_t value) {
    PutU16(out, key);
    PutU64(out, value);
  });
}

size_t BeginRecord(std::string& out, Op op) {
  const size_t record_start = out.size();
  PutU8(out, static_cast<uint8_t>(op));
  PutU64(out, 0);
  return record_start;
}

void EndRecord(std::string& out, size_t record_start, uint64_t content_bytes_elsewhere) {
  const uint64_t content_length = out.size() - record_start - kRecordPrefixBytes + content_bytes_elsewhere;
  PatchLittleEndian(out, record_start + 1, content_length, 8);
}

void AppendSchemaRecord(std::string& out, uint16_t id, const std::string& name, const std::string& encoding,
                        const std::string& data) {
  const size_t start = BeginRecord(out, Op::kSchema);
  PutU16(out, id);
  PutString(out, name);
  PutString(out, encoding);
  PutString(out, data);  // Bytes with a uint32 length: the same layout as a String
  EndRecord(out, start);
}

void AppendChannelRecord(std::string& out, uint16_t id, uint16_t schema_id, const std::string& topic,
                         const std::string& message_encoding, const std::map<std::string, std::string>& metadata) {
  const size_t start = BeginRecord(out, Op::kChannel);
  PutU16(out, id);
  PutU16(out, schema_id);
  PutString(out, topic);
  PutString(out, message_encoding);
  PutStringMap(out, metadata);
  EndRecord(out, start);
}

}  // namespace locaid::record::mcap
