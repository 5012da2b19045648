// `locaid subscribe ID --format mcap`: the Foxglove channels in an MCAP file,
// read by Foxglove's own reader (@mcap/core via tests/record/js/read_mcap.mjs).
// Skips when node is missing (fails when CI is set: needs_tool.hpp).
#include "bridge_support.hpp"

#include <gtest/gtest.h>

namespace {

namespace ft = locaid::foxglove::testing;
namespace st = locaid::server::testing;
using nlohmann::json;

const std::filesystem::path kMcapJsDir = LOCAID_MCAP_JS_DIR;

const json kSchemas = {"foxglove.FrameTransforms", "foxglove.LocationFix", "foxglove.PoseInFrame",
                       "foxglove.PosesInFrame",    "locaid.Status",        "locaid.v1.PoseUpdate"};

// Every message of every topic decoded by the schema stored in the file
// (protobuf from its FileDescriptorSet, JSON).
void ExpectEveryMessageDecoded(const json& read) {
  EXPECT_EQ(read.value("decode_errors", json::array()), json::array());
  const json topics = read.value("topics", json::object());
  ASSERT_FALSE(topics.empty());
  for (const auto& [topic, t] : topics.items()) {
    EXPECT_EQ(t.value("decoded", -1), t.value("count", -2)) << topic;
  }
}

class McapSubscribeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    LOCAID_NEEDS_TOOL(ft::HaveNode(), "node is not installed; the official MCAP reader (@mcap/core) needs it");
    ASSERT_TRUE(std::filesystem::exists(kMcapJsDir / "node_modules/@mcap/core"))
        << "run tests/record/js/setup.sh " << kMcapJsDir << " (the McapJsReaderSetup CTest fixture does)";
    server_ = std::make_unique<st::ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = st::MakeStub(server_->port());
  }
  // Both of @mcap/core's readers read the whole file and agree.
  json ReadFully(const std::filesystem::path& file) {
    const ft::NodeRun run = ft::RunNode(kMcapJsDir / "read_mcap.mjs", {file.string()});
    EXPECT_EQ(run.exit_code, 0) << run.text;
    return run.out.is_discarded() ? json::object() : run.out["indexed"];
  }

  // `locaid subscribe ID --format mcap --out FILE` running live while a
  // real-time session plays, once the session has published `poses` poses
  // to it; returns the session's stats at that moment.
  locaid::v1::SessionStats RecordLive(const std::string& id, const std::filesystem::path& file, uint64_t poses,
                                      std::unique_ptr<st::ChildProcess>& cli) {
    cli = std::make_unique<st::ChildProcess>(
        st::CliArgv(server_->port(), {"subscribe", id, "--format", "mcap", "--out", file.string()}),
        st::ChildProcess::Options{dir_ / "cli.out", dir_ / "cli.err", 0});
    return st::WaitStats(stub_.get(), id, 60, [poses](const auto& s) {
      return s.poses_published() >= poses && s.subscribers() >= 1;
    });
  }

  const locaid::test_support::ScopedTempDir dir_{"mcap_subscribe"};  // outlives the server
  std::unique_ptr<st::ServerProcess> server_;
  std::unique_ptr<locaid::v1::Localization::Stub> stub_;
};

