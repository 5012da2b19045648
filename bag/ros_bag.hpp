// RosBag: the messages of a ROS 2 bag in file order: one .mcap file, or a
// rosbag2 directory (metadata.yaml and its split .mcap files, read in the
// order metadata.yaml lists them; without metadata.yaml, every .mcap file of
// the directory in name order).
//
// Only messages a bag source can use are returned: channel encoding "cdr"
// with a "ros2msg" (or "ros2idl") schema; others are counted per topic and
// skipped. A file cut short is read up to its last complete record and noted
// (notes()); every other error of a file is McapError naming it.
#pragma once

#include "bag/mcap_reader.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::bag {

struct BagMessage {
  std::string_view topic, type;  // type: the schema name, e.g. sensor_msgs/msg/Imu
  std::string_view data;         // CDR; valid until the next Next()
  uint64_t log_time_ns = 0;
  std::string_view file;  // the .mcap file it came from
  uint64_t index = 0;     // the message's index in that file (0-based)

  // "FILE: topic /imu/data, message 12": for errors about this message.
  std::string Where() const;
};

class RosBag {
 public:
  // Throws std::runtime_error for a path that is neither a readable .mcap file
  // nor a directory with one, and McapError for a file that is not MCAP.
  explicit RosBag(const std::filesystem::path& path);

  bool Next(BagMessage& out);

  const std::vector<std::filesystem::path>& files() const { return files_; }
  uint64_t total_bytes() const { return total_bytes_; }
  uint64_t bytes_done() const;  // of the files read so far (progress)
  // Cut files, chunks skipped for a bad CRC, topics skipped for their
  // encoding: one line each, for a user.
  std::vector<std::string> notes() const;
  // Messages skipped for their encoding, by topic.
  const std::map<std::string, uint64_t>& skipped_by_topic() const { return skipped_; }

 private:
  bool OpenNext();
  void NoteFile(const McapReader& reader);

  std::vector<std::filesystem::path> files_;
  size_t next_file_ = 0;
  uint64_t total_bytes_ = 0, bytes_before_current_ = 0;
  std::unique_ptr<McapReader> reader_;
  std::string current_file_;
  std::map<std::string, uint64_t> skipped_;
  std::vector<std::string> notes_;
};

}  // namespace locaid::bag
