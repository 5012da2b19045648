// ROS 2 bags the way a user makes them: `locaid-replay --drive D --out-bag F`
// over a drive rendered by locaid-synth, and `locaid subscribe ID --format
// ros2-mcap --out F` against the real locaid-server on 127.0.0.1; each file
// read and checked by js/read_ros2_bag.mjs (the field's own libraries).
// Skips when node is missing (fails when CI is set: needs_tool.hpp).
#include "ros2_bag_reader.hpp"

#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;
namespace ft = locaid::foxglove::testing;
namespace st = locaid::server::testing;
using nlohmann::json;

const std::string kBin = LOCAID_BIN_DIR;

// read_ros2_bag.mjs's summary of `file`; its checks passed.
json ReadBag(const fs::path& file) {
  const ft::NodeRun run = locaid::output::testing::ReadRos2Bag(file);
  EXPECT_EQ(run.exit_code, 0) << run.text;
  return run.exit_code == 0 ? run.out : json::object();
}

uint64_t Count(const json& read, const std::string& topic) {
  return read.value("topics", json::object()).value(topic, json::object()).value("count", uint64_t{0});
}

using Ros2BagEndToEnd = locaid::output::testing::Ros2BagReaderTest;

TEST_F(Ros2BagEndToEnd, ReplayOutBagOfASyntheticDrive) {
  constexpr uint64_t kFrames = 80;
  std::string error;
  const fs::path drive = st::RenderSynthDrive(dir_ / "d", static_cast<int>(kFrames), 5, 320, 96, &error);
  ASSERT_FALSE(drive.empty()) << error;
  const fs::path file = dir_ / "replay.mcap";
  const st::CliResult r = st::RunShell(kBin + "/locaid-replay --drive " + st::ShellQuote(drive.string()) +
                                       " --scenario open-sky --out-bag " + st::ShellQuote(file.string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find(std::to_string(kFrames) + " poses -> " + file.string()), std::string::npos) << r.err;
  const json read = ReadBag(file);
  EXPECT_EQ(Count(read, "/locaid/odometry"), kFrames);
  EXPECT_EQ(Count(read, "/tf"), kFrames);
  EXPECT_EQ(Count(read, "/locaid/status"), kFrames);
  EXPECT_EQ(Count(read, "/tf_static"), 1u);
  // A fused fix once the filter is initialised (it needs some driving first);
  // 10 Hz GPS in open sky.
  EXPECT_GE(Count(read, "/locaid/fix"), kFrames / 2);
  EXPECT_LT(Count(read, "/locaid/fix"), kFrames);
  EXPECT_GE(Count(read, "/locaid/gps"), kFrames - 10);
}

TEST_F(Ros2BagEndToEnd, SubscribeFormatRos2McapFromARealServer) {
  st::ServerProcess server(dir_ / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  const auto stub = st::MakeStub(server.port());
  const std::string id = ft::StartSynthetic(stub.get(), 7, 60, 0);
  const uint64_t poses = ft::WaitFinished(stub.get(), id, 120);
  ASSERT_GT(poses, 0u);
  const fs::path file = dir_ / "live.mcap";
  const st::CliResult r =
      st::RunCli(server.port(), {"subscribe", id, "--from-start", "--format", "ros2-mcap", "--out", file.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json read = ReadBag(file);
  EXPECT_EQ(Count(read, "/locaid/odometry"), poses);
  EXPECT_EQ(Count(read, "/tf"), poses);
  EXPECT_EQ(Count(read, "/tf_static"), 1u);
  EXPECT_GE(Count(read, "/locaid/gps"), 1u);
  EXPECT_EQ(read["topics"]["/locaid/odometry"]["first"]["header"]["frame_id"], "map");
}

// Checked before any call: no server needed.
TEST(Ros2BagCli, MissingOutIsAUsageError) {
  const st::CliResult r = st::RunCli(1, {"subscribe", "s000000000000", "--format", "ros2-mcap"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--out is required for --format ros2-mcap"), std::string::npos) << r.err;
}

}  // namespace
