// McapReader on files our McapWriter writes (zstd and uncompressed chunks,
// with summary) and on files assembled byte by byte here (top-level messages,
// lz4 chunks, no summary, cut at every length, bad CRCs, broken records).
#include "bag/mcap_reader.hpp"
#include "error_of.hpp"
#include "record/mcap_format.hpp"
#include "record/mcap_writer.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <lz4frame.h>

#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace locaid::bag {
namespace {

namespace mcap = record::mcap;
using test_support::ErrorOf;

struct Msg {
  uint16_t channel = 0;
  uint32_t sequence = 0;
  uint64_t log_time_ns = 0, publish_time_ns = 0;
  std::string data;
  bool operator==(const Msg&) const = default;
};

// The messages Next() returns from here on (indexes count on from the ones read before).
std::vector<Msg> ReadAll(McapReader& reader) {
  std::vector<Msg> out;
  const uint64_t first = reader.report().messages;
  McapMessage m;
  while (reader.Next(m)) {
    EXPECT_EQ(m.index, first + out.size());
    out.push_back(Msg{m.channel_id, m.sequence, m.log_time_ns, m.publish_time_ns, std::string(m.data)});
  }
  return out;
}

McapReader FromBytes(const std::string& bytes, const std::string& name = "test-bytes") {
  return McapReader(std::make_unique<std::istringstream>(bytes), name);
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// ---- byte-level file assembly (record/mcap_format.hpp's appenders) ----------

std::string Start(const std::string& profile = "ros2") {
  std::string out(mcap::kMagic);
  const size_t at = mcap::BeginRecord(out, mcap::Op::kHeader);
  mcap::PutString(out, profile);
  mcap::PutString(out, "bag-test");
  mcap::EndRecord(out, at);
  return out;
}

void AppendMessage(std::string& out, const Msg& m) {
  const size_t at = mcap::BeginRecord(out, mcap::Op::kMessage);
  mcap::PutU16(out, m.channel);
  mcap::PutU32(out, m.sequence);
  mcap::PutU64(out, m.log_time_ns);
  mcap::PutU64(out, m.publish_time_ns);
  out += m.data;
  mcap::EndRecord(out, at);
}

// Schema 1 + channel `channel` on it.
void AppendDeclarations(std::string& out, uint16_t channel, const std::string& topic) {
  mcap::AppendSchemaRecord(out, 1, "sensor_msgs/msg/Imu", "ros2msg", "std_msgs/Header header\n");
  mcap::AppendChannelRecord(out, channel, 1, topic, "cdr", {{"offered_qos_profiles", "- history: 3"}});
}

// A Chunk record around `records`, whose payload is `payload` (the records,
// compressed or not); `crc` overrides the CRC of `records`.
void AppendChunk(std::string& out, const std::string& records, const std::string& compression,
                 const std::string& payload, std::optional<uint32_t> crc = std::nullopt,
                 std::optional<uint64_t> uncompressed_size = std::nullopt) {
  const size_t at = mcap::BeginRecord(out, mcap::Op::kChunk);
  mcap::PutU64(out, 0);
  mcap::PutU64(out, 0);
  mcap::PutU64(out, uncompressed_size.value_or(records.size()));
  mcap::PutU32(out, crc.value_or(mcap::ComputeCrc32(records)));
  mcap::PutString(out, compression);
  mcap::PutU64(out, payload.size());
  out += payload;
  mcap::EndRecord(out, at);
}

void AppendEnd(std::string& out) {
  size_t at = mcap::BeginRecord(out, mcap::Op::kDataEnd);
  mcap::PutU32(out, 0);
  mcap::EndRecord(out, at);
  at = mcap::BeginRecord(out, mcap::Op::kFooter);
  mcap::PutU64(out, 0);
  mcap::PutU64(out, 0);
  mcap::PutU32(out, 0);
  mcap::EndRecord(out, at);
  out += mcap::kMagic;
}

std::string Lz4Frame(const std::string& bytes) {
  std::string out(LZ4F_compressFrameBound(bytes.size(), nullptr), '\0');
  const size_t n = LZ4F_compressFrame(out.data(), out.size(), bytes.data(), bytes.size(), nullptr);
  EXPECT_FALSE(LZ4F_isError(n));
  out.resize(n);
  return out;
}

Msg Sample(uint16_t channel, uint32_t i) {
  return Msg{channel, i, 1'000'000'000ull + i * 10'000'000ull, 2'000'000'000ull + i,
             "payload-" + std::to_string(channel) + "-" + std::string(i % 7, 'x') + std::to_string(i)};
}

// ---- files written by record::McapWriter -------------------------------------

struct WrittenFile {
  std::string bytes;
  std::vector<Msg> messages;
};

WrittenFile WriteWithMcapWriter(const std::filesystem::path& path, bool zstd, int count) {
  record::McapOptions options;
  options.zstd = zstd;
  options.chunk_size_bytes = 300;
  options.profile = "ros2";
  WrittenFile file;
  {
    record::McapWriter writer(path, options);
    const uint16_t schema = writer.AddSchema("sensor_msgs/msg/Imu", "ros2msg", "float64 x\n");
    const uint16_t imu = writer.AddChannel(schema, "/imu", "cdr", {{"offered_qos_profiles", "reliable"}});
    const uint16_t fix = writer.AddChannel(0, "/fix", "cdr");
    for (int i = 0; i < count; ++i) {
      const Msg m = Sample(i % 3 == 0 ? fix : imu, static_cast<uint32_t>(i));
      writer.Write(m.channel, m.log_time_ns, m.publish_time_ns, m.data, m.sequence);
      file.messages.push_back(m);
    }
    writer.Close();
  }
  file.bytes = ReadFile(path);
  return file;
}

TEST(McapReader, ReadsEveryMessageOfAWriterFileInOrder) {
  for (const bool zstd : {true, false}) {
    SCOPED_TRACE(zstd ? "zstd" : "uncompressed");
    const test_support::ScopedTempDir dir("bag_writer");
    const WrittenFile file = WriteWithMcapWriter(dir / "w.mcap", zstd, 60);
    McapReader reader(dir / "w.mcap");
    EXPECT_EQ(reader.profile(), "ros2");
    EXPECT_EQ(reader.path(), dir / "w.mcap");
    EXPECT_EQ(ReadAll(reader), file.messages);
    const McapReadReport& report = reader.report();
    EXPECT_EQ(report.messages, 60u);
    EXPECT_GT(report.chunks, 3u);
    EXPECT_EQ(report.chunks_bad_crc, 0u);
    EXPECT_TRUE(report.summary_present);
    EXPECT_FALSE(report.truncated) << report.truncation;
    EXPECT_EQ(report.file_bytes, file.bytes.size());
    ASSERT_EQ(reader.channels().size(), 2u);
    const McapChannel& imu = reader.channels().at(1);
    EXPECT_EQ(imu.topic, "/imu");
    EXPECT_EQ(imu.schema_id, 1);
    EXPECT_EQ(imu.message_encoding, "cdr");
    EXPECT_EQ(imu.metadata.at("offered_qos_profiles"), "reliable");
    EXPECT_EQ(reader.channels().at(2).schema_id, 0);
    ASSERT_EQ(reader.schemas().size(), 1u);
    EXPECT_EQ(reader.schemas().at(1).name, "sensor_msgs/msg/Imu");
    EXPECT_EQ(reader.schemas().at(1).encoding, "ros2msg");
    EXPECT_EQ(reader.schemas().at(1).data, "float64 x\n");
    McapMessage m;
    EXPECT_FALSE(reader.Next(m));  // stays at the end
  }
}

// A cut at any byte: no exception, a prefix of the messages, and either the
// data section was complete (cut in the summary) or the cut is reported.
TEST(McapReader, AFileCutAtEveryLengthYieldsAPrefixAndSaysSo) {
  const test_support::ScopedTempDir dir("bag_cut");
  for (const bool zstd : {true, false}) {
    SCOPED_TRACE(zstd ? "zstd" : "uncompressed");
    const WrittenFile file = WriteWithMcapWriter(dir / "w.mcap", zstd, 12);
    size_t previous = 0;
    bool saw_record_cut = false;
    for (size_t n = 0; n < file.bytes.size(); ++n) {
      SCOPED_TRACE("cut at " + std::to_string(n));
      std::vector<Msg> got;
      McapReadReport report;
      ASSERT_NO_THROW({
        McapReader reader = FromBytes(file.bytes.substr(0, n));
        got = ReadAll(reader);
        report = reader.report();
      });
      ASSERT_LE(got.size(), file.messages.size());
      EXPECT_TRUE(std::equal(got.begin(), got.end(), file.messages.begin()));
      EXPECT_GE(got.size(), previous);  // a longer prefix of the file never reads fewer
      previous = got.size();
      EXPECT_NE(report.truncated, report.summary_present) << report.truncation;
      EXPECT_EQ(report.truncated, !report.truncation.empty());
      if (report.summary_present) {
        EXPECT_EQ(got.size(), file.messages.size());
      }
      saw_record_cut |= report.truncation.find("inside a Chunk record that starts at byte") != std::string::npos;
    }
    EXPECT_TRUE(saw_record_cut);
    EXPECT_EQ(previous, file.messages.size());
  }
}

TEST(McapReader, CutMessageSaysWhereAndHowMuchIsMissing) {
  std::string bytes = Start();
  AppendDeclarations(bytes, 3, "/imu");
  AppendMessage(bytes, Sample(3, 0));
  const size_t second = bytes.size();
  AppendMessage(bytes, Sample(3, 1));
  const size_t full = bytes.size();
  McapReader reader = FromBytes(bytes.substr(0, full - 5), "cut.mcap");
  EXPECT_EQ(ReadAll(reader).size(), 1u);
  EXPECT_TRUE(reader.report().truncated);
  EXPECT_EQ(reader.report().truncation, "file ends at byte " + std::to_string(full - 5) +
                                            " inside a Message record that starts at byte " + std::to_string(second) +
                                            " (needs 5 more bytes); the messages before it were read");
}

TEST(McapReader, ReadsTopLevelMessagesAndSkipsRecordsItDoesNotUse) {
  std::string bytes = Start("");
  AppendDeclarations(bytes, 5, "/gps/fix");
  std::vector<Msg> expected;
  std::vector<uint64_t> offsets;
  for (uint32_t i = 0; i < 4; ++i) {
    offsets.push_back(bytes.size());
    expected.push_back(Sample(5, i));
    AppendMessage(bytes, expected.back());
    mcap::PutU8(bytes, 0x42);  // an opcode of a later format version, skipped
    mcap::PutU64(bytes, 3);
    bytes += "abc";
  }
  AppendEnd(bytes);
  McapReader reader = FromBytes(bytes);
  EXPECT_EQ(reader.profile(), "");
  McapMessage m;
  for (size_t i = 0; i < expected.size(); ++i) {
    ASSERT_TRUE(reader.Next(m));
    EXPECT_EQ(m.record_offset, offsets[i]);
    EXPECT_EQ(std::string(m.data), expected[i].data);
    EXPECT_EQ(m.log_time_ns, expected[i].log_time_ns);
  }
  EXPECT_FALSE(reader.Next(m));
  EXPECT_TRUE(reader.report().summary_present);
  EXPECT_FALSE(reader.report().truncated);
  EXPECT_EQ(reader.report().chunks, 0u);
  EXPECT_EQ(reader.channels().at(5).metadata.at("offered_qos_profiles"), "- history: 3");
}

TEST(McapReader, ReadsLz4ChunksAndAFileWithoutSummaryIsTruncated) {
  std::string records;
  AppendDeclarations(records, 1, "/imu");
  std::vector<Msg> expected;
  for (uint32_t i = 0; i < 20; ++i) {
    expected.push_back(Sample(1, i));
    AppendMessage(records, expected.back());
  }
  std::string bytes = Start();
  const uint64_t chunk_at = bytes.size();
  AppendChunk(bytes, records, "lz4", Lz4Frame(records));
  McapReader reader = FromBytes(bytes);
  McapMessage m;
  ASSERT_TRUE(reader.Next(m));
  EXPECT_EQ(m.record_offset, chunk_at);
  std::vector<Msg> got{Msg{m.channel_id, m.sequence, m.log_time_ns, m.publish_time_ns, std::string(m.data)}};
  for (Msg& rest : ReadAll(reader)) got.push_back(rest);
  EXPECT_EQ(got, expected);
  EXPECT_EQ(reader.report().chunks, 1u);
  EXPECT_TRUE(reader.report().truncated);
  EXPECT_FALSE(reader.report().summary_present);
  EXPECT_NE(reader.report().truncation.find("no Data End record: the recorder did not close the file"),
            std::string::npos)
      << reader.report().truncation;
}

TEST(McapReader, Lz4ChunkOfAnotherSizeThanStatedIsAnError) {
  std::string records;
  AppendDeclarations(records, 1, "/imu");
  AppendMessage(records, Sample(1, 0));
  for (const uint64_t stated : {records.size() - 1, records.size() + 1}) {
    std::string bytes = Start();
    const uint64_t at = bytes.size();
    AppendChunk(bytes, records, "lz4", Lz4Frame(records), std::nullopt, stated);
    const std::string error = ErrorOf<McapError>([&] {
      McapReader reader = FromBytes(bytes, "lz4.mcap");
      ReadAll(reader);
    });
    EXPECT_NE(error.find("'lz4.mcap' at byte " + std::to_string(at)), std::string::npos) << error;
    EXPECT_NE(error.find("LZ4"), std::string::npos) << error;
  }
}

TEST(McapReader, ChunkWithBadCrcIsSkippedAndCountedLaterChunksAreRead) {
  std::string first, bad, last;
  AppendDeclarations(first, 1, "/imu");
  AppendMessage(first, Sample(1, 0));
  mcap::AppendChannelRecord(bad, 2, 1, "/only_in_bad_chunk", "cdr", {});
  AppendMessage(bad, Sample(1, 1));
  AppendMessage(bad, Sample(2, 2));
  AppendMessage(last, Sample(1, 3));
  AppendMessage(last, Sample(2, 4));  // its channel was declared in the skipped chunk only
  std::string bytes = Start();
  AppendChunk(bytes, first, "", first);
  AppendChunk(bytes, bad, "", bad, mcap::ComputeCrc32(bad) ^ 1u);
  AppendChunk(bytes, last, "lz4", Lz4Frame(last));
  AppendEnd(bytes);
  McapReader reader = FromBytes(bytes);
  EXPECT_EQ(ReadAll(reader), (std::vector<Msg>{Sample(1, 0), Sample(1, 3)}));
  const McapReadReport& report = reader.report();
  EXPECT_EQ(report.chunks, 3u);
  EXPECT_EQ(report.chunks_bad_crc, 1u);
  EXPECT_EQ(report.messages_in_bad_chunks, 3u);  // two in the bad chunk, one on its channel after it
  EXPECT_EQ(report.messages, 2u);
  EXPECT_TRUE(report.summary_present);
}

TEST(McapReader, ChunkCrcZeroIsNotChecked) {
  std::string records;
  AppendDeclarations(records, 1, "/imu");
  AppendMessage(records, Sample(1, 0));
  std::string bytes = Start();
  AppendChunk(bytes, records, "", records, 0u);
  AppendEnd(bytes);
  McapReader reader = FromBytes(bytes);
  EXPECT_EQ(ReadAll(reader).size(), 1u);
  EXPECT_EQ(reader.report().chunks_bad_crc, 0u);
}

TEST(McapReader, UnknownCompressionNamesItAndTheOffset) {
  std::string records;
  AppendDeclarations(records, 1, "/imu");
  AppendMessage(records, Sample(1, 0));
  std::string bytes = Start();
  AppendChunk(bytes, records, "", records);
  const uint64_t at = bytes.size();
  AppendChunk(bytes, records, "brotli", records);
  AppendEnd(bytes);
  McapReader reader = FromBytes(bytes, "odd.mcap");
  McapMessage m;
  ASSERT_TRUE(reader.Next(m));  // the first chunk is read
  const std::string error = ErrorOf<McapError>([&] { reader.Next(m); });
  EXPECT_NE(error.find("'odd.mcap' at byte " + std::to_string(at)), std::string::npos) << error;
  EXPECT_NE(error.find("unknown chunk compression 'brotli'"), std::string::npos) << error;
}

TEST(McapReader, BrokenRecordsAreErrorsNamingTheFileAndOffset) {
  const std::string start = Start();
  struct Case {
    const char* name;
    std::string tail;
    std::string expected;
  };
  std::vector<Case> cases;
  {  // a topic whose String length runs past the Channel record
    std::string tail;
    const size_t at = mcap::BeginRecord(tail, mcap::Op::kChannel);
    mcap::PutU16(tail, 1);
    mcap::PutU16(tail, 0);
    mcap::PutU32(tail, 1000);
    tail += "/imu";
    mcap::EndRecord(tail, at);
    cases.push_back({"lying string", tail, "Channel record: topic states 1000 bytes"});
  }
  {
    std::string tail;
    AppendMessage(tail, Sample(7, 0));
    cases.push_back({"undeclared channel", tail, "a message on channel 7, which no Channel record declared"});
  }
  {
    std::string tail;
    mcap::AppendChannelRecord(tail, 1, 9, "/imu", "cdr", {});
    cases.push_back({"undeclared schema", tail, "names schema 9, which no Schema record declared"});
  }
  {  // stated far beyond kMaxChunkBytes: refused before any allocation
    std::string records;
    AppendMessage(records, Sample(1, 0));
    std::string tail;
    AppendChunk(tail, records, "zstd", records, std::nullopt, uint64_t{1} << 60);
    cases.push_back({"huge chunk", tail, "uncompressed bytes, more than the"});
  }
  {  // 1 GiB from a few bytes: more than zstd can expand to
    std::string tail;
    AppendChunk(tail, "x", "zstd", "0123456789", std::nullopt, McapReader::kMaxChunkBytes);
    cases.push_back({"zstd ratio", tail, "uncompressed bytes, more than its 10 bytes of zstd can hold"});
  }
  {  // not a zstd frame
    std::string records;
    AppendMessage(records, Sample(1, 0));
    std::string tail;
    AppendChunk(tail, records, "zstd", records);
    cases.push_back({"bad zstd", tail, "zstd frame"});
  }
  {  // a record inside a chunk that states more bytes than the chunk holds
    std::string records;
    mcap::PutU8(records, 0x05);
    mcap::PutU64(records, 500);
    records += "short";
    std::string tail;
    AppendChunk(tail, records, "", records);
    cases.push_back({"lying record in chunk", tail, "Message record at uncompressed byte 0 of the Chunk states 500"});
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::string bytes = start + c.tail;
    AppendEnd(bytes);
    const std::string error = ErrorOf<McapError>([&] {
      McapReader reader = FromBytes(bytes, "broken.mcap");
      ReadAll(reader);
    });
    EXPECT_NE(error.find("'broken.mcap' at byte " + std::to_string(start.size())), std::string::npos) << error;
    EXPECT_NE(error.find(c.expected), std::string::npos) << error;
  }
}

TEST(McapReader, NotAnMcapFileIsAnErrorAndAnEmptyOneIsCut) {
  const test_support::ScopedTempDir dir("bag_magic");
  std::ofstream(dir / "x.mcap") << "PK\x03\x04 this is a zip file, not MCAP at all";
  const std::string error = ErrorOf<McapError>([&] { McapReader reader(dir / "x.mcap"); });
  EXPECT_NE(error.find((dir / "x.mcap").string()), std::string::npos) << error;
  EXPECT_NE(error.find("bad magic"), std::string::npos) << error;
  EXPECT_NE(ErrorOf<McapError>([&] { McapReader reader(dir / "missing.mcap"); }).find("cannot open"),
            std::string::npos);
  // A record other than Header first.
  std::string no_header(mcap::kMagic);
  AppendEnd(no_header);
  EXPECT_NE(ErrorOf<McapError>([&] { FromBytes(no_header); }).find("not a Header"), std::string::npos);
  // A recorder killed before its first write.
  McapReader empty = FromBytes("");
  McapMessage m;
  EXPECT_FALSE(empty.Next(m));
  EXPECT_TRUE(empty.report().truncated);
  EXPECT_NE(empty.report().truncation.find("inside the leading magic"), std::string::npos);
}

TEST(McapReader, MessageDataStaysValidUntilTheNextCall) {
  std::string bytes = Start();
  AppendDeclarations(bytes, 1, "/imu");
  AppendMessage(bytes, Msg{1, 0, 1, 1, std::string(100, 'a')});
  AppendMessage(bytes, Msg{1, 1, 2, 2, std::string(3000, 'b')});  // a larger record: the buffer grows
  AppendEnd(bytes);
  McapReader reader = FromBytes(bytes);
  McapMessage m;
  ASSERT_TRUE(reader.Next(m));
  EXPECT_EQ(m.data, std::string(100, 'a'));
  ASSERT_TRUE(reader.Next(m));
  EXPECT_EQ(m.data, std::string(3000, 'b'));
  EXPECT_EQ(m.index, 1u);
}

}  // namespace
}  // namespace locaid::bag
