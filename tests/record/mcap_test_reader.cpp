#include "mcap_test_reader.hpp"

#include <zstd.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace locaid::record::testing {
namespace {

constexpr std::string_view kMagic{"\x89MCAP0\r\n", 8};
constexpr uint64_t kPrefix = 1 + 8;               // opcode + content length
constexpr uint64_t kFooterLength = kPrefix + 20;  // summary_start, summary_offset_start, summary_crc
constexpr uint64_t kDataEndLength = kPrefix + 4;

[[noreturn]] void Fail(const std::string& what) { throw std::runtime_error("MCAP test reader: " + what); }

// Reads little-endian fields front to back; running past the end throws.
class Cursor {
 public:
  Cursor(std::string_view bytes, std::string what) : bytes_(bytes), what_(std::move(what)) {}
  uint64_t Uint(size_t width) {
    const std::string_view raw = Take(width);
    uint64_t value = 0;
    for (size_t i = 0; i < width; ++i) value |= uint64_t{static_cast<unsigned char>(raw[i])} << (8 * i);
    return value;
  }
  uint8_t U8() { return static_cast<uint8_t>(Uint(1)); }
  uint16_t U16() { return static_cast<uint16_t>(Uint(2)); }
  uint32_t U32() { return static_cast<uint32_t>(Uint(4)); }
  uint64_t U64() { return Uint(8); }
  std::string String() { return std::string(Take(U32())); }
  std::string_view Take(uint64_t n) {
    if (n > remaining()) {
      Fail(what_ + ": needs " + std::to_string(n) + " bytes at " + std::to_string(pos_) + ", has " +
           std::to_string(remaining()));
    }
    const std::string_view out = bytes_.substr(pos_, n);
    pos_ += n;
    return out;
  }
  uint64_t remaining() const { return bytes_.size() - pos_; }

