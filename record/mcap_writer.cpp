#include "record/mcap_writer.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <limits>
#include <stdexcept>
#include <system_error>

namespace locaid::record {
namespace {

using mcap::Op;

// Schema id 0 means "no schema" and channel id 0 is avoided for the same
// reason, so both count from 1 and 65535 records is the most of each.
uint16_t NextId(size_t existing, const char* what) {
  if (existing >= std::numeric_limits<uint16_t>::max()) {
    throw std::length_error(std::string("McapWriter: more than 65535 ") + what + "s");
  }
  return static_cast<uint16_t>(existing + 1);
}

}  // namespace

struct McapWriter::ZstdContext {
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  ~ZstdContext() { ZSTD_freeCCtx(cctx); }
};

void McapWriter::OpenChunk::Clear() {
  records.clear();  // keeps the capacity: the next chunk reuses it
  index.clear();
  start_time = end_time = 0;
}

McapWriter::McapWriter(const std::filesystem::path& path, McapOptions options)
    : path_(path), options_(std::move(options)) {
  if (options_.zstd) {
    if (options_.zstd_level < ZSTD_minCLevel() || options_.zstd_level > ZSTD_maxCLevel()) {
      throw std::invalid_argument("McapWriter: zstd_level " + std::to_string(options_.zstd_level) + " is outside [" +
                                  std::to_string(ZSTD_minCLevel()) + ", " + std::to_string(ZSTD_maxCLevel()) + "]");
    }
    zstd_ = std::make_unique<ZstdContext>();
    if (zstd_->cctx == nullptr) throw std::runtime_error("McapWriter: cannot create a zstd compression context");
  }
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw std::system_error(errno, std::generic_category(), "McapWriter: cannot create '" + path_.string() + "'");
  }

  std::string start(mcap::kMagic);
  const size_t header = mcap::BeginRecord(start, Op::kHeader);
  mcap::PutString(start, options_.profile);
  mcap::PutString(start, options_.library);
  mcap::EndRecord(start, header);
  WriteToFile(start);
}

McapWriter::~McapWriter() {
  try {
    Close();
  } catch (...) {
    // A destructor cannot report; callers who care call Close() themselves.
  }
  CloseFd();
}

uint16_t McapWriter::AddSchema(std::string name, std::string encoding, std::string data) {
  RequireOpen("AddSchema");
  const uint16_t id = NextId(schemas_.size(), "schema");
  schemas_.push_back(Schema{std::move(name), std::move(encoding), std::move(data)});
  return id;
}

uint16_t McapWriter::AddChannel(uint16_t schema_id, std::string topic, std::string message_encoding,
                                std::map<std::string, std::string> metadata) {
  RequireOpen("AddChannel");
  if (schema_id > schemas_.size()) {
    throw std::invalid_argument("McapWriter::AddChannel: unknown schema id " + std::to_string(schema_id) +
                                " for topic '" + topic + "' in '" + path_.string() + "'");
  }
  const uint16_t id = NextId(channels_.size(), "channel");
  channels_.push_back(Channel{schema_id, std::move(topic), std::move(message_encoding), std::move(metadata)});
  return id;
}

void McapWriter::Write(uint16_t channel_id, uint64_t log_time_ns, uint64_t publish_time_ns, std::string_view data,
                       uint32_t sequence) {
  RequireOpen("Write");
  if (channel_id == 0 || channel_id > channels_.size()) {
    throw std::invalid_argument("McapWriter::Write: unknown channel id " + std::to_string(channel_id) + " in '" +
                                path_.string() + "'");
  }
  Channel& channel = channels_[channel_id - 1];
  if (!channel.in_file) AppendSchemaAndChannel(channel_id, channel);

  const uint64_t offset_in_chunk = chunk_.records.size();
  const size_t start = mcap::BeginRecord(chunk_.records, Op::kMessage);
  mcap::PutU16(chunk_.records, channel_id);
  mcap::PutU32(chunk_.records, sequence);
  mcap::PutU64(chunk_.records, log_time_ns);
  mcap::PutU64(chunk_.records, publish_time_ns);
  chunk_.records.append(data);
  mcap::EndRecord(chunk_.records, start);

  const bool first_in_chunk = chunk_.index.empty();
  chunk_.start_time = first_in_chunk ? log_time_ns : std::min(chunk_.start_time, log_time_ns);
  chunk_.end_time = first_in_chunk ? log_time_ns : std::max(chunk_.end_time, log_time_ns);
  chunk_.index[channel_id].emplace_back(log_time_ns, offset_in_chunk);
  start_time_ = message_count_ == 0 ? log_time_ns : std::min(start_time_, log_time_ns);
  end_time_ = message_count_ == 0 ? log_time_ns : std::max(end_time_, log_time_ns);
  ++message_count_;
  ++channel.message_count;

  if (chunk_.records.size() >= options_.chunk_size_bytes ||
      (options_.chunk_max_span_ns > 0 && chunk_.end_time - chunk_.start_time >= options_.chunk_max_span_ns)) {
    WriteChunk();
  }
}

