#include "bag/mcap_reader.hpp"

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <utility>

namespace locaid::bag {
namespace {

constexpr std::string_view kMagic{"\x89MCAP0\r\n", 8};
constexpr uint64_t kPrefixBytes = 1 + 8;  // opcode + uint64 content length
// Largest record content loaded into memory: a chunk at the uncompressed
// limit stored uncompressed, plus its fields.
constexpr uint64_t kMaxRecordBytes = McapReader::kMaxChunkBytes + (1u << 20);

enum Op : uint8_t {
  kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
  kMessageIndex = 0x07, kChunkIndex = 0x08, kAttachment = 0x09, kAttachmentIndex = 0x0A,
  kStatistics = 0x0B, kMetadata = 0x0C, kMetadataIndex = 0x0D, kSummaryOffset = 0x0E, kDataEnd = 0x0F,
};

std::string OpName(uint8_t op) {
  static constexpr const char* kNames[] = {
      "", "Header", "Footer", "Schema", "Channel", "Message", "Chunk", "Message Index", "Chunk Index",
      "Attachment", "Attachment Index", "Statistics", "Metadata", "Metadata Index", "Summary Offset", "Data End"};
  if (op >= 1 && op <= kDataEnd) return kNames[op];
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X", op);
  return std::string("unknown (opcode ") + hex + ")";
}

// Records whose content this reader uses; every other record is skipped unread.
bool Needed(uint8_t op) {
  return op == kSchema || op == kChannel || op == kMessage || op == kChunk;
}

uint64_t LittleEndian(const char* p, int bytes) {
  uint64_t value = 0;
  for (int i = bytes - 1; i >= 0; --i) value = (value << 8) | static_cast<uint8_t>(p[i]);
  return value;
}

std::string Where(const std::string& name, uint64_t offset) {
  return "McapReader: '" + name + "' at byte " + std::to_string(offset) + ": ";
}

// The fields of one record's content, each checked against the bytes left.
class Fields {
 public:
  Fields(std::string_view content, std::string context) : content_(content), context_(std::move(context)) {}

  uint16_t U16(const char* what) { return static_cast<uint16_t>(LittleEndian(Take(2, what).data(), 2)); }
  uint32_t U32(const char* what) { return static_cast<uint32_t>(LittleEndian(Take(4, what).data(), 4)); }
  uint64_t U64(const char* what) { return LittleEndian(Take(8, what).data(), 8); }
  // A String or Bytes field: uint32 length, then the bytes.
  std::string_view String(const char* what) { return Take(U32(what), what, 4); }
  std::string_view Rest() const { return content_.substr(pos_); }
  size_t remaining() const { return content_.size() - pos_; }

  std::string_view Take(uint64_t n, const char* what, size_t length_bytes = 0) {
    if (n > remaining()) {
      throw McapError(context_ + what + (length_bytes ? " states " : " needs ") + std::to_string(n) +
                      " bytes at content byte " + std::to_string(pos_ - length_bytes) + ", the record has " +
                      std::to_string(remaining()) + " left");
    }
    const std::string_view out = content_.substr(pos_, n);
    pos_ += n;
    return out;
  }

 private:
  std::string_view content_;
  size_t pos_ = 0;
  std::string context_;
};

// LZ4 frame -> exactly out.size() bytes; an error text, or empty on success.
std::string DecompressLz4(std::string_view in, std::string& out) {
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return "cannot create an LZ4 context";
  size_t in_pos = 0, out_pos = 0, hint = 1;
  std::string error;
  while (hint != 0 && error.empty()) {
    size_t in_size = in.size() - in_pos, out_size = out.size() - out_pos;
    hint = LZ4F_decompress(ctx, out.data() + out_pos, &out_size, in.data() + in_pos, &in_size, nullptr);
    if (LZ4F_isError(hint)) {
      error = std::string("LZ4 frame does not decompress: ") + LZ4F_getErrorName(hint);
    } else if (in_size == 0 && out_size == 0 && hint != 0) {
      error = out_pos == out.size() ? "LZ4 frame decompresses to more than the stated uncompressed size"
                                    : "LZ4 frame ends early (incomplete frame)";
    }
    in_pos += in_size;
    out_pos += out_size;
  }
  LZ4F_freeDecompressionContext(ctx);
  if (error.empty() && out_pos != out.size()) {
    error = "LZ4 frame decompresses to " + std::to_string(out_pos) + " bytes, the chunk states " +
            std::to_string(out.size());
  }
  return error;
}

}  // namespace

McapReader::McapReader(const std::filesystem::path& path) : path_(path), name_(path.string()) {
  auto file = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!file->is_open()) throw McapError("McapReader: cannot open '" + name_ + "'");
  in_ = std::move(file);
  Open();
}

