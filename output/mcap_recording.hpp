// An MCAP file of a session's poses with the same channels, schemas and
// messages the Foxglove bridge publishes live (output/channels.hpp), so a
// recording opens in Foxglove/Lichtblick with the same layout.
//
// Every channel and schema is registered up front (a channel that never gets
// a message still shows in the file's summary). Messages are logged at the
// pose's sensor time; their per-channel sequence counts 0, 1, 2, ...
// Errors are McapWriter's (std::system_error naming the file).
#pragma once

#include "output/channels.hpp"
#include "record/mcap_writer.hpp"

#include <array>
#include <cstdint>
#include <filesystem>

namespace locaid::output {

class McapRecording {
 public:
  explicit McapRecording(const std::filesystem::path& path, record::McapOptions options = {});
  void Add(const v1::PoseUpdate& pose);
  // Writes the summary and footer; the destructor does it too (swallowing errors).
  void Close();
  uint64_t poses() const { return poses_; }
  uint64_t messages() const { return writer_.messages_written(); }

 private:
  record::McapWriter writer_;
  PoseConverter converter_;
  std::array<uint16_t, static_cast<size_t>(Topic::kCount)> channel_ids_{};
  std::array<uint32_t, static_cast<size_t>(Topic::kCount)> sequences_{};
  uint64_t poses_ = 0;
};

}  // namespace locaid::output