 private:
  std::string_view bytes_;
  std::string what_;
  size_t pos_ = 0;
};

// The record starting at `offset` of `bytes`; throws when it does not fit.
RawRecord RecordAt(std::string_view bytes, uint64_t offset, const std::string& where) {
  if (offset > bytes.size()) Fail(where + ": offset " + std::to_string(offset) + " is past the end");
  Cursor cursor(bytes.substr(offset), where + " record at " + std::to_string(offset));
  RawRecord record;
  record.op = cursor.U8();
  record.offset = offset;
  record.content = cursor.Take(cursor.U64());
  return record;
}

// Splits a run of whole records (chunk contents, a summary group).
std::vector<RawRecord> SplitRecords(std::string_view bytes, uint64_t base, const std::string& where) {
  std::vector<RawRecord> records;
  for (uint64_t pos = 0; pos < bytes.size();) {
    RawRecord record = RecordAt(bytes, pos, where);
    record.offset += base;
    pos += record.length();
    records.push_back(record);
  }
  return records;
}

struct Chunk {
  uint64_t start_time = 0, end_time = 0, uncompressed_size = 0, compressed_size = 0;
  uint32_t crc = 0;
  std::string compression;
  std::string records;  // decompressed
};

Chunk ParseChunk(const RawRecord& record) {
  const std::string where = "chunk at " + std::to_string(record.offset);
  Cursor cursor(record.content, where);
  Chunk chunk;
  chunk.start_time = cursor.U64();
  chunk.end_time = cursor.U64();
  chunk.uncompressed_size = cursor.U64();
  chunk.crc = cursor.U32();
  chunk.compression = cursor.String();
  const std::string_view stored = cursor.Take(cursor.U64());
  chunk.compressed_size = stored.size();
  if (cursor.remaining() != 0) Fail(where + ": " + std::to_string(cursor.remaining()) + " bytes after the records");
  if (chunk.compression.empty()) {
    chunk.records = std::string(stored);
  } else if (chunk.compression == "zstd") {
    chunk.records.resize(chunk.uncompressed_size);
    const size_t n = ZSTD_decompress(chunk.records.data(), chunk.records.size(), stored.data(), stored.size());
    if (ZSTD_isError(n)) Fail(where + ": zstd says " + ZSTD_getErrorName(n));
    chunk.records.resize(n);
  } else {
    Fail(where + ": unexpected compression '" + chunk.compression + "'");
  }
  if (chunk.records.size() != chunk.uncompressed_size) {
    Fail(where + ": " + std::to_string(chunk.records.size()) + " bytes uncompressed, header says " +
         std::to_string(chunk.uncompressed_size));
  }
  if (ReferenceCrc32(chunk.records) != chunk.crc) Fail(where + ": uncompressed_crc does not match the records");
  return chunk;
}

Message ParseMessage(const RawRecord& record) {
  Cursor cursor(record.content, "message at " + std::to_string(record.offset));
  Message message;
  message.channel_id = cursor.U16();
  message.sequence = cursor.U32();
  message.log_time = cursor.U64();
  message.publish_time = cursor.U64();
  message.data = std::string(cursor.Take(cursor.remaining()));
  return message;
}

// Schema, Channel and Message records of one chunk into the scan.
void ScanChunk(const RawRecord& record, StreamScan& scan) {
  const Chunk chunk = ParseChunk(record);
  scan.chunk_compressions.push_back(chunk.compression);
  uint64_t min_time = UINT64_MAX, max_time = 0;
  for (const RawRecord& inner : SplitRecords(chunk.records, 0, "chunk records")) {
    Cursor cursor(inner.content, "record in chunk");
    if (inner.op == 0x03) {
      const uint16_t id = cursor.U16();
      scan.schema_names[id] = cursor.String();
    } else if (inner.op == 0x04) {
      const uint16_t id = cursor.U16();
      const uint16_t schema_id = cursor.U16();
      if (schema_id != 0 && !scan.schema_names.contains(schema_id)) Fail("channel before its schema");
      scan.channel_topics[id] = cursor.String();
    } else if (inner.op == 0x05) {
      Message message = ParseMessage(inner);
      if (!scan.channel_topics.contains(message.channel_id)) Fail("message before its channel");
      min_time = std::min(min_time, message.log_time);
      max_time = std::max(max_time, message.log_time);
      scan.messages.push_back(std::move(message));
    } else {
      Fail("record opcode " + std::to_string(inner.op) + " inside a chunk");
    }
  }
  if (min_time != chunk.start_time || max_time != chunk.end_time) {
    Fail("chunk start/end times do not match its messages");
  }
  ++scan.chunk_count;
}

// Checks one Chunk Index against the chunk and message indexes it points at.
void CheckChunkIndex(std::string_view file, const RawRecord& record) {
  Cursor cursor(record.content, "chunk index at " + std::to_string(record.offset));
  const uint64_t start_time = cursor.U64(), end_time = cursor.U64();
  const uint64_t chunk_offset = cursor.U64(), chunk_length = cursor.U64();
  Cursor offsets(cursor.Take(cursor.U32()), "message_index_offsets");
  std::map<uint16_t, uint64_t> index_offsets;
  while (offsets.remaining() > 0) {
    const uint16_t channel = offsets.U16();
    index_offsets[channel] = offsets.U64();
  }
  const uint64_t index_length = cursor.U64();
  const std::string compression = cursor.String();
  const uint64_t compressed_size = cursor.U64(), uncompressed_size = cursor.U64();

  const RawRecord chunk_record = RecordAt(file, chunk_offset, "chunk index target");
  if (chunk_record.op != 0x06 || chunk_record.length() != chunk_length) Fail("chunk index does not frame a chunk");
  const Chunk chunk = ParseChunk(chunk_record);
  if (chunk.start_time != start_time || chunk.end_time != end_time || chunk.compression != compression ||
      chunk.compressed_size != compressed_size || chunk.uncompressed_size != uncompressed_size) {
    Fail("chunk index fields differ from the chunk at " + std::to_string(chunk_offset));
  }

  // The message indexes follow the chunk back to back, one per channel.
  const uint64_t indexes_start = chunk_offset + chunk_length;
  uint64_t indexed_messages = 0, seen_length = 0;
  for (const auto& [channel, offset] : index_offsets) {
    const RawRecord index = RecordAt(file, offset, "message index");
    if (index.op != 0x07 || offset < indexes_start || offset + index.length() > indexes_start + index_length) {
      Fail("message index offset " + std::to_string(offset) + " is not a message index after its chunk");
    }
    seen_length += index.length();
    Cursor entries(index.content, "message index");
    if (entries.U16() != channel) Fail("message index for the wrong channel");
    Cursor array(entries.Take(entries.U32()), "message index entries");
    while (array.remaining() > 0) {
      const uint64_t log_time = array.U64(), message_offset = array.U64();
      const Message message = ParseMessage(RecordAt(chunk.records, message_offset, "indexed message"));
      if (message.channel_id != channel || message.log_time != log_time) Fail("message index entry points elsewhere");
      ++indexed_messages;
    }
  }
  if (seen_length != index_length) Fail("message_index_length does not add up");
  uint64_t messages_in_chunk = 0;
  for (const RawRecord& inner : SplitRecords(chunk.records, 0, "chunk records")) messages_in_chunk += inner.op == 0x05;
  if (indexed_messages != messages_in_chunk) Fail("message indexes do not cover every message of the chunk");
}

void ParseStatistics(const RawRecord& record, Summary& summary) {
  Cursor cursor(record.content, "statistics");
  summary.message_count = cursor.U64();
  summary.schema_count = cursor.U16();
  summary.channel_count = cursor.U32();
  cursor.U32();  // attachments
  cursor.U32();  // metadata
  summary.chunk_count = cursor.U32();
  summary.start_time = cursor.U64();
  summary.end_time = cursor.U64();
  Cursor counts(cursor.Take(cursor.U32()), "channel_message_counts");
  while (counts.remaining() > 0) {
    const uint16_t channel = counts.U16();
    summary.channel_message_counts[channel] = counts.U64();
  }
}

}  // namespace

