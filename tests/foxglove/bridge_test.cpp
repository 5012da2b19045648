// locaid-foxglove end to end: the real locaid-server on a loopback port, the
// real bridge, and Foxglove's own client (@foxglove/ws-protocol over `ws`,
// js/client.mjs). Also: switching to a newer session, SIGTERM, a server that
// is not there, and flag errors. Skips when node is missing (fails when CI is
// set: needs_tool.hpp).
#include "bridge_support.hpp"

#include <gtest/gtest.h>

namespace {

namespace ft = locaid::foxglove::testing;
namespace st = locaid::server::testing;
using nlohmann::json;

const std::filesystem::path kJsDir = LOCAID_FOXGLOVE_JS_DIR;
constexpr uint32_t kFrames = 60;  // 6 s of a synthetic drive at 10 Hz

class BridgeTest : public ::testing::Test {
 protected:
  // client.mjs in the background, its JSON summary in `dir_`/client.json.
  std::unique_ptr<st::ChildProcess> StartClient(int ws_port, int sessions, uint64_t updates) {
    const std::vector<std::string> argv = {"/usr/bin/env",  "node",
                                           (kJsDir / "client.mjs").string(), "--url",
                                           "ws://127.0.0.1:" + std::to_string(ws_port), "--sessions",
                                           std::to_string(sessions), "--updates",
                                           std::to_string(updates), "--timeout-s",
                                           "120"};
    return std::make_unique<st::ChildProcess>(argv,
                                              st::ChildProcess::Options{dir_ / "client.json", dir_ / "client.err", 0});
  }
  json ClientResult(st::ChildProcess& client) {
    EXPECT_TRUE(client.Wait(150)) << "client.mjs did not end";
    EXPECT_EQ(client.exit_code(), 0) << st::Slurp(dir_ / "client.json") << st::Slurp(dir_ / "client.err");
    return json::parse(st::Slurp(dir_ / "client.json"), nullptr, false);
  }
  static std::vector<std::string> NamedSessions(const json& result) {
    std::vector<std::string> ids;
    for (const auto& id : result["server_infos"]) {
      if (id.is_string()) ids.push_back(id);
    }
    return ids;
  }

  const locaid::test_support::ScopedTempDir dir_{"bridge"};  // outlives the processes of the test
};

// A server, the bridge following its newest session, and Foxglove's client
// subscribed to every channel before any session starts (the WebSocket is
// live only: nothing is replayed to a late subscriber).
class BridgeClientTest : public BridgeTest {
 protected:
  void SetUp() override {
    LOCAID_NEEDS_TOOL(ft::HaveNode(), "node is not installed; the Foxglove client (@foxglove/ws-protocol) needs it");
    ASSERT_TRUE(std::filesystem::exists(kJsDir / "node_modules/@foxglove/ws-protocol"))
        << "run tests/foxglove/js/setup.sh " << kJsDir << " (the FoxgloveJsClientSetup CTest fixture does)";
    server_ = std::make_unique<st::ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = st::MakeStub(server_->port());
    ws_port_ = ft::FreeLoopbackPort();
    bridge_ = std::make_unique<ft::BridgeProcess>(dir_, server_->port(), ws_port_);
    ASSERT_TRUE(bridge_->WaitForLog("listening on", 10)) << bridge_->log();
  }
  // Starts client.mjs and waits until the bridge saw its subscriptions.
  void Subscribe(int sessions, uint64_t updates) {
    client_ = StartClient(ws_port_, sessions, updates);
    ASSERT_TRUE(bridge_->WaitForLog("subscribed to /locaid/update", 30)) << bridge_->log();
  }

