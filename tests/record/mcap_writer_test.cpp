// McapWriter checked byte by byte with the test's own small reader
// (mcap_test_reader.hpp): framing, CRCs, indexes, statistics, the file left
// behind mid-recording, and the errors the writer reports.
#include "record/mcap_writer.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

#include "mcap_test_reader.hpp"
#include "sample_recording.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using locaid::record::McapOptions;
using locaid::record::McapWriter;
namespace rt = locaid::record::testing;

namespace {

constexpr size_t kSmallChunkBytes = 4096;  // many chunks from a few seconds of data

class McapWriterFileTest : public ::testing::Test {
 protected:
  const locaid::test_support::ScopedTempDir dir_{"mcap"};
};

TEST(McapCrc32, MatchesTheStandardCheckValue) {
  // "123456789" -> 0xCBF43926 is the published check value of this CRC-32.
  EXPECT_EQ(rt::ReferenceCrc32("123456789"), 0xCBF43926u);
  EXPECT_EQ(locaid::record::mcap::ComputeCrc32("123456789"), 0xCBF43926u);
  locaid::record::mcap::Crc32 pieces;
  pieces.Update("1234");
  pieces.Update("56789");
  EXPECT_EQ(pieces.Value(), 0xCBF43926u);
}

TEST_F(McapWriterFileTest, EmptyRecordingHasHeaderSummaryAndFooter) {
  const fs::path path = dir_ / "empty.mcap";
  {
    McapWriter writer(path, McapOptions{.profile = "", .library = "locaid-test"});
    EXPECT_EQ(writer.messages_written(), 0u);
  }  // the destructor closes
  const std::string file = rt::ReadFileBytes(path);
  ASSERT_GE(file.size(), 9u);
  EXPECT_EQ(file.substr(0, 8), std::string("\x89MCAP0\r\n", 8));
  EXPECT_EQ(static_cast<uint8_t>(file[8]), 0x01) << "the Header record follows the magic";

  const rt::StreamScan scan = rt::ScanStream(file);
  EXPECT_FALSE(scan.truncated);
  EXPECT_TRUE(scan.data_end_seen);
  EXPECT_EQ(scan.header_library, "locaid-test");
  EXPECT_EQ(scan.chunk_count, 0u);
  const rt::Summary summary = rt::CheckSummary(file);
  EXPECT_EQ(summary.message_count, 0u);
  EXPECT_EQ(summary.chunk_count, 0u);
  EXPECT_EQ(summary.records_per_opcode.at(0x0B), 1) << "one Statistics record";
}

class McapWriterCompressionTest : public McapWriterFileTest, public ::testing::WithParamInterface<bool> {};

TEST_P(McapWriterCompressionTest, ChunksIndexesCrcsAndStatisticsAgree) {
  const bool zstd = GetParam();
  const fs::path path = dir_ / "drive.mcap";
  const McapOptions options{.chunk_size_bytes = kSmallChunkBytes, .zstd = zstd, .profile = "", .library = "locaid"};
  const rt::SampleRecording sample =
      rt::WriteSampleRecording(path, options, 10, /*large_message_bytes=*/3 * kSmallChunkBytes);
  const std::string file = rt::ReadFileBytes(path);

  rt::StreamScan scan;
  ASSERT_NO_THROW(scan = rt::ScanStream(file));
  EXPECT_FALSE(scan.truncated);
  EXPECT_TRUE(scan.data_end_seen);
  EXPECT_EQ(scan.header_library, "locaid");
  EXPECT_EQ(scan.messages.size(), sample.message_count);
  EXPECT_GT(scan.chunk_count, 5u) << "a " << kSmallChunkBytes << "-byte chunk size splits 10 s of data";
  for (const std::string& compression : scan.chunk_compressions) EXPECT_EQ(compression, zstd ? "zstd" : "");
  EXPECT_EQ(scan.schema_names.size(), static_cast<size_t>(rt::kSampleSchemas));
  EXPECT_EQ(scan.channel_topics.size(), 3u) << "a channel's record goes in with its first message";

  rt::Summary summary;
  ASSERT_NO_THROW(summary = rt::CheckSummary(file));
  EXPECT_EQ(summary.message_count, sample.message_count);
  EXPECT_EQ(summary.schema_count, rt::kSampleSchemas);
  EXPECT_EQ(summary.channel_count, static_cast<uint32_t>(rt::kSampleChannels));
  EXPECT_EQ(summary.chunk_count, scan.chunk_count);
  EXPECT_EQ(summary.chunk_index_count, scan.chunk_count);
  EXPECT_EQ(summary.start_time, sample.start_time_ns);
  EXPECT_EQ(summary.end_time, sample.end_time_ns);
  EXPECT_EQ(summary.channel_message_counts.at(1), sample.messages_per_topic.at("/locaid/pose"));
  EXPECT_EQ(summary.channel_message_counts.at(2), sample.messages_per_topic.at("/locaid/gps"));
  EXPECT_EQ(summary.channel_message_counts.at(3), sample.messages_per_topic.at("/locaid/vo_status"));
  EXPECT_FALSE(summary.channel_message_counts.contains(4)) << "the unused channel has no count";
  EXPECT_EQ(summary.records_per_opcode.at(0x03), rt::kSampleSchemas);
  EXPECT_EQ(summary.records_per_opcode.at(0x04), rt::kSampleChannels);
  EXPECT_EQ(summary.summary_offset_opcodes.size(), 4u) << "Schema, Channel, Chunk Index, Statistics groups";

  std::cout << "[   info   ] " << (zstd ? "zstd" : "uncompressed") << ": " << file.size() << " bytes, "
            << scan.chunk_count << " chunks, " << sample.message_count << " messages\n";
}

INSTANTIATE_TEST_SUITE_P(ZstdAndUncompressed, McapWriterCompressionTest, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Zstd" : "Uncompressed"; });

TEST_F(McapWriterFileTest, FullChunksAreInTheFileBeforeClose) {
  const fs::path path = dir_ / "open.mcap";
  McapWriter writer(path, McapOptions{.chunk_size_bytes = kSmallChunkBytes, .zstd = true});
  const uint16_t channel = writer.AddChannel(0, "/locaid/gps", "json");
  // About 150 bytes a message: three and a half chunks, nothing flushed by hand.
  const uint32_t written = 100;
  for (uint32_t i = 0; i < written; ++i) {
    writer.Write(channel, rt::kSampleStartNs + i, rt::kSampleStartNs + i, rt::SamplePayload("/locaid/gps", i), i);
  }
  const rt::StreamScan scan = rt::ScanStream(rt::ReadFileBytes(path));
  EXPECT_TRUE(scan.truncated) << "no footer yet";
  EXPECT_GE(scan.chunk_count, 3u);
  EXPECT_GT(scan.messages.size(), 0u);
  EXPECT_LT(scan.messages.size(), written) << "the open chunk stays in memory";
  for (size_t i = 0; i < scan.messages.size(); ++i) ASSERT_EQ(scan.messages[i].sequence, i);
}

// Small messages never fill a chunk; the log-time span closes it instead, so
// a recorder killed mid-session loses at most that span.
TEST_F(McapWriterFileTest, AChunkClosesOnceItSpansItsMaximumLogTime) {
  const fs::path path = dir_ / "span.mcap";
  McapWriter writer(path, McapOptions{.chunk_max_span_ns = 1'000'000'000, .zstd = true});
  const uint16_t channel = writer.AddChannel(0, "/locaid/gps", "json");
  // 10 Hz for 3.05 s: chunks of 0.0-1.0, 1.1-2.1, 2.2-3.0 s (the third still open).
  const uint32_t written = 31;
  for (uint32_t i = 0; i < written; ++i) {
    const uint64_t t = rt::kSampleStartNs + uint64_t{i} * 100'000'000;
    writer.Write(channel, t, t, rt::SamplePayload("/locaid/gps", i), i);
  }
  const rt::StreamScan scan = rt::ScanStream(rt::ReadFileBytes(path));
  EXPECT_TRUE(scan.truncated) << "no footer yet";
  EXPECT_EQ(scan.chunk_count, 2u);
  EXPECT_EQ(scan.messages.size(), 22u);  // 11 per chunk: 1.0 s is reached by the 11th message

  McapWriter by_size(dir_ / "size.mcap", McapOptions{.chunk_max_span_ns = 0, .zstd = true});
  const uint16_t c = by_size.AddChannel(0, "/locaid/gps", "json");
  for (uint32_t i = 0; i < written; ++i) {
    const uint64_t t = rt::kSampleStartNs + uint64_t{i} * 100'000'000;
    by_size.Write(c, t, t, rt::SamplePayload("/locaid/gps", i), i);
  }
  EXPECT_EQ(rt::ScanStream(rt::ReadFileBytes(dir_ / "size.mcap")).chunk_count, 0u) << "1 MiB chunks: none full yet";
}

TEST_F(McapWriterFileTest, UnknownIdsAreRejectedNamingTheId) {
  McapWriter writer(dir_ / "ids.mcap");
  try {
    writer.AddChannel(7, "/x", "json");
    FAIL() << "schema 7 does not exist";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown schema id 7"), std::string::npos) << e.what();
  }
  try {
    writer.Write(3, 1, 1, "{}");
    FAIL() << "channel 3 does not exist";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown channel id 3"), std::string::npos) << e.what();
  }
}

TEST_F(McapWriterFileTest, UseAfterCloseIsALogicError) {
  McapWriter writer(dir_ / "closed.mcap");
  const uint16_t channel = writer.AddChannel(0, "/x", "json");
  writer.Close();
  writer.Close();  // a second Close does nothing
  EXPECT_THROW(writer.Write(channel, 1, 1, "{}"), std::logic_error);
  EXPECT_THROW(writer.AddSchema("s", "jsonschema", "{}"), std::logic_error);
}

TEST(McapWriterErrors, UnopenableFileNamesPathAndErrno) {
  const fs::path path = "/nonexistent-locaid-dir/x.mcap";
  try {
    McapWriter writer(path);
    FAIL() << "the folder does not exist";
  } catch (const std::system_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find("No such file or directory"), std::string::npos) << what;
    EXPECT_EQ(e.code().value(), ENOENT);
  }
}

TEST(McapWriterErrors, FullDiskIsReportedWithTheErrnoText) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "/dev/full absent";
  try {
    McapWriter writer("/dev/full");  // the Header write already fails
    FAIL() << "/dev/full accepts no bytes";
  } catch (const std::system_error& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.code().value(), ENOSPC);
    EXPECT_NE(what.find("/dev/full"), std::string::npos) << what;
    EXPECT_NE(what.find("No space left on device"), std::string::npos) << what;
  }
}

TEST(McapWriterErrors, ZstdLevelOutOfRangeIsRejected) {
  const locaid::test_support::ScopedTempDir dir("mcap");
  const fs::path path = dir / "never-created.mcap";
  EXPECT_THROW(McapWriter(path, McapOptions{.zstd = true, .zstd_level = 1000}), std::invalid_argument);
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