std::string ReadFileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail("cannot open " + path.string());
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

uint32_t ReferenceCrc32(std::string_view bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

StreamScan ScanStream(std::string_view file) {
  if (!file.starts_with(kMagic)) Fail("no leading magic");
  StreamScan scan;
  uint64_t pos = kMagic.size();
  for (bool first = true;; first = false) {
    if (file.size() - pos < kPrefix) break;  // cut short between or inside records
    Cursor prefix(file.substr(pos), "record prefix");
    const uint8_t op = prefix.U8();
    const uint64_t content_length = prefix.U64();
    if (content_length > prefix.remaining()) break;  // the last record was cut short
    const RawRecord record = RecordAt(file, pos, "data section");
    pos += record.length();
    if (first != (op == 0x01)) Fail("the header must be the first record, and only the first");
    if (op == 0x01) {
      Cursor header(record.content, "header");
      scan.header_profile = header.String();
      scan.header_library = header.String();
    } else if (op == 0x06) {
      ScanChunk(record, scan);
    } else if (op == 0x0F) {
      scan.data_end_seen = true;
    } else if (op == 0x02) {
      if (file.substr(pos) != kMagic) Fail("the footer is not followed by the magic and the end of the file");
      return scan;
    } else if (op == 0x05) {
      Fail("message outside a chunk");
    }
  }
  scan.truncated = true;
  return scan;
}

Summary CheckSummary(std::string_view file) {
  if (file.size() < 2 * kMagic.size() + kFooterLength || !file.ends_with(kMagic)) Fail("no trailing magic");
  const uint64_t footer_offset = file.size() - kMagic.size() - kFooterLength;
  const RawRecord footer = RecordAt(file, footer_offset, "footer");
  if (footer.op != 0x02 || footer.length() != kFooterLength) Fail("no footer before the trailing magic");
  Cursor fields(footer.content, "footer");
  Summary summary;
  summary.summary_start = fields.U64();
  summary.summary_offset_start = fields.U64();
  const uint32_t summary_crc = fields.U32();
  if (summary.summary_start < kMagic.size() + kDataEndLength || summary.summary_offset_start < summary.summary_start ||
      summary.summary_offset_start > footer_offset) {
    Fail("footer offsets out of order");
  }

  const uint64_t data_end_offset = summary.summary_start - kDataEndLength;
  const RawRecord data_end = RecordAt(file, data_end_offset, "data end");
  if (data_end.op != 0x0F || data_end.length() != kDataEndLength) Fail("no Data End right before the summary");
  if (Cursor(data_end.content, "data end").U32() != ReferenceCrc32(file.substr(0, data_end_offset))) {
    Fail("data_section_crc does not match");
  }
  const uint64_t crc_end = footer_offset + kPrefix + 16;  // through summary_offset_start
  if (summary_crc != ReferenceCrc32(file.substr(summary.summary_start, crc_end - summary.summary_start))) {
    Fail("summary_crc does not match");
  }

  const auto records =
      SplitRecords(file.substr(summary.summary_start, summary.summary_offset_start - summary.summary_start),
                   summary.summary_start, "summary");
  std::map<uint8_t, std::pair<uint64_t, uint64_t>> groups;  // opcode -> (start, length)
  uint8_t previous_op = 0;
  for (const RawRecord& record : records) {
    if (record.op != previous_op && groups.contains(record.op)) Fail("summary records not grouped by opcode");
    auto [it, added] = groups.try_emplace(record.op, record.offset, 0);
    it->second.second += record.length();
    previous_op = record.op;
    ++summary.records_per_opcode[record.op];
    if (record.op == 0x0B) ParseStatistics(record, summary);
    if (record.op == 0x08) {
      CheckChunkIndex(file, record);
      ++summary.chunk_index_count;
    }
  }

  const auto offsets =
      SplitRecords(file.substr(summary.summary_offset_start, footer_offset - summary.summary_offset_start),
                   summary.summary_offset_start, "summary offsets");
  for (const RawRecord& record : offsets) {
    Cursor cursor(record.content, "summary offset");
    const uint8_t op = cursor.U8();
    const uint64_t start = cursor.U64(), length = cursor.U64();
    if (record.op != 0x0E) Fail("non-summary-offset record in the summary offset section");
    const auto group = groups.find(op);
    if (group == groups.end() || group->second != std::make_pair(start, length)) {
      Fail("summary offset for opcode " + std::to_string(op) + " does not frame its group");
    }
    summary.summary_offset_opcodes.push_back(op);
  }
  if (summary.summary_offset_opcodes.size() != groups.size()) Fail("a summary group has no summary offset");
  return summary;
}

}  // namespace locaid::record::testing