TEST_F(McapSubscribeTest, RecordsTheBridgeChannelsOfAFinishedSession) {
  const std::string id = ft::StartSynthetic(stub_.get(), 7, 60, 0);
  const uint64_t poses = ft::WaitFinished(stub_.get(), id, 120);
  const auto file = dir_ / "run.mcap";
  const st::CliResult r = st::RunCli(server_->port(), {"subscribe", id, "--from-start", "--format", "mcap", "--out",
                                                       file.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json read = ReadFully(file);
  ASSERT_TRUE(read.contains("topics")) << read.dump(2);
  EXPECT_EQ(read["schemas"], kSchemas);
  for (const char* topic : {"/locaid/pose", "/tf", "/locaid/fix", "/locaid/status", "/locaid/update", "/locaid/path"}) {
    ASSERT_TRUE(read["topics"].contains(topic)) << topic << " in " << read["topics"].dump();
    EXPECT_TRUE(read["topics"][topic]["sequences_in_order"].get<bool>()) << topic;
  }
  EXPECT_EQ(read["topics"]["/locaid/update"]["count"].get<uint64_t>(), poses);
  EXPECT_EQ(read["topics"]["/tf"]["count"].get<uint64_t>(), poses);
  EXPECT_EQ(read["statistics"]["channel_count"], 9);  // every channel is declared, also those without messages
  ExpectEveryMessageDecoded(read);
}

// A recorder killed without warning: the file ends mid-way, yet every chunk
// written before the kill reads, and chunks close each second of log time,
// so at most about a second of poses is lost.
TEST_F(McapSubscribeTest, SigkillLeavesEveryCompleteChunkReadable) {
  const std::string id = ft::StartSynthetic(stub_.get(), 7, 80, 1.0);  // 8 s of real time
  const auto file = dir_ / "killed.mcap";
  std::unique_ptr<st::ChildProcess> cli;
  const auto stats = RecordLive(id, file, 40, cli);
  ASSERT_GE(stats.poses_published(), 40u);
  ASSERT_TRUE(cli->Signal(SIGKILL));
  ASSERT_TRUE(cli->Wait(10));
  const ft::NodeRun run = ft::RunNode(kMcapJsDir / "read_mcap.mjs", {"--stream", file.string()});
  ASSERT_EQ(run.exit_code, 0) << run.text;
  EXPECT_TRUE(run.out["truncated"].get<bool>()) << "no footer: the recorder never closed the file";
  const json& read = run.out["stream"];
  const json updates =
      read.value("topics", json::object()).value("/locaid/update", json{{"count", 0}, {"sequences_in_order", false}});
  // 10 poses a second: all but the open chunk's (<= 1 s, plus the pose in flight).
  EXPECT_GE(updates["count"].get<uint64_t>(), stats.poses_published() - 12) << read.dump(2);
  EXPECT_TRUE(updates["sequences_in_order"].get<bool>());
  ExpectEveryMessageDecoded(read);
}

TEST_F(McapSubscribeTest, SigtermClosesTheFileProperly) {
  const std::string id = ft::StartSynthetic(stub_.get(), 7, 60, 1.0);  // 6 s of real time
  const auto file = dir_ / "live.mcap";
  std::unique_ptr<st::ChildProcess> cli;
  RecordLive(id, file, 10, cli);
  ASSERT_TRUE(cli->Signal(SIGTERM));
  ASSERT_TRUE(cli->Wait(10)) << st::Slurp(dir_ / "cli.err");
  EXPECT_EQ(cli->exit_code(), 0) << st::Slurp(dir_ / "cli.err");
  const json read = ReadFully(file);  // complete: summary and footer were written
  ASSERT_TRUE(read.contains("topics")) << read.dump(2);
  EXPECT_GE(read["topics"]["/locaid/update"]["count"].get<uint64_t>(), 1u);
  EXPECT_EQ(read["schemas"], kSchemas);
}

// Checked before any call: no server (nor node) needed.
TEST(McapSubscribe, MissingOutIsAUsageError) {
  const st::CliResult r = st::RunCli(1, {"subscribe", "s000000000000", "--format", "mcap"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--out is required for --format mcap"), std::string::npos) << r.err;
}

}  // namespace

namespace {

// `locaid-replay --out-mcap`: offline, the same channels; a synthetic drive
// has ground truth, so the truth channels are there too.
TEST(McapReplay, RecordsEveryReplayedPoseWithItsTruthAndFixes) {
  LOCAID_NEEDS_TOOL(ft::HaveNode(), "node is not installed; the official MCAP reader (@mcap/core) needs it");
  const locaid::test_support::ScopedTempDir dir("mcap_replay");
  const std::string bin = LOCAID_BIN_DIR;
  ASSERT_EQ(std::system((bin + "/locaid-synth -q --out " + (dir / "d").string() +
                         " --frames 120 --width 320 --height 96 --seed 5").c_str()), 0);
  std::filesystem::path drive;
  for (const auto& e : std::filesystem::directory_iterator(dir / "d"))
    if (e.is_directory()) drive = e.path();
  const auto file = dir / "replay.mcap";
  ASSERT_EQ(std::system((bin + "/locaid-replay --drive " + drive.string() + " --scenario open-sky --out-mcap " +
                         file.string() + " > /dev/null 2>&1").c_str()), 0);
  const ft::NodeRun run = ft::RunNode(kMcapJsDir / "read_mcap.mjs", {file.string()});
  ASSERT_EQ(run.exit_code, 0) << run.text;
  const json read = run.out["indexed"];
  EXPECT_EQ(read["schemas"], kSchemas);
  for (const char* topic : {"/locaid/pose", "/tf", "/locaid/status", "/locaid/update"})
    EXPECT_EQ(read["topics"][topic]["count"].get<uint64_t>(), 120u) << topic;
  // Truth once the filter has its ENU origin (its first fix); 10 Hz fixes.
  EXPECT_GE(read["topics"]["/locaid/truth"]["count"].get<uint64_t>(), 115u);
  EXPECT_GE(read["topics"]["/locaid/gps"]["count"].get<uint64_t>(), 110u);
  EXPECT_EQ(read["statistics"]["channel_count"], 9);
  ExpectEveryMessageDecoded(read);
}

}  // namespace
