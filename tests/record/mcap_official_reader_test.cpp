// McapWriter's files read by Foxglove's TypeScript reader (@mcap/core, pinned
// in js/package-lock.json, installed by js/setup.sh as a CTest fixture):
// js/read_mcap.mjs prints what McapIndexedReader and McapStreamReader found.
// Skips when node is not installed (fails when CI is set: needs_tool.hpp).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "mcap_test_reader.hpp"
#include "needs_tool.hpp"
#include "record/mcap_writer.hpp"
#include "sample_recording.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using locaid::record::McapOptions;
using locaid::record::McapWriter;
using nlohmann::json;
namespace rt = locaid::record::testing;

namespace {

const fs::path kJsDir = LOCAID_MCAP_JS_DIR;

struct NodeRun {
  int exit_code = -1;
  std::string out;
};

// Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "'" + s + "'".
std::string Quoted(const fs::path& path) {
  std::string out = "'";
  out += path.string();
  out += '\'';
  return out;
}

// Runs read_mcap.mjs; its stderr goes to the test log.
NodeRun ReadWithNode(const std::string& args) {
  const std::string command = "node " + Quoted(kJsDir / "read_mcap.mjs") + " " + args;
  NodeRun run;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  char buffer[4096];
  for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) run.out.append(buffer, n);
  const int status = ::pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

class McapOfficialReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    LOCAID_NEEDS_TOOL(locaid::test_support::HaveCommand("node"),
                      "node is not installed; the official MCAP reader (@mcap/core) needs it");
    ASSERT_TRUE(fs::exists(kJsDir / "node_modules/@mcap/core"))
        << "run tests/record/js/setup.sh " << kJsDir << " (the McapJsReaderSetup CTest fixture does)";
  }

  // Both readers read the whole file and agree (read_mcap.mjs checks that).
  json ReadFully(const fs::path& path) {
    const NodeRun run = ReadWithNode(Quoted(path));
    EXPECT_EQ(run.exit_code, 0) << run.out;
    return run.exit_code == 0 ? json::parse(run.out) : json::object();
  }

  const locaid::test_support::ScopedTempDir dir_{"mcap_js"};
};

void ExpectMatchesSample(const json& read, const rt::SampleRecording& sample) {
  ASSERT_TRUE(read.contains("topics")) << read.dump(2);
  EXPECT_EQ(read["message_count"].get<uint64_t>(), sample.message_count);
  EXPECT_EQ(read["topics"].size(), sample.messages_per_topic.size());
  for (const auto& [topic, count] : sample.messages_per_topic) {
    ASSERT_TRUE(read["topics"].contains(topic)) << topic;
    EXPECT_EQ(read["topics"][topic]["count"].get<uint64_t>(), count) << topic;
    EXPECT_TRUE(read["topics"][topic]["sequences_in_order"].get<bool>()) << topic;
  }
  EXPECT_EQ(read["start_time"].get<std::string>(), std::to_string(sample.start_time_ns));
  EXPECT_EQ(read["end_time"].get<std::string>(), std::to_string(sample.end_time_ns));
  EXPECT_EQ(read["schemas"], json({"foxglove.PoseInFrame", "locaid.VoStatus"}));
}

TEST_F(McapOfficialReaderTest, ReadsZstdAndUncompressedChunkedFiles) {
  for (const bool zstd : {true, false}) {
    SCOPED_TRACE(zstd ? "zstd" : "uncompressed");
    const fs::path path = dir_ / (zstd ? "zstd.mcap" : "plain.mcap");
    const rt::SampleRecording sample =
        rt::WriteSampleRecording(path, McapOptions{.chunk_size_bytes = 8192, .zstd = zstd}, 20, 20000);
    const json read = ReadFully(path);
    ASSERT_FALSE(read.empty());
    ExpectMatchesSample(read["indexed"], sample);
    ExpectMatchesSample(read["stream"], sample);
    const json& stats = read["indexed"]["statistics"];
    EXPECT_EQ(stats["message_count"].get<std::string>(), std::to_string(sample.message_count));
    EXPECT_EQ(stats["channel_count"].get<int>(), rt::kSampleChannels);
    EXPECT_EQ(stats["schema_count"].get<int>(), rt::kSampleSchemas);
    const int chunks = read["indexed"]["chunk_count"].get<int>();
    EXPECT_GT(chunks, 10);
    EXPECT_EQ(stats["chunk_count"].get<int>(), chunks);
    EXPECT_EQ(read["stream"]["chunk_count"].get<int>(), chunks);
    EXPECT_EQ(read["indexed"]["summary_offset_opcodes"], json({0x03, 0x04, 0x08, 0x0B}));
    std::cout << "[   info   ] " << path.filename().string() << ": " << fs::file_size(path) << " bytes, " << chunks
              << " chunks, " << sample.message_count << " messages read by @mcap/core\n";
  }
}