  std::unique_ptr<st::ServerProcess> server_;
  std::unique_ptr<locaid::v1::Localization::Stub> stub_;
  int ws_port_ = 0;
  std::unique_ptr<ft::BridgeProcess> bridge_;
  std::unique_ptr<st::ChildProcess> client_;
};

TEST_F(BridgeClientTest, ServesEveryChannelToTheFoxgloveClient) {
  Subscribe(1, kFrames);
  const std::string id = ft::StartSynthetic(stub_.get(), 7, kFrames, 1.0);
  const json result = ClientResult(*client_);
  ASSERT_FALSE(result.is_discarded());

  EXPECT_EQ(result["errors"], json::array());
  EXPECT_EQ(result["subprotocol"], "foxglove.websocket.v1");
  EXPECT_EQ(NamedSessions(result), std::vector<std::string>{id});
  const std::map<std::string, std::string> schemas = {
      {"/locaid/pose", "foxglove.PoseInFrame"},   {"/tf", "foxglove.FrameTransforms"},
      {"/locaid/fix", "foxglove.LocationFix"},    {"/locaid/gps", "foxglove.LocationFix"},
      {"/locaid/truth", "foxglove.PoseInFrame"},  {"/locaid/truth_fix", "foxglove.LocationFix"},
      {"/locaid/path", "foxglove.PosesInFrame"},  {"/locaid/status", "locaid.Status"},
      {"/locaid/update", "locaid.v1.PoseUpdate"}};
  ASSERT_EQ(result["channels"].size(), schemas.size()) << result["channels"].dump(2);
  for (const auto& [topic, schema] : schemas) {
    EXPECT_EQ(result["channels"][topic]["schemaName"], schema) << topic;
  }
  const json& counts = result["counts"];
  for (const char* topic : {"/locaid/pose", "/tf", "/locaid/fix", "/locaid/status", "/locaid/update", "/locaid/path"}) {
    EXPECT_GT(counts.value(topic, 0), 0) << topic << " in " << counts.dump();
  }
  EXPECT_EQ(counts.value("/locaid/update", 0), static_cast<int>(kFrames));  // from_start: every pose, once
  EXPECT_EQ(counts.value("/locaid/pose", 0), static_cast<int>(kFrames));
  EXPECT_EQ(result["update_session_mismatches"], 0);
  EXPECT_EQ(result["last_update"]["session_id"], id);
  EXPECT_EQ(result["first_tf"]["transforms"][1]["child_frame_id"], "cam0");
  EXPECT_GT(result["last_path_poses"].get<int>(), 1);
  // Every foxglove.* message passed ajv against Foxglove's published schemas
  // (a failure is in `errors` above); the GPS and truth channels too, now
  // that the server fills them.
  for (const char* topic : {"/locaid/pose", "/tf", "/locaid/fix", "/locaid/gps", "/locaid/truth", "/locaid/truth_fix",
                            "/locaid/path"}) {
    EXPECT_EQ(result["schema_validated"].value(topic, 0), counts.value(topic, 0)) << topic;
    EXPECT_GT(result["schema_validated"].value(topic, 0), 0) << topic;
  }
  std::cout << "[   info   ] counts " << counts.dump() << "\n";
}

// What the viewer gets is what the gRPC stream of the same session carries:
// the same poses in the same order, the same numbers to the last bit (the
// bridge writes doubles in their shortest round-trip form).
TEST_F(BridgeClientTest, CarriesTheValuesOfTheGrpcStream) {
  Subscribe(1, kFrames);
  const std::string id = ft::StartSynthetic(stub_.get(), 9, kFrames, 1.0);
  const json result = ClientResult(*client_);
  ASSERT_FALSE(result.is_discarded());
  EXPECT_EQ(result["errors"], json::array());
  ft::WaitFinished(stub_.get(), id, 60);
  st::PoseCollector grpc(st::MakeChannel(server_->port()), id, /*from_start=*/true);
  ASSERT_TRUE(grpc.WaitDone(60));
  const std::vector<locaid::v1::PoseUpdate> poses = grpc.poses();
  ASSERT_EQ(poses.size(), kFrames);
  const json& v = result["values"];
  ASSERT_EQ(v["update"].size(), poses.size());
  ASSERT_EQ(v["pose"].size(), poses.size());
  ASSERT_EQ(v["status"].size(), poses.size());
  size_t fixes = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const locaid::v1::PoseUpdate& p = poses[i];
    const std::string t = std::to_string(p.t_ns());
    const json& update = v["update"][i];
    EXPECT_EQ(update["sequence"], std::to_string(p.sequence()));
    EXPECT_EQ(update["t_ns"], t);
    EXPECT_EQ(update["mode"], static_cast<int>(p.mode()));
    const json& pose = v["pose"][i];
    EXPECT_EQ(pose["t_ns"], t);
    for (const json* xyz : {&update, &pose}) {
      EXPECT_EQ((*xyz)["x"].get<double>(), p.position_enu_m().x()) << "pose " << i;
      EXPECT_EQ((*xyz)["y"].get<double>(), p.position_enu_m().y()) << "pose " << i;
      EXPECT_EQ((*xyz)["z"].get<double>(), p.position_enu_m().z()) << "pose " << i;
    }
    const json& status = v["status"][i];
    EXPECT_EQ(status["t_ns"], t);
    EXPECT_EQ(status["sequence"], p.sequence());
    EXPECT_EQ(status["mode"], locaid::v1::Mode_Name(p.mode()).substr(5));  // without MODE_
    EXPECT_EQ(status["gps_used"], p.gps_used());
    if (p.mode() == locaid::v1::MODE_LOST) continue;  // no fused fix without a position
    ASSERT_LT(fixes, v["fix"].size());
    const json& fix = v["fix"][fixes++];
    EXPECT_EQ(fix["t_ns"], t);
    EXPECT_EQ(fix["latitude"].get<double>(), p.latitude_deg()) << "pose " << i;
    EXPECT_EQ(fix["longitude"].get<double>(), p.longitude_deg()) << "pose " << i;
    EXPECT_EQ(fix["altitude"].get<double>(), p.altitude_m()) << "pose " << i;
  }
  EXPECT_EQ(fixes, v["fix"].size());
  EXPECT_GT(fixes, 0u);
}

