// McapWriter: records timestamped messages into an MCAP file (the container
// format Foxglove Studio and the `mcap` tools read), chunked and indexed.
//
// Layout written: magic, Header; then per chunk a Chunk record (zstd or
// uncompressed) followed by its Message Index records; at Close() Data End,
// the summary (Schema, Channel, Chunk Index, Statistics), Summary Offsets,
// Footer, magic. A Schema and a Channel record go into the first chunk that
// carries a message on that channel, so a reader streaming from the start of
// the file meets them before their messages.
//
// Guarantees:
//  - Bounded memory: at most one chunk is buffered. A chunk is closed once its
//    uncompressed records reach `chunk_size_bytes` (a single larger message
//    makes a chunk of its own) or its messages span `chunk_max_span_ns` of
//    log time. Besides the chunk, the writer keeps one Chunk Index entry per
//    written chunk (80 bytes + 16 per channel in the chunk: ~240 bytes with
//    the bridge's 9 channels, so ~21 MB for a day of 1 s chunks) and the
//    schemas and channels.
//  - Crash safety: every completed chunk and its indexes are handed to the
//    kernel with write(2) before Write() returns, with no user-space buffer.
//    A process killed at any point leaves a file whose complete chunks a
//    streaming reader still reads; only the summary and footer are missing,
//    and of the messages only the open chunk's: with the default span, at
//    most the last second of log time.
//    (No fsync: a power loss may still drop what the kernel had not stored.)
//  - No threads, no global state; not safe for concurrent calls on one object.
//  - Errors throw: std::system_error (a std::runtime_error) naming the file
//    and the errno text for I/O, std::invalid_argument for unknown ids, and
//    std::logic_error for use after Close(). After an I/O error the writer is
//    closed; the file then holds whatever reached it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "record/mcap_format.hpp"

namespace locaid::record {

struct McapOptions {
  size_t chunk_size_bytes = 1 << 20;  // uncompressed records per chunk before it is written
  // A chunk is also written once its messages span this much log time, so a
  // killed recorder loses at most that much (0: chunks close by size only).
  uint64_t chunk_max_span_ns = 1'000'000'000;
  bool zstd = true;                   // compress chunks with zstd; false: stored uncompressed
  int zstd_level = 1;  // measured on 1 s chunks of poses: faster and smaller than 3 (docs/benchmarks.md)
  std::string profile = "";  // Header profile, e.g. "ros2"; empty: none
  std::string library = "locaid";
};

class McapWriter {
 public:
  // Creates (or truncates) `path` and writes the magic and the Header.
  McapWriter(const std::filesystem::path& path, McapOptions options = {});
  // Close()s an open writer; an error there is swallowed, never thrown.
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Ids count up from 1. `encoding` names the schema language ("jsonschema",
  // "protobuf" with a FileDescriptorSet as data, ...); `data` is the schema.
  uint16_t AddSchema(std::string name, std::string encoding, std::string data);
  // schema_id 0: no schema (self-describing encodings such as "json").
  uint16_t AddChannel(uint16_t schema_id, std::string topic, std::string message_encoding,
                      std::map<std::string, std::string> metadata = {});
  // Times are nanoseconds on one epoch of the caller's choice (Unix time for
  // Foxglove). Writes the chunk to the file when it is full or spans
  // chunk_max_span_ns.
  void Write(uint16_t channel_id, uint64_t log_time_ns, uint64_t publish_time_ns, std::string_view data,
             uint32_t sequence = 0);
  // Writes the last chunk, the summary and the footer, and closes the file.
  // A second call does nothing.
  void Close();

  uint64_t messages_written() const { return message_count_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  struct Schema {
    std::string name, encoding, data;
    bool in_file = false;  // its record went into a chunk already
  };
  struct Channel {
    uint16_t schema_id = 0;
    std::string topic, message_encoding;
    std::map<std::string, std::string> metadata;
    uint64_t message_count = 0;
    bool in_file = false;  // its record went into a chunk already
  };
  // The Chunk Index record's fields of one written chunk.
  struct ChunkIndex {
    uint64_t start_time = 0, end_time = 0;
    uint64_t chunk_offset = 0, chunk_length = 0;
    std::vector<std::pair<uint16_t, uint64_t>> message_index_offsets;  // by channel id
    uint64_t message_index_length = 0;
    uint64_t compressed_size = 0, uncompressed_size = 0;
  };
  // The records of the chunk being filled, uncompressed, and what its
  // Chunk and Message Index records need.
  struct OpenChunk {
    std::string records;
    std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> index;  // channel -> (log time, offset)
    uint64_t start_time = 0, end_time = 0;
    void Clear();
  };

  void AppendSchemaAndChannel(uint16_t channel_id, Channel& channel);
  void WriteChunk();
  void WriteSummaryAndFooter();
  // Writes to the file, advancing the offset and the data-section CRC.
  void WriteToFile(std::string_view bytes);
  void RequireOpen(const char* operation) const;
  // Closes the file descriptor (leaving the file as it is); close(2)'s result.
  int CloseFd();
  // Closes the file and throws std::system_error for `errno` `error`.
  [[noreturn]] void FailIo(const char* what, int error);

  std::filesystem::path path_;
  McapOptions options_;
  int fd_ = -1;
  uint64_t offset_ = 0;
  mcap::Crc32 data_crc_;           // of every byte written before Data End
  std::vector<Schema> schemas_;    // id = index + 1
  std::vector<Channel> channels_;  // id = index + 1
  OpenChunk chunk_;
  std::vector<ChunkIndex> chunk_indexes_;
  uint64_t message_count_ = 0;
  uint64_t start_time_ = 0, end_time_ = 0;
  std::string compressed_;  // reused zstd output buffer
  struct ZstdContext;
  std::unique_ptr<ZstdContext> zstd_;
};

}  // namespace locaid::record