TEST_F(McapOfficialReaderTest, ReadsAnEmptyRecording) {
  const fs::path path = dir_ / "empty.mcap";
  McapWriter(path).Close();
  const json read = ReadFully(path);
  ASSERT_FALSE(read.empty());
  EXPECT_EQ(read["indexed"]["message_count"].get<int>(), 0);
  EXPECT_EQ(read["indexed"]["chunk_count"].get<int>(), 0);
  EXPECT_EQ(read["stream"]["message_count"].get<int>(), 0);
}

// A recorder killed with SIGKILL while writing: the file has no summary or
// footer, and the stream reader must still read every complete chunk.
TEST_F(McapOfficialReaderTest, StreamReaderReadsWhatAKilledWriterLeft) {
  const fs::path path = dir_ / "killed.mcap";
  constexpr uint64_t kKillAfterBytes = 96 * 1024;  // several 8 KiB chunks
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The child records until it is killed, at most 20 s, never returning into gtest.
    try {
      McapWriter writer(path, McapOptions{.chunk_size_bytes = 8192, .zstd = true});
      const uint16_t pose =
          writer.AddChannel(writer.AddSchema("foxglove.PoseInFrame", "jsonschema", "{}"), "/locaid/pose", "json");
      const uint16_t gps = writer.AddChannel(0, "/locaid/gps", "json");
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      for (uint32_t i = 0; std::chrono::steady_clock::now() < deadline; ++i) {
        const uint64_t t_ns = rt::kSampleStartNs + i * 10'000'000ull;
        writer.Write(pose, t_ns, t_ns, rt::SamplePayload("/locaid/pose", i), i);
        if (i % 10 == 0) writer.Write(gps, t_ns, t_ns, rt::SamplePayload("/locaid/gps", i), i / 10);
        std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }

  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  std::error_code ec;
  while (std::chrono::steady_clock::now() < give_up &&
         (!fs::exists(path, ec) || fs::file_size(path, ec) < kKillAfterBytes)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the writer ended before it was killed";

  // What a complete-chunk reader must find, by the test's own reader.
  const rt::StreamScan expected = rt::ScanStream(rt::ReadFileBytes(path));
  ASSERT_TRUE(expected.truncated);
  ASSERT_GE(expected.chunk_count, 3u);

  const NodeRun run = ReadWithNode("--stream " + Quoted(path));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const json read = json::parse(run.out);
  EXPECT_TRUE(read["truncated"].get<bool>());
  const json& stream = read["stream"];
  EXPECT_FALSE(stream["data_end_seen"].get<bool>());
  EXPECT_EQ(stream["chunk_count"].get<uint64_t>(), expected.chunk_count);
  EXPECT_EQ(stream["message_count"].get<uint64_t>(), expected.messages.size());
  for (const auto& [topic, counts] : stream["topics"].items()) {
    EXPECT_TRUE(counts["sequences_in_order"].get<bool>()) << topic << ": a message of a complete chunk is missing";
  }
  std::cout << "[   info   ] killed writer left " << fs::file_size(path) << " bytes: " << expected.chunk_count
            << " complete chunks, " << expected.messages.size() << " messages\n";

  // The indexed reader, which needs the footer, rejects the same file.
  EXPECT_NE(ReadWithNode(Quoted(path) + " 2>/dev/null").exit_code, 0);
}

// A kill in the middle of a chunk's write(2) leaves part of that chunk; a cut
// anywhere must leave every chunk before it readable.
TEST_F(McapOfficialReaderTest, StreamReaderReadsEveryChunkBeforeACut) {
  const fs::path whole = dir_ / "whole.mcap";
  rt::WriteSampleRecording(whole, McapOptions{.chunk_size_bytes = 8192, .zstd = true}, 20);
  const std::string bytes = rt::ReadFileBytes(whole);
  const uint64_t all_chunks = rt::ScanStream(bytes).chunk_count;
  bool cut_inside_a_chunk = false;
  for (const double fraction : {0.1, 0.37, 0.5, 0.81, 0.999}) {
    const size_t cut_at = static_cast<size_t>(fraction * static_cast<double>(bytes.size()));
    SCOPED_TRACE("cut at byte " + std::to_string(cut_at) + " of " + std::to_string(bytes.size()));
    const fs::path cut = dir_ / "cut.mcap";
    std::ofstream(cut, std::ios::binary | std::ios::trunc) << bytes.substr(0, cut_at);
    const rt::StreamScan expected = rt::ScanStream(bytes.substr(0, cut_at));
    ASSERT_TRUE(expected.truncated);
    cut_inside_a_chunk |= expected.chunk_count < all_chunks;

    const NodeRun run = ReadWithNode("--stream " + Quoted(cut));
    ASSERT_EQ(run.exit_code, 0) << run.out;
    const json read = json::parse(run.out);
    EXPECT_TRUE(read["truncated"].get<bool>());
    EXPECT_EQ(read["stream"]["chunk_count"].get<uint64_t>(), expected.chunk_count);
    EXPECT_EQ(read["stream"]["message_count"].get<uint64_t>(), expected.messages.size());
  }
  EXPECT_TRUE(cut_inside_a_chunk);
}

}  // namespace