void McapWriter::Close() {
  if (fd_ < 0) return;
  WriteChunk();
  WriteSummaryAndFooter();
  if (CloseFd() != 0) {
    throw std::system_error(errno, std::generic_category(), "McapWriter: cannot close '" + path_.string() + "'");
  }
}

// A channel's first message carries its Schema and Channel records into the
// chunk, ahead of the message, as the official writers do.
void McapWriter::AppendSchemaAndChannel(uint16_t channel_id, Channel& channel) {
  if (channel.schema_id != 0 && !schemas_[channel.schema_id - 1].in_file) {
    Schema& schema = schemas_[channel.schema_id - 1];
    mcap::AppendSchemaRecord(chunk_.records, channel.schema_id, schema.name, schema.encoding, schema.data);
    schema.in_file = true;
  }
  mcap::AppendChannelRecord(chunk_.records, channel_id, channel.schema_id, channel.topic, channel.message_encoding,
                            channel.metadata);
  channel.in_file = true;
}

// Chunk record, then one Message Index record per channel in the chunk.
void McapWriter::WriteChunk() {
  if (chunk_.index.empty()) return;
  const std::string_view records = chunk_.records;
  std::string_view payload = records;
  if (zstd_) {
    compressed_.resize(ZSTD_compressBound(records.size()));
    const size_t size = ZSTD_compressCCtx(zstd_->cctx, compressed_.data(), compressed_.size(), records.data(),
                                          records.size(), options_.zstd_level);
    if (ZSTD_isError(size)) {
      CloseFd();
      throw std::runtime_error("McapWriter: zstd compression of a chunk for '" + path_.string() +
                               "' failed: " + ZSTD_getErrorName(size));
    }
    payload = std::string_view(compressed_.data(), size);
  }

  ChunkIndex entry;
  entry.start_time = chunk_.start_time;
  entry.end_time = chunk_.end_time;
  entry.chunk_offset = offset_;
  entry.compressed_size = payload.size();
  entry.uncompressed_size = records.size();

  std::string head;
  const size_t start = mcap::BeginRecord(head, Op::kChunk);
  mcap::PutU64(head, chunk_.start_time);
  mcap::PutU64(head, chunk_.end_time);
  mcap::PutU64(head, records.size());
  mcap::PutU32(head, mcap::ComputeCrc32(records));
  mcap::PutString(head, zstd_ ? "zstd" : "");
  mcap::PutU64(head, payload.size());
  mcap::EndRecord(head, start, payload.size());
  entry.chunk_length = head.size() + payload.size();

  std::string indexes;
  for (auto& [channel_id, entries] : chunk_.index) {
    // Readers seek by time: a channel's entries go out in log-time order
    // (messages may have been written out of it, e.g. late GPS fixes).
    std::stable_sort(entries.begin(), entries.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    entry.message_index_offsets.emplace_back(channel_id, entry.chunk_offset + entry.chunk_length + indexes.size());
    const size_t index_start = mcap::BeginRecord(indexes, Op::kMessageIndex);
    mcap::PutU16(indexes, channel_id);
    mcap::PutU32(indexes, static_cast<uint32_t>(entries.size() * 16));  // Array byte length: 8 + 8 per entry
    for (const auto& [log_time, offset] : entries) {
      mcap::PutU64(indexes, log_time);
      mcap::PutU64(indexes, offset);
    }
    mcap::EndRecord(indexes, index_start);
  }
  entry.message_index_length = indexes.size();

  WriteToFile(head);
  WriteToFile(payload);
  WriteToFile(indexes);
  chunk_indexes_.push_back(std::move(entry));
  chunk_.Clear();
}

void McapWriter::WriteToFile(std::string_view bytes) {
  data_crc_.Update(bytes);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) FailIo("cannot write to", errno);
    done += static_cast<size_t>(n);
  }
  offset_ += bytes.size();
}

void McapWriter::RequireOpen(const char* operation) const {
  if (fd_ < 0) {
    throw std::logic_error(std::string("McapWriter::") + operation + " on '" + path_.string() +
                           "', which is closed (after Close() or an I/O error)");
  }
}

int McapWriter::CloseFd() {
  if (fd_ < 0) return 0;
  const int result = ::close(fd_);
  fd_ = -1;
  return result;
}

void McapWriter::FailIo(const char* what, int error) {
  CloseFd();
  throw std::system_error(error, std::generic_category(),
                          std::string("McapWriter: ") + what + " '" + path_.string() + "'");
}

}  // namespace locaid::record