McapReader::McapReader(std::unique_ptr<std::istream> in, std::string name) : name_(std::move(name)), in_(std::move(in)) {
  if (!in_) throw McapError("McapReader: '" + name_ + "': no stream");
  Open();
}

// Size, magic and Header. A file that ends inside them is cut, not foreign.
void McapReader::Open() {
  in_->seekg(0, std::ios::end);
  const std::streamoff size = in_->tellg();
  in_->seekg(0, std::ios::beg);
  if (size < 0 || !*in_) Fail(0, "cannot read it (size unknown: not a seekable file)");
  report_.file_bytes = static_cast<uint64_t>(size);

  char magic[8] = {};
  const uint64_t have = std::min<uint64_t>(kMagic.size(), report_.file_bytes);
  ReadExactly(magic, have, 0);
  if (std::string_view(magic, have) != kMagic.substr(0, have)) Fail(0, "not an MCAP file (bad magic)");
  pos_ = have;
  if (have < kMagic.size()) {
    Truncated("file ends at byte " + std::to_string(have) + " inside the leading magic; it holds no messages");
    return;
  }
  uint8_t op = 0;
  uint64_t offset = 0;
  if (!NextRecordInFile(op, record_, offset)) return;
  if (op != kHeader) Fail(offset, "the first record is a " + OpName(op) + " record, not a Header");
  Fields fields(record_, Where(name_, offset) + "Header record: ");
  profile_ = fields.String("profile");
}

bool McapReader::Next(McapMessage& out) {
  while (true) {
    if (chunk_pos_ < chunk_.size() && NextInChunk(out)) return true;
    if (done_) return false;
    uint8_t op = 0;
    uint64_t offset = 0;
    if (!NextRecordInFile(op, record_, offset)) return false;
    switch (op) {
      case kSchema: OnSchema(record_, offset); break;
      case kChannel: OnChannel(record_, offset); break;
      case kMessage:
        if (OnMessage(record_, offset, out)) return true;
        break;
      case kChunk: LoadChunk(record_, offset); break;
      case kDataEnd:
        report_.summary_present = true;
        done_ = true;
        return false;
      case kFooter:  // no Data End, yet closed: the data section is complete
        done_ = true;
        return false;
      default: break;  // indexes, attachments, metadata, unknown opcodes
    }
  }
}

// The next record of the file: its opcode, its content when Needed() (else
// skipped), and its offset. False at a cut (report() says where).
bool McapReader::NextRecordInFile(uint8_t& op, std::string& content, uint64_t& offset) {
  offset = pos_;
  const uint64_t left = report_.file_bytes - pos_;
  if (left == 0) {
    Truncated("no Data End record: the recorder did not close the file (it ends at byte " + std::to_string(pos_) +
              ", after a complete record); the messages before it were read");
    return false;
  }
  if (left < kPrefixBytes) {
    Truncated("file ends at byte " + std::to_string(report_.file_bytes) + " inside the opcode and length of a record"
              " that starts at byte " + std::to_string(pos_) + " (needs " + std::to_string(kPrefixBytes - left) +
              " more bytes); the messages before it were read");
    return false;
  }
  char prefix[kPrefixBytes];
  ReadExactly(prefix, kPrefixBytes, pos_);
  op = static_cast<uint8_t>(prefix[0]);
  const uint64_t length = LittleEndian(prefix + 1, 8);
  if (length > left - kPrefixBytes) {
    Truncated("file ends at byte " + std::to_string(report_.file_bytes) + " inside a " + OpName(op) +
              " record that starts at byte " + std::to_string(pos_) + " (needs " +
              std::to_string(length - (left - kPrefixBytes)) + " more bytes); the messages before it were read");
    return false;
  }
  pos_ += kPrefixBytes;
  if (Needed(op) || op == kHeader) {
    if (length > kMaxRecordBytes) {
      Fail(offset, "a " + OpName(op) + " record of " + std::to_string(length) + " bytes is larger than the " +
                       std::to_string(kMaxRecordBytes) + " bytes this reader accepts");
    }
    content.resize(length);
    ReadExactly(content.data(), length, pos_);
  } else {
    in_->seekg(static_cast<std::streamoff>(pos_ + length), std::ios::beg);
  }
  pos_ += length;
  return true;
}

