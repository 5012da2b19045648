#include "output/mcap_recording.hpp"

#include <map>
#include <string>

namespace locaid::output {

McapRecording::McapRecording(const std::filesystem::path& path, record::McapOptions options)
    : writer_(path, std::move(options)) {
  // One Schema record per schema name (three channels share LocationFix).
  // MCAP names the encodings "jsonschema" and "protobuf", as the WebSocket
  // protocol does.
  std::map<std::string, uint16_t> schema_ids;
  for (size_t i = 0; i < channel_ids_.size(); ++i) {
    const ChannelSpec& spec = Channels()[i];
    auto [it, added] = schema_ids.emplace(spec.schema_name, 0);
    if (added) it->second = writer_.AddSchema(spec.schema_name, spec.schema_encoding, spec.schema);
    channel_ids_[i] = writer_.AddChannel(it->second, spec.topic, spec.encoding);
  }
}

void McapRecording::Add(const v1::PoseUpdate& pose) {
  for (const OutMessage& m : converter_.Convert(pose)) {
    const auto i = static_cast<size_t>(m.topic);
    writer_.Write(channel_ids_[i], m.log_time_ns, m.log_time_ns, m.data, sequences_[i]++);
  }
  ++poses_;
}

void McapRecording::Close() { writer_.Close(); }

}  // namespace locaid::output