TEST_F(BridgeClientTest, SwitchesToANewerSessionWithANewServerInfo) {
  Subscribe(2, 5);
  const std::string first = ft::StartSynthetic(stub_.get(), 7, kFrames, 1.0);
  ASSERT_TRUE(bridge_->WaitForLog("following session " + first, 30)) << bridge_->log();
  st::WaitStats(stub_.get(), first, 60, [](const auto& s) { return s.poses_published() >= 10; });
  const std::string second = ft::StartSynthetic(stub_.get(), 8, kFrames, 1.0);
  const json result = ClientResult(*client_);
  ASSERT_FALSE(result.is_discarded());

  EXPECT_EQ(NamedSessions(result), (std::vector<std::string>{first, second}));
  EXPECT_GT(result["counts_by_session"][first].value("/locaid/update", 0), 0);
  EXPECT_GE(result["counts_by_session"][second].value("/locaid/update", 0), 5);
  EXPECT_EQ(result["update_session_mismatches"], 0);  // the new serverInfo comes before the new session's data
  EXPECT_EQ(result["last_update"]["session_id"], second);
  EXPECT_NE(bridge_->log().find("a newer session started; switching"), std::string::npos) << bridge_->log();
}

// 20 Foxglove clients on one bridge, one of which stops reading: the other
// 19 get every update of the session, the bridge's own gRPC stream never
// falls behind (the server drops nothing for it), and the stalled client,
// reading again, has lost old messages (told once) and catches up with the
// newest update. A small queue and kernel send buffer (--queue,
// --send-buffer) make the loss happen within a short session.
TEST_F(BridgeTest, TwentyClientsOneStalledTheOthersGetEverything) {
  LOCAID_NEEDS_TOOL(ft::HaveNode(), "node is not installed; the Foxglove client (@foxglove/ws-protocol) needs it");
  constexpr int kClients = 20;
  constexpr uint32_t kCrowdFrames = 100;
  st::ServerProcess server(dir_ / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = st::MakeStub(server.port());
  const int ws_port = ft::FreeLoopbackPort();
  ft::BridgeProcess bridge(dir_, server.port(), ws_port, {"--queue", "20", "--send-buffer", "16384"});
  ASSERT_TRUE(bridge.WaitForLog("listening on", 10)) << bridge.log();
  st::ChildProcess crowd({"/usr/bin/env", "node", (kJsDir / "crowd.mjs").string(), "--url",
                          "ws://127.0.0.1:" + std::to_string(ws_port), "--clients", std::to_string(kClients),
                          "--updates", std::to_string(kCrowdFrames), "--timeout-s", "120"},
                         st::ChildProcess::Options{dir_ / "crowd.json", dir_ / "crowd.err", 0});
  ASSERT_TRUE(bridge.WaitForLogCount("subscribed to /locaid/update", kClients, 30)) << bridge.log();
  const std::string id = ft::StartSynthetic(stub.get(), 7, kCrowdFrames, 1.0);
  ASSERT_TRUE(crowd.Wait(150)) << "crowd.mjs did not end";
  EXPECT_EQ(crowd.exit_code(), 0) << st::Slurp(dir_ / "crowd.json") << st::Slurp(dir_ / "crowd.err");
  const json result = json::parse(st::Slurp(dir_ / "crowd.json"), nullptr, false);
  ASSERT_FALSE(result.is_discarded()) << st::Slurp(dir_ / "crowd.err");

  ASSERT_EQ(result["readers"].size(), static_cast<size_t>(kClients - 1));
  for (const auto& reader : result["readers"]) {
    EXPECT_EQ(reader["updates"], kCrowdFrames) << reader.dump();
    EXPECT_EQ(reader["errors"], json::array()) << reader.dump();
  }
  const json& stalled = result["stalled"];
  EXPECT_TRUE(stalled["caught_up"].get<bool>()) << stalled.dump();
  EXPECT_EQ(stalled["last_sequence"], result["newest_sequence"]);
  // What the stalled client missed was dropped from its queue, and it was told once.
  EXPECT_LT(stalled["updates"].get<uint32_t>(), kCrowdFrames) << stalled.dump();
  EXPECT_EQ(stalled["statuses"], json::array({"Send buffer limit reached"})) << stalled.dump();
  std::cout << "[   info   ] stalled client: " << stalled["updates"] << " of " << kCrowdFrames << " updates, statuses "
            << stalled["statuses"].dump() << "\n";
  EXPECT_EQ(ft::WaitFinished(stub.get(), id, 60), kCrowdFrames);
  EXPECT_EQ(st::GetStats(stub.get(), id).dropped_total(), 0u) << "the server dropped poses for the bridge";
}

// How soon the bridge exits is a benchmark figure; the wait is a hang guard.
TEST_F(BridgeTest, SigtermWhileStreamingExitsZero) {
  st::ServerProcess server(dir_ / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  ft::BridgeProcess bridge(dir_, server.port(), ft::FreeLoopbackPort());
  auto stub = st::MakeStub(server.port());
  const std::string id = ft::StartSynthetic(stub.get(), 7, kFrames, 1.0);
  ASSERT_TRUE(bridge.WaitForLog("following session " + id, 30)) << bridge.log();
  ASSERT_TRUE(bridge.process().Signal(SIGTERM));
  ASSERT_TRUE(bridge.process().Wait(60)) << "still running 60 s after SIGTERM\n" << bridge.log();
  EXPECT_EQ(bridge.process().exit_code(), 0) << bridge.log();
  EXPECT_NE(bridge.log().find("stopping on SIGTERM"), std::string::npos) << bridge.log();
}

TEST_F(BridgeTest, WithoutAServerRetriesWithBackoffAndStopsOnSigint) {
  const int nobody = ft::FreeLoopbackPort();  // nothing listens there
  ft::BridgeProcess bridge(dir_, nobody, ft::FreeLoopbackPort());
  ASSERT_TRUE(bridge.WaitForLog("retrying in 1 s", 20)) << bridge.log();
  const std::string log = bridge.log();
  EXPECT_NE(log.find("ListSessions failed: UNAVAILABLE"), std::string::npos) << log;
  EXPECT_NE(log.find("retrying in 0.5 s"), std::string::npos) << log;
  ASSERT_TRUE(bridge.process().Signal(SIGINT));
  ASSERT_TRUE(bridge.process().Wait(60)) << bridge.log();
  EXPECT_EQ(bridge.process().exit_code(), 0) << bridge.log();
}

TEST_F(BridgeTest, ReconnectsWhenTheServerComesBack) {
  const int grpc_port = ft::FreeLoopbackPort();
  ft::BridgeProcess bridge(dir_, grpc_port, ft::FreeLoopbackPort());
  ASSERT_TRUE(bridge.WaitForLog("ListSessions failed", 20)) << bridge.log();
  // The server the bridge was told about starts late, on that port.
  st::ServerProcess server(dir_ / "server", {}, grpc_port);
  ASSERT_EQ(server.port(), grpc_port) << server.log();
  auto stub = st::MakeStub(grpc_port);
  // The bridge may be in its longest wait (5 s) when the server comes up: the
  // session must still be live when it asks again (kFrames, 6 s, was not
  // always, on a loaded machine), so 30 s of drive.
  constexpr uint32_t kOutlivesTheBackoff = 300;
  const std::string id = ft::StartSynthetic(stub.get(), 7, kOutlivesTheBackoff, 1.0);
  EXPECT_TRUE(bridge.WaitForLog("following session " + id, 30)) << bridge.log();
}

// The server goes away mid-session and a new one comes up on the same port:
// a Foxglove client connected to the bridge the whole time gets a new
// serverInfo and the new server's session, without reconnecting itself.
TEST_F(BridgeTest, AFoxgloveClientStaysConnectedAcrossAServerRestart) {
  LOCAID_NEEDS_TOOL(ft::HaveNode(), "node is not installed; the Foxglove client (@foxglove/ws-protocol) needs it");
  const int grpc_port = ft::FreeLoopbackPort();
  auto server = std::make_unique<st::ServerProcess>(dir_ / "server1", std::vector<std::string>{}, grpc_port);
  ASSERT_EQ(server->port(), grpc_port) << server->log();
  const int ws_port = ft::FreeLoopbackPort();
  ft::BridgeProcess bridge(dir_, grpc_port, ws_port);
  ASSERT_TRUE(bridge.WaitForLog("listening on", 10)) << bridge.log();
  auto client = StartClient(ws_port, 2, 5);
  ASSERT_TRUE(bridge.WaitForLog("subscribed to /locaid/update", 30)) << bridge.log();

  auto stub = st::MakeStub(grpc_port);
  const std::string first = ft::StartSynthetic(stub.get(), 7, kFrames, 1.0);
  st::WaitStats(stub.get(), first, 60, [](const auto& s) { return s.poses_published() >= 10; });
  ASSERT_TRUE(server->process().Signal(SIGTERM));
  ASSERT_TRUE(server->process().Wait(20)) << server->log();
  server = std::make_unique<st::ServerProcess>(dir_ / "server2", std::vector<std::string>{}, grpc_port);
  ASSERT_EQ(server->port(), grpc_port) << server->log();
  stub = st::MakeStub(grpc_port);
  const std::string second = ft::StartSynthetic(stub.get(), 8, kFrames, 1.0);

  const json result = ClientResult(*client);
  ASSERT_FALSE(result.is_discarded());
  EXPECT_EQ(result["errors"], json::array());
  EXPECT_EQ(NamedSessions(result), (std::vector<std::string>{first, second}));
  EXPECT_GT(result["counts_by_session"][first].value("/locaid/update", 0), 0);
  EXPECT_GE(result["counts_by_session"][second].value("/locaid/update", 0), 5);
  EXPECT_EQ(result["update_session_mismatches"], 0);
  EXPECT_NE(bridge.log().find("lost: UNAVAILABLE"), std::string::npos) << bridge.log();
}

TEST_F(BridgeTest, SendsTheTokenFromTokenFile) {
  {
    std::ofstream(dir_ / "token") << "s3cret-token\n";  // the trailing newline is not part of it
  }
  st::ServerProcess server(dir_ / "server", {"--token", "s3cret-token"});
  ASSERT_GT(server.port(), 0) << server.log();
  ft::BridgeProcess without(dir_ / "without", server.port(), ft::FreeLoopbackPort());
  ft::BridgeProcess with(dir_, server.port(), ft::FreeLoopbackPort(), {"--token-file", (dir_ / "token").string()});
  EXPECT_TRUE(without.WaitForLog("ListSessions failed: UNAUTHENTICATED", 20)) << without.log();
  EXPECT_TRUE(with.WaitForLog("no live session", 20)) << with.log();
  EXPECT_EQ(with.log().find("UNAUTHENTICATED"), std::string::npos) << with.log();
}

TEST_F(BridgeTest, BadFlagsAreUsageErrors) {
  auto run = [](const std::string& args) {
    return st::RunShell(st::ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-foxglove") + " " + args);
  };
  st::CliResult r = run("--server 127.0.0.1:1 --listen nonsense");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--listen 'nonsense': expected HOST:PORT"), std::string::npos) << r.err;
  r = run("--server 127.0.0.1:1 --listen 127.0.0.1:70000");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("port '70000' is not a number in [0, 65535]"), std::string::npos) << r.err;
  r = run("--listen 127.0.0.1:0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--server is required"), std::string::npos) << r.err;
  r = run("--server 127.0.0.1:1 --send-buffer 12");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--send-buffer"), std::string::npos) << r.err;
  r = run("--server 127.0.0.1:1 --token-file /nonexistent/token");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("/nonexistent/token"), std::string::npos) << r.err;
}

TEST_F(BridgeTest, AWebSocketPortInUseIsReported) {
  st::ServerProcess server(dir_ / "server");
  ASSERT_GT(server.port(), 0);
  // The gRPC server's own port is taken: the bridge cannot listen there.
  const st::CliResult r = st::RunShell(st::ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-foxglove") +
                                       " --server 127.0.0.1:" + std::to_string(server.port()) +
                                       " --listen 127.0.0.1:" + std::to_string(server.port()));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cannot listen on 127.0.0.1:" + std::to_string(server.port())), std::string::npos) << r.err;
}

}  // namespace