// The next message among the current chunk's records; false when the chunk
// is used up (it is then released).
bool McapReader::NextInChunk(McapMessage& out) {
  while (chunk_pos_ < chunk_.size()) {
    const uint64_t left = chunk_.size() - chunk_pos_;
    if (left < kPrefixBytes) {
      Fail(chunk_offset_, "the Chunk's records end inside a record's opcode and length (at uncompressed byte " +
                              std::to_string(chunk_pos_) + ")");
    }
    const uint8_t op = static_cast<uint8_t>(chunk_[chunk_pos_]);
    const uint64_t length = LittleEndian(chunk_.data() + chunk_pos_ + 1, 8);
    if (length > left - kPrefixBytes) {
      Fail(chunk_offset_, "a " + OpName(op) + " record at uncompressed byte " + std::to_string(chunk_pos_) +
                              " of the Chunk states " + std::to_string(length) + " bytes, the chunk has " +
                              std::to_string(left - kPrefixBytes) + " left");
    }
    const std::string_view content(chunk_.data() + chunk_pos_ + kPrefixBytes, length);
    chunk_pos_ += kPrefixBytes + length;
    if (op == kSchema) OnSchema(content, chunk_offset_);
    if (op == kChannel) OnChannel(content, chunk_offset_);
    if (op == kMessage && OnMessage(content, chunk_offset_, out)) return true;
  }
  chunk_.clear();
  chunk_pos_ = 0;
  return false;
}

void McapReader::LoadChunk(std::string_view content, uint64_t offset) {
  Fields fields(content, Where(name_, offset) + "Chunk record: ");
  fields.U64("message_start_time");
  fields.U64("message_end_time");
  const uint64_t uncompressed_size = fields.U64("uncompressed_size");
  const uint32_t crc = fields.U32("uncompressed_crc");
  const std::string_view compression = fields.String("compression");
  const std::string_view records = fields.Take(fields.U64("records length"), "records", 8);

  if (compression != "" && compression != "zstd" && compression != "lz4") {
    Fail(offset, "unknown chunk compression '" + std::string(compression) + "' (known: none, zstd, lz4)");
  }
  if (uncompressed_size > kMaxChunkBytes) {
    Fail(offset, "the Chunk states " + std::to_string(uncompressed_size) + " uncompressed bytes, more than the " +
                     std::to_string(kMaxChunkBytes) + " this reader accepts");
  }
  // Neither format can expand beyond these ratios (zstd: a 4-byte RLE block
  // per 128 KiB; lz4: 255 bytes per length byte), so a small chunk cannot make
  // the reader allocate up to the limit.
  const uint64_t max_ratio = compression == "zstd" ? 32768 : compression == "lz4" ? 256 : 1;
  if (!compression.empty() && uncompressed_size / max_ratio > records.size() + 1024) {
    Fail(offset, "the Chunk states " + std::to_string(uncompressed_size) + " uncompressed bytes, more than its " +
                     std::to_string(records.size()) + " bytes of " + std::string(compression) + " can hold");
  }
  if (compression.empty() && records.size() != uncompressed_size) {
    Fail(offset, "an uncompressed Chunk holds " + std::to_string(records.size()) + " bytes of records but states " +
                     std::to_string(uncompressed_size));
  }
  if (compression == "zstd") {
    const unsigned long long frame = ZSTD_getFrameContentSize(records.data(), records.size());
    if (frame == ZSTD_CONTENTSIZE_ERROR) Fail(offset, "the Chunk's records are not a zstd frame");
    if (frame != ZSTD_CONTENTSIZE_UNKNOWN && frame != uncompressed_size) {
      Fail(offset, "the Chunk's zstd frame holds " + std::to_string(frame) + " bytes, the chunk states " +
                       std::to_string(uncompressed_size));
    }
  }
  chunk_.resize(uncompressed_size);
  chunk_pos_ = 0;
  if (compression.empty()) {
    std::memcpy(chunk_.data(), records.data(), records.size());
  } else if (compression == "zstd") {
    const size_t n = ZSTD_decompress(chunk_.data(), chunk_.size(), records.data(), records.size());
    if (ZSTD_isError(n) || n != uncompressed_size) {
      chunk_.clear();
      Fail(offset, std::string("the Chunk's zstd frame does not decompress to its stated ") +
                       std::to_string(uncompressed_size) + " bytes" +
                       (ZSTD_isError(n) ? std::string(": ") + ZSTD_getErrorName(n) : ""));
    }
  } else if (const std::string error = DecompressLz4(records, chunk_); !error.empty()) {
    chunk_.clear();
    Fail(offset, "the Chunk's " + error);
  }
  ++report_.chunks;
  chunk_offset_ = offset;

  if (crc != 0 && static_cast<uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(chunk_.data()), chunk_.size())) !=
                      crc) {
    ++report_.chunks_bad_crc;
    for (size_t at = 0; at + kPrefixBytes <= chunk_.size();) {  // count what is lost, as far as it parses
      const uint64_t length = LittleEndian(chunk_.data() + at + 1, 8);
      if (chunk_[at] == static_cast<char>(kMessage)) ++report_.messages_in_bad_chunks;
      if (length > chunk_.size() - at - kPrefixBytes) break;
      at += kPrefixBytes + length;
    }
    chunk_.clear();
  }
}

