// McapReader: reads the messages of an MCAP file (rosbag2's default storage,
// the files Foxglove and the `mcap` tools write) in file order, one record at
// a time, for the ROS 2 bag source (ros_bag.hpp).
//
// Reads files with and without chunks; chunk compression "" (none), "zstd"
// and "lz4" (LZ4 frame format); with or without summary, indexes and footer.
// The summary section is not needed: schemas and channels are taken from the
// data section as they come (a writer puts them before their messages).
//
// A file cut short (a recorder killed mid-write) is not an error: every
// complete record before the cut is read, and report().truncated says where
// the file ends and what was cut (also for a file that ends inside the
// leading magic or the Header record, an empty file included: no messages). A chunk whose uncompressed CRC does not
// match is skipped and counted (report().chunks_bad_crc); its messages are
// lost, the rest of the file is read. After such a chunk, a message on a
// channel no Channel record declared (its record may have been in the
// skipped chunk) is skipped too and counted in messages_in_bad_chunks.
//
// Errors (McapError, a std::runtime_error naming the file and the byte offset
// of the record): not an MCAP file (bad magic), unreadable file, unknown chunk
// compression, a chunk that does not decompress to its stated size, a record
// whose content is shorter than its fields, a message on a channel no Channel
// record declared before it, a channel whose schema was not declared.
//
// Bounds: one chunk is held at a time, compressed and uncompressed; a chunk
// stating more than kMaxChunkBytes uncompressed is an error (never allocated).
// No threads, no global state; not safe for concurrent calls on one object.
#pragma once

#include <cstdint>
#include <filesystem>
#include <istream>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

namespace locaid::bag {

class McapError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct McapSchema {
  uint16_t id = 0;
  std::string name;      // e.g. "sensor_msgs/msg/Image"
  std::string encoding;  // e.g. "ros2msg"
  std::string data;      // the schema text
};

struct McapChannel {
  uint16_t id = 0;
  uint16_t schema_id = 0;  // 0: no schema
  std::string topic;
  std::string message_encoding;  // e.g. "cdr"
  std::map<std::string, std::string> metadata;
};

struct McapMessage {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time_ns = 0, publish_time_ns = 0;
  std::string_view data;     // valid until the next call of Next()
  uint64_t record_offset = 0;  // byte offset of the Message record, or of its Chunk
  uint64_t index = 0;          // 0, 1, 2, ... over the messages this reader returned
};

struct McapReadReport {
  uint64_t file_bytes = 0;
  uint64_t chunks = 0, chunks_bad_crc = 0, messages_in_bad_chunks = 0;  // bad: skipped
  uint64_t messages = 0;     // returned by Next()
  bool summary_present = false;  // a Data End record was reached (the data section is complete)
  bool truncated = false;        // the file ends inside a record or before the footer
  std::string truncation;        // truncated: where and what was cut, for a user
};

class McapReader {
 public:
  // Largest uncompressed chunk accepted (bytes).
  static constexpr uint64_t kMaxChunkBytes = uint64_t{1} << 30;

  // Opens `path` and checks the leading magic and the Header record.
  explicit McapReader(const std::filesystem::path& path);
  // Reads from `in` (any seekable stream: its size is taken with seekg/tellg
  // once, up front); `name` stands for the file in error messages and
  // reports. path() is then empty.
  McapReader(std::unique_ptr<std::istream> in, std::string name);

  // The next message in file order; false at the end of the data (Data End,
  // the footer, or a cut).
  bool Next(McapMessage& out);

  const std::map<uint16_t, McapSchema>& schemas() const { return schemas_; }
  const std::map<uint16_t, McapChannel>& channels() const { return channels_; }
  const std::string& profile() const { return profile_; }  // Header profile ("ros2" for rosbag2)
  const McapReadReport& report() const { return report_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  // Implementation-defined: the open stream, the current chunk's
  // decompressed records and the position in them.
  void Open();
  bool NextRecordInFile(uint8_t& op, std::string& content, uint64_t& offset);
  bool NextInChunk(McapMessage& out);
  void LoadChunk(std::string_view content, uint64_t offset);
  void OnSchema(std::string_view content, uint64_t offset);
  void OnChannel(std::string_view content, uint64_t offset);
  bool OnMessage(std::string_view content, uint64_t offset, McapMessage& out);
  void ReadExactly(char* out, uint64_t n, uint64_t offset);
  void Truncated(std::string what);
  [[noreturn]] void Fail(uint64_t offset, const std::string& what) const;

  std::filesystem::path path_;
  std::string name_;  // the path, or the stream's name: for messages
  std::unique_ptr<std::istream> in_;
  uint64_t pos_ = 0;
  std::string profile_;
  std::map<uint16_t, McapSchema> schemas_;
  std::map<uint16_t, McapChannel> channels_;
  McapReadReport report_;
  std::string record_;          // content of the record read last
  std::string chunk_;           // decompressed records of the current chunk
  size_t chunk_pos_ = 0;        // next record in chunk_
  uint64_t chunk_offset_ = 0;   // file offset of the current chunk
  bool done_ = false;
};

}  // namespace locaid::bag
