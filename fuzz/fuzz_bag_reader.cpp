// libFuzzer target: ROS 2 bag files (bag/mcap_reader.hpp, ros/cdr.hpp).
// Contract: McapReader reads messages or throws McapError; what it returns is
// consistent with its report (indexes count up, every message is on a
// declared channel, a stop is the Data End, the footer or a reported cut).
// Each message's data goes through CdrReader, which reads or throws CdrError.
#include "bag/mcap_reader.hpp"
#include "fuzz/fuzz_support.hpp"
#include "ros/cdr.hpp"
#include "ros/messages.hpp"

#include <memory>
#include <sstream>
#include <vector>

namespace {

using locaid::bag::McapChannel;
using locaid::bag::McapMessage;
using locaid::bag::McapReader;
using locaid::ros::CdrError;
using locaid::ros::CdrReader;

// A message shaped like most ROS 2 sensor messages: a std_msgs/Header
// (stamp sec, nanosec, frame_id), then float64 sequences and fields until the
// data runs out.
void ReadAsCdr(std::string_view data) {
  try {
    CdrReader cdr(data);
    cdr.I32();
    cdr.U32();
    cdr.String();
    std::vector<double> values;
    while (true) {
      const uint32_t n = cdr.SequenceLength(8);
      LOCAID_FUZZ_CHECK(n <= cdr.remaining() / 8, "sequence count beyond the bytes left");
      values.resize(n);
      cdr.F64Array(values.data(), n);
      cdr.F64();
      LOCAID_FUZZ_CHECK(cdr.offset() <= data.size(), "offset past the data");
    }
  } catch (const CdrError&) {
  }
}

// One message through the decoders: the generic CDR walk, then the ROS 2
// decoder of its schema's type, and of every type the bag source reads (a
// lying schema name must not matter either).
void FuzzMessage(const McapReader& reader, const McapChannel& channel, const McapMessage& message) {
  if (channel.message_encoding != "cdr") return;
  ReadAsCdr(message.data);
  const auto schema = reader.schemas().find(channel.schema_id);
  std::vector<std::string_view> types = {
      locaid::ros::kImage,     locaid::ros::kCompressedImage, locaid::ros::kCameraInfo,  locaid::ros::kImu,
      locaid::ros::kNavSatFix, locaid::ros::kTfMessage,       locaid::ros::kTwistStamped};
  if (schema != reader.schemas().end()) types.insert(types.begin(), schema->second.name);
  for (const auto type : types) {
    try {
      locaid::ros::DecodeAny(type, message.data);
    } catch (const CdrError&) {
      // a precise error is the expected outcome for bytes that are not this type
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(locaid::fuzz::AsText(data, size));
  try {
    McapReader reader(std::make_unique<std::istringstream>(bytes), "fuzz.mcap");
    McapMessage message;
    uint64_t count = 0;
    while (reader.Next(message)) {
      LOCAID_FUZZ_CHECK(message.index == count++, "message index does not count up");
      LOCAID_FUZZ_CHECK(message.data.size() <= size, "message larger than the file");
      const auto channel = reader.channels().find(message.channel_id);
      LOCAID_FUZZ_CHECK(channel != reader.channels().end(), "message on an undeclared channel");
      FuzzMessage(reader, channel->second, message);
    }
    const auto& report = reader.report();
    LOCAID_FUZZ_CHECK(report.messages == count, "report().messages differs from the messages returned");
    LOCAID_FUZZ_CHECK(report.file_bytes == size, "report().file_bytes is not the input size");
    LOCAID_FUZZ_CHECK(report.truncated != report.truncation.empty(), "truncated without a reason, or the reverse");
    LOCAID_FUZZ_CHECK(!(report.truncated && report.summary_present), "both cut and complete");
    LOCAID_FUZZ_CHECK(report.chunks_bad_crc <= report.chunks, "more bad chunks than chunks");
    LOCAID_FUZZ_CHECK(!reader.Next(message), "Next() after the end returned a message");
  } catch (const locaid::bag::McapError& e) {
    LOCAID_FUZZ_CHECK(std::string_view(e.what()).find("'fuzz.mcap'") != std::string_view::npos,
                      std::string("McapError without the file name: ") + e.what());
  }
  return 0;
}