void McapReader::OnSchema(std::string_view content, uint64_t offset) {
  Fields fields(content, Where(name_, offset) + "Schema record: ");
  McapSchema schema;
  schema.id = fields.U16("id");
  schema.name = fields.String("name");
  schema.encoding = fields.String("encoding");
  schema.data = fields.String("data");
  schemas_[schema.id] = std::move(schema);
}

void McapReader::OnChannel(std::string_view content, uint64_t offset) {
  Fields fields(content, Where(name_, offset) + "Channel record: ");
  McapChannel channel;
  channel.id = fields.U16("id");
  channel.schema_id = fields.U16("schema_id");
  channel.topic = fields.String("topic");
  channel.message_encoding = fields.String("message_encoding");
  Fields map(fields.String("metadata"), Where(name_, offset) + "Channel record metadata: ");
  while (map.remaining() > 0) {
    const std::string_view key = map.String("key");
    channel.metadata[std::string(key)] = map.String("value");
  }
  if (channel.schema_id != 0 && schemas_.count(channel.schema_id) == 0) {
    Fail(offset, "channel " + std::to_string(channel.id) + " ('" + channel.topic + "') names schema " +
                     std::to_string(channel.schema_id) + ", which no Schema record declared before it");
  }
  channels_[channel.id] = std::move(channel);
}

// False: a message skipped as lost with a bad chunk (see the header).
bool McapReader::OnMessage(std::string_view content, uint64_t offset, McapMessage& out) {
  Fields fields(content, Where(name_, offset) + "Message record: ");
  out.channel_id = fields.U16("channel_id");
  out.sequence = fields.U32("sequence");
  out.log_time_ns = fields.U64("log_time");
  out.publish_time_ns = fields.U64("publish_time");
  out.data = fields.Rest();
  out.record_offset = offset;
  if (channels_.count(out.channel_id) == 0) {
    if (report_.chunks_bad_crc > 0) {  // its Channel record may have been in the skipped chunk
      ++report_.messages_in_bad_chunks;
      return false;
    }
    Fail(offset, "a message on channel " + std::to_string(out.channel_id) +
                     ", which no Channel record declared before it");
  }
  out.index = report_.messages++;
  return true;
}

void McapReader::ReadExactly(char* out, uint64_t n, uint64_t offset) {
  in_->read(out, static_cast<std::streamsize>(n));
  if (static_cast<uint64_t>(in_->gcount()) != n) {
    Fail(offset, "read error: got " + std::to_string(in_->gcount()) + " of " + std::to_string(n) +
                     " bytes (did the file shrink while it was read?)");
  }
}

void McapReader::Truncated(std::string what) {
  report_.truncated = true;
  report_.truncation = std::move(what);
  done_ = true;
}

void McapReader::Fail(uint64_t offset, const std::string& what) const { throw McapError(Where(name_, offset) + what); }

}  // namespace locaid::bag
