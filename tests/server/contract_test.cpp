// Regression tests of the service contract (issue 18), each against the real
// locaid-server process on 127.0.0.1 driven by the real CLI or a gRPC stub
// built from proto/ alone, the way an outside client sees it.
#include "test_support.hpp"

#include "needs_tool.hpp"

#include <cstdlib>
#include <limits>
#include <set>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

void WriteFile(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

// The container's deploy/entrypoint.sh `server` with the container's
// variables `env` (NAME=value) and `server_args`, as a child process (killed
// when it goes out of scope). Its scratch is in `dir`: LOCAID_WORK_DIR is
// dir/work, and LOCAID_CONFIG names another folder there, dir/yaml_work, as
// the YAML's work_dir (which LOCAID_WORK_DIR overrides).
std::unique_ptr<ChildProcess> StartEntrypoint(const fs::path& dir, const std::vector<std::string>& env,
                                              const std::vector<std::string>& server_args) {
  fs::create_directories(dir);
  const fs::path work = dir / "work";
  WriteFile(dir / "entry.yaml", "work_dir: " + (dir / "yaml_work").string() + "\n");
  const char* path = std::getenv("PATH");
  std::vector<std::string> argv = {"/usr/bin/env",
                                   "PATH=" + std::string(LOCAID_BIN_DIR) + ":" + (path ? path : "/usr/bin:/bin"),
                                   "LOCAID_WORK_DIR=" + work.string(), "LOCAID_CONFIG=" + (dir / "entry.yaml").string(),
                                   "LOCAID_LISTEN=127.0.0.1:0"};
  argv.insert(argv.end(), env.begin(), env.end());
  argv.insert(argv.end(), {"bash", std::string(LOCAID_SOURCE_DIR) + "/deploy/entrypoint.sh", "server"});
  argv.insert(argv.end(), server_args.begin(), server_args.end());
  return std::make_unique<ChildProcess>(argv, ChildProcess::Options{dir / "entry.out", dir / "entry.err", 0});
}

// The port the entrypoint's server wrote to `port_file` (its --port-file),
// once it is there; 0 when the entrypoint ended first (or after 60 s).
int EntrypointPort(ChildProcess& entry, const fs::path& port_file) {
  int port = 0;
  for (int i = 0; i < 6000 && port == 0 && entry.running(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::ifstream(port_file) >> port;
    entry.Wait(0);
  }
  return port;
}

// Defect 1: the documented ways to keep the token out of argv.
TEST(Contract, TokenFileWorksAsFlagConfigKeyAndContainerVariable) {
  const ScopedTempDir dir("contract_token");
  WriteFile(dir / "token", "s3cret\n");
  WriteFile(dir / "server.yaml", "token_file: " + (dir / "token").string() + "\n");
  auto check = [&dir](int port, const std::string& how) {
    ASSERT_GT(port, 0) << how << ": the server did not start";
    CliResult r = RunCli(port, {"session", "list"});
    EXPECT_NE(r.err.find("UNAUTHENTICATED"), std::string::npos) << how << ": " << r.err;
    r = RunCli(port, {"session", "list"}, {"--token", "s3cret"});
    EXPECT_EQ(r.exit_code, 0) << how << ": " << r.err;
    // The client's side of keeping the secret out of argv.
    r = RunCli(port, {"session", "list"}, {"--token-file", (dir / "token").string()});
    EXPECT_EQ(r.exit_code, 0) << how << ", locaid --token-file: " << r.err;
    r = RunCli(port, {"session", "list"}, {"--token-file", (dir / "missing").string()});
    EXPECT_NE(r.err.find("--token-file " + (dir / "missing").string() + ": cannot read"), std::string::npos) << r.err;
  };
  {
    ServerProcess flag(dir / "flag", {"--token-file", (dir / "token").string()});
    check(flag.port(), "--token-file\n" + flag.log());
  }
  {
    ServerProcess yaml(dir / "yaml", {"--config", (dir / "server.yaml").string()});
    check(yaml.port(), "token_file: in --config\n" + yaml.log());
  }
  // The container's entrypoint maps LOCAID_TOKEN_FILE to --token-file.
  const fs::path entry_dir = dir / "entry", port_file = dir / "entry.port";
  const auto entry = StartEntrypoint(entry_dir, {"LOCAID_TOKEN_FILE=" + (dir / "token").string()},
                                     {"--port-file", port_file.string()});
  check(EntrypointPort(*entry, port_file), "LOCAID_TOKEN_FILE\n" + Slurp(entry_dir / "entry.err"));
  EXPECT_TRUE(entry->Signal(SIGTERM));
  EXPECT_TRUE(entry->Wait(30)) << "the entrypoint's server did not exit after SIGTERM";
}

// The container's LOCAID_WORK_DIR is the server's work_dir (--work-dir, over
// the YAML's): the drive a killed server left in LOCAID_WORK_DIR/synthetic is
// removed when the entrypoint's server starts, and the YAML's folder is not
// touched.
TEST(Contract, EntrypointPassesLocaidWorkDirToTheServer) {
  const ScopedTempDir dir("contract_workdir");
  const fs::path entry_dir = dir / "entry", port_file = dir / "entry.port";
  const fs::path stale = entry_dir / "work" / "synthetic" / "left-by-a-killed-server";
  const fs::path yaml_drive = entry_dir / "yaml_work" / "synthetic" / "not-this-servers";
  fs::create_directories(stale);
  fs::create_directories(yaml_drive);
  const auto entry = StartEntrypoint(entry_dir, {}, {"--port-file", port_file.string()});
  auto entry_log = [&] { return Slurp(entry_dir / "entry.out") + Slurp(entry_dir / "entry.err"); };
  ASSERT_GT(EntrypointPort(*entry, port_file), 0) << entry_log();
  EXPECT_FALSE(fs::exists(stale)) << "the server did not take LOCAID_WORK_DIR as its work_dir\n" << entry_log();
  EXPECT_NE(entry_log().find("in " + (entry_dir / "work" / "synthetic").string()), std::string::npos) << entry_log();
  EXPECT_TRUE(fs::exists(yaml_drive)) << "LOCAID_WORK_DIR overrides the YAML's work_dir\n" << entry_log();
  EXPECT_TRUE(entry->Signal(SIGTERM));
  EXPECT_TRUE(entry->Wait(30)) << "the entrypoint's server did not exit after SIGTERM";
}

// Defect 15: grpc.health.v1 answers for the service's full name too.
TEST(Contract, HealthAnswersForTheServerAndForTheServiceName) {
  const ScopedTempDir dir("contract_health");
  ServerProcess server(dir);
  ASSERT_GT(server.port(), 0) << server.log();
  EXPECT_EQ(RunCli(server.port(), {"health"}).out, "SERVING\n");
  EXPECT_EQ(RunCli(server.port(), {"health", "--service", "locaid.v1.Localization"}).out, "SERVING\n");
  const CliResult other = RunCli(server.port(), {"health", "--service", "locaid.v1.Nope"});
  EXPECT_NE(other.err.find("NOT_FOUND"), std::string::npos) << other.err;
}

v1::Session StartSynthetic(v1::Localization::Stub* stub, const std::string& scenario_yaml, int frames) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 60);
  v1::StartSessionRequest req;
  req.mutable_synthetic()->set_seed(3);
  req.mutable_synthetic()->set_frames(frames);
  req.mutable_synthetic()->set_options_yaml("width: 320\nheight: 96\n");
  if (!scenario_yaml.empty()) req.mutable_scenario()->set_yaml(scenario_yaml);
  req.set_playback_rate(0);
  v1::Session s;
  const grpc::Status st = stub->StartSession(&ctx, req, &s);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return s;
}

v1::Session Get(v1::Localization::Stub* stub, const std::string& id) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 10);
  v1::GetSessionRequest req;
  req.set_session_id(id);
  v1::Session s;
  EXPECT_TRUE(stub->GetSession(&ctx, req, &s).ok());
  return s;
}

// Defects 2, 14 and 16 (scenario name): a session of the real pipeline.
TEST(Contract, SessionReportsItsOriginIdsAreUniqueAcrossRestartsYamlScenarioIsNamedYaml) {
  const ScopedTempDir dir("contract_session");
  std::set<std::string> ids;
  std::string first_id;
  for (int run = 0; run < 2; ++run) {  // two server processes: a restart
    ServerProcess server(dir / ("run" + std::to_string(run)));
    ASSERT_GT(server.port(), 0) << server.log();
    auto stub = v1::Localization::NewStub(server.NewChannel());
    if (run == 1) {
      // The id from before the restart names nothing now.
      grpc::ClientContext ctx;
      SetDeadline(&ctx, 10);
      v1::GetSessionRequest req;
      req.set_session_id(first_id);
      v1::Session s;
      EXPECT_EQ(stub->GetSession(&ctx, req, &s).error_code(), grpc::NOT_FOUND);
    }
    const v1::Session s = StartSynthetic(stub.get(), "base: open-sky\nseed: 2\n", 60);
    ASSERT_FALSE(s.id().empty());
    EXPECT_EQ(s.id().size(), 13u) << s.id();
    EXPECT_TRUE(ids.insert(s.id()).second) << "id " << s.id() << " used twice";
    if (run == 0) first_id = s.id();
    EXPECT_EQ(s.scenario(), "yaml");
    v1::Session done;
    for (int i = 0; i < 600; ++i) {  // at most 60 s
      done = Get(stub.get(), s.id());
      if (done.state() == v1::SESSION_STATE_FINISHED || done.state() == v1::SESSION_STATE_FAILED) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_EQ(done.state(), v1::SESSION_STATE_FINISHED) << done.error();
    EXPECT_TRUE(done.has_origin()) << "the filter fixed its ENU origin at the first fix";
    // Synthetic drives are rendered around Karlsruhe (49 N, 8.4 E).
    EXPECT_NEAR(done.origin_latitude_deg(), 49.0, 1.0);
    EXPECT_NEAR(done.origin_longitude_deg(), 8.4, 1.0);
    // Defect 16: synthetic t_ns is Unix time (UTC) on the render date, as
    // the proto's header says.
    PoseCollector poses(server.NewChannel(9), s.id(), true, 30);
    ASSERT_TRUE(poses.WaitDone(30));
    ASSERT_FALSE(poses.poses().empty());
    constexpr int64_t k20240517 = 1715904000LL * 1000000000LL;
    EXPECT_GE(poses.poses().front().t_ns(), k20240517);
    EXPECT_LT(poses.poses().front().t_ns(), k20240517 + 86400LL * 1000000000LL);
  }
}

// Issue 19: what a viewer needs rides on each pose: the fixes the filter saw
// since the previous pose (with its gate's verdict) and, for drives with
// ground truth, the true pose in the same ENU frame and the error.
TEST(Contract, PosesCarryTheFixesTheFilterSawAndTheGroundTruth) {
  const ScopedTempDir dir("contract_viewer");
  ServerProcess server(dir);
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  const v1::Session s = StartSynthetic(stub.get(), "base: open-sky\nseed: 2\n", 60);
  PoseCollector poses(server.NewChannel(1), s.id(), true, 60);
  ASSERT_TRUE(poses.WaitDone(60));
  ASSERT_EQ(poses.poses().size(), 60u);
  int fixes = 0, used = 0, with_truth = 0;
  for (const v1::PoseUpdate& p : poses.poses()) {
    for (const v1::GpsFixSeen& f : p.gps_fixes()) {
      ++fixes;
      used += f.used() ? 1 : 0;
      EXPECT_LE(f.t_ns(), p.t_ns());
      EXPECT_NEAR(f.latitude_deg(), 49.0, 1.0);
      EXPECT_DOUBLE_EQ(f.sigma_horizontal_m(), 1.5);  // open-sky
      if (f.used()) {
        EXPECT_LE(f.nis(), f.gate());
      }
    }
    if (!p.has_truth()) continue;
    ++with_truth;
    const double dx = p.position_enu_m().x() - p.truth_position_enu_m().x();
    const double dy = p.position_enu_m().y() - p.truth_position_enu_m().y();
    EXPECT_NEAR(p.horizontal_error_m(), std::hypot(dx, dy), 1e-9);
    EXPECT_NEAR(p.truth_latitude_deg(), p.latitude_deg(), 1e-3);
    if (p.mode() == v1::MODE_GPS_FUSED) {
      EXPECT_LT(p.horizontal_error_m(), 5.0);
    }
  }
  // open-sky: 10 Hz fixes over 6 s, all before the last pose.
  EXPECT_GE(fixes, 55);
  EXPECT_GE(used, fixes - 15);  // the first few are buffered while the filter starts
  EXPECT_GE(with_truth, 50);    // every pose once the ENU origin is set
}

class ContractRequests : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_);
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = v1::Localization::NewStub(server_->NewChannel());
  }
  grpc::Status Start(const v1::StartSessionRequest& req, v1::Session* out = nullptr) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    v1::Session resp;
    const grpc::Status s = stub_->StartSession(&ctx, req, &resp);
    if (out) *out = resp;
    return s;
  }
  const ScopedTempDir dir_{"contract_requests"};  // outlives the server
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

// Defect 6: a huge input is answered with its own code and a cut echo.
TEST_F(ContractRequests, HugeInputsGetTheirOwnCodeAndACutEcho) {
  const std::string huge(1 << 20, 'x');
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 30);
  v1::GetSessionRequest get;
  get.set_session_id(huge);
  v1::Session session;
  grpc::Status s = stub_->GetSession(&ctx, get, &session);
  EXPECT_EQ(s.error_code(), grpc::NOT_FOUND) << s.error_message().substr(0, 300);
  EXPECT_LE(s.error_message().size(), 1100u);
  EXPECT_NE(s.error_message().find("(1048576 bytes)"), std::string::npos) << s.error_message();
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path("/" + huge);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << s.error_message().substr(0, 300);
  EXPECT_NE(s.error_message().find("PATH_MAX"), std::string::npos) << s.error_message().substr(0, 300);
  req.mutable_kitti()->set_path("/nonexistent/" + std::string(3000, 'y'));
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("(3013 bytes)"), std::string::npos) << s.error_message();
  EXPECT_EQ(RunCli(server_->port(), {"health"}).out, "SERVING\n");
}

// Defects 8 and 9: ranges are checked before the session exists.
TEST_F(ContractRequests, FrameRangeAndPlaybackRateAreCheckedBeforeOk) {
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(dir_.path().string());  // exists: the range check comes next
  req.mutable_kitti()->set_first_frame(10);
  req.mutable_kitti()->set_last_frame(5);
  grpc::Status s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("kitti.last_frame 5: before first_frame 10"), std::string::npos)
      << s.error_message();
  v1::StartSessionRequest live;
  *live.mutable_live() = SmallCamera();
  for (double bad : {1e-300, 1e-4, 1e4, -1.0, std::numeric_limits<double>::infinity()}) {
    live.set_playback_rate(bad);
    s = Start(live);
    EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << bad;
    EXPECT_NE(s.error_message().find("playback_rate: must be 0 (as fast as possible) or in [0.001, 1000]"),
              std::string::npos)
        << s.error_message();
  }
  for (double good : {0.0, 0.001, 2.5, 1000.0}) {
    live.set_playback_rate(good);
    EXPECT_TRUE(Start(live).ok()) << good;
  }
}

// Defect 7: synthetic options are validated before StartSession returns OK.
TEST_F(ContractRequests, SyntheticOptionsAreValidatedBeforeOk) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"width: [1, 2", "synthetic.options_yaml"},               // not YAML
      {"colour: red", "unknown key 'colour'"},                  // unknown key
      {"width: 100000\nheight: 100000", "out of range"},        // huge image
      {"frame_rate_hz: 0", "frame_rate_hz"},                    // zero rate
      {"noise_sigma_dn: .nan", "noise_sigma_dn"},               // NaN
      {"length_m: 50000", "max_synthetic_frames"},              // too long a drive
  };
  for (const auto& [yaml, expected] : bad) {
    v1::StartSessionRequest req;
    req.mutable_synthetic()->set_seed(1);
    req.mutable_synthetic()->set_frames(20);
    req.mutable_synthetic()->set_options_yaml(yaml);
    const grpc::Status s = Start(req);
    EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << yaml;
    EXPECT_NE(s.error_message().find(expected), std::string::npos) << yaml << " -> " << s.error_message();
  }
  v1::StartSessionRequest too_many;
  too_many.mutable_synthetic()->set_frames(100000);
  const grpc::Status s = Start(too_many);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("max_synthetic_frames=3000"), std::string::npos) << s.error_message();

  // The estimator is built once the drive is rendered; its VO method and
  // scenario are still checked before the answer.
  v1::StartSessionRequest bad_method;
  bad_method.mutable_synthetic()->set_frames(20);
  bad_method.set_vo_method("no-such-method");
  const grpc::Status m = Start(bad_method);
  EXPECT_EQ(m.error_code(), grpc::INVALID_ARGUMENT) << m.error_message();
  EXPECT_NE(m.error_message().find("unknown VO method 'no-such-method'"), std::string::npos) << m.error_message();
  bad_method.set_vo_method("thesis");
  EXPECT_TRUE(Start(bad_method).ok());
}

// Defect 11: a KITTI drive without right images is refused at StartSession.
TEST_F(ContractRequests, KittiDriveWithoutRightImagesIsFailedPrecondition) {
  const ScopedTempDir dir("contract_no_image_01");
  std::string error;
  const fs::path drive = RenderSynthDrive(dir / "2024_05_17", 6, 1, 160, 64, &error);
  ASSERT_FALSE(drive.empty()) << error;
  fs::remove_all(drive / "image_01");
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  const grpc::Status s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("has both a left and a right image"), std::string::npos) << s.error_message();
}

// Defect 10: controls of a stopped session are refused, not silently kept.
TEST_F(ContractRequests, OutageAndScenarioOnAStoppedSessionAreFailedPrecondition) {
  v1::StartSessionRequest req;
  *req.mutable_live() = SmallCamera();
  v1::Session session;
  ASSERT_TRUE(Start(req, &session).ok());
  {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 10);
    v1::StopSessionRequest stop;
    stop.set_session_id(session.id());
    v1::Session stopped;
    ASSERT_TRUE(stub_->StopSession(&ctx, stop, &stopped).ok());
  }
  grpc::ClientContext ctx1;
  SetDeadline(&ctx1, 10);
  v1::InjectOutageRequest outage;
  outage.set_session_id(session.id());
  outage.set_action(v1::InjectOutageRequest::START_NOW);
  v1::Session out;
  grpc::Status s = stub_->InjectOutage(&ctx1, outage, &out);
  EXPECT_EQ(s.error_code(), grpc::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("SESSION_STATE_STOPPED"), std::string::npos) << s.error_message();
  grpc::ClientContext ctx2;
  SetDeadline(&ctx2, 10);
  v1::SetScenarioRequest scenario;
  scenario.set_session_id(session.id());
  scenario.mutable_scenario()->set_name("open-sky");
  s = stub_->SetScenario(&ctx2, scenario, &out);
  EXPECT_EQ(s.error_code(), grpc::FAILED_PRECONDITION) << s.error_message();
}

// Defects 3 and 16 (state): rendering is STARTING, cancellable, parallel and
// bounded; StopSession never waits for a render (a full-size render takes a
// minute or more: a stop that waited would miss its 30 s deadline) and other
// RPCs answer meanwhile. How fast a stop returns is measured in bench/.
TEST(Contract, StopDuringRenderCancelsItAndRendersAreBounded) {
  const ScopedTempDir dir("contract_render");
  ServerProcess server(dir, {"--max-concurrent-renders", "3"});
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  auto start = [&](uint64_t seed, v1::Session* out) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    v1::StartSessionRequest req;
    req.mutable_synthetic()->set_seed(seed);
    req.mutable_synthetic()->set_frames(2000);  // full size: a render of a minute or more
    req.set_playback_rate(0);
    return stub->StartSession(&ctx, req, out);
  };
  std::vector<std::string> ids;
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    v1::Session s;
    const grpc::Status st = start(seed, &s);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(s.state(), v1::SESSION_STATE_STARTING) << "a drive being rendered is STARTING";
    ids.push_back(s.id());
  }
  v1::Session fourth;
  const grpc::Status busy = start(4, &fourth);
  EXPECT_EQ(busy.error_code(), grpc::RESOURCE_EXHAUSTED) << busy.error_message();
  EXPECT_NE(busy.error_message().find("max_concurrent_renders"), std::string::npos) << busy.error_message();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the renders are under way
  // Stop all three at once, from three threads, while ListSessions runs.
  std::vector<std::thread> stoppers;
  for (size_t i = 0; i < ids.size(); ++i) {
    stoppers.emplace_back([&, i] {
      auto own = v1::Localization::NewStub(server.NewChannel(static_cast<int>(i) + 1));
      grpc::ClientContext ctx;
      SetDeadline(&ctx, 30);
      v1::StopSessionRequest req;
      req.set_session_id(ids[i]);
      req.set_remove(true);
      v1::Session out;
      const grpc::Status st = own->StopSession(&ctx, req, &out);
      EXPECT_TRUE(st.ok()) << st.error_code() << " " << st.error_message();
      EXPECT_EQ(out.state(), v1::SESSION_STATE_STOPPED);
    });
  }
  {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    v1::ListSessionsResponse list;
    const grpc::Status st = stub->ListSessions(&ctx, v1::ListSessionsRequest{}, &list);
    EXPECT_TRUE(st.ok()) << st.error_code() << " " << st.error_message();
  }
  for (auto& t : stoppers) t.join();
  // Removed with their stop: nothing is left to list.
  {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    v1::ListSessionsResponse list;
    ASSERT_TRUE(stub->ListSessions(&ctx, v1::ListSessionsRequest{}, &list).ok());
    EXPECT_EQ(list.sessions_size(), 0);
  }
  // Cancelled renders leave no partial drive behind: StopSession answers at
  // once and each render's thread deletes its folder after the frame being
  // drawn, so the folders go soon after (bounded wait: a hang, not a speed).
  auto left = [&dir] {
    size_t n = 0;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir / "work" / "synthetic", ec)) n += e.is_directory() ? 1 : 0;
    return n;
  };
  for (int i = 0; i < 1200 && left() > 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(left(), 0u) << "rendered folders left in " << (dir / "work" / "synthetic");
  EXPECT_EQ(RunCli(server.port(), {"health"}).out, "SERVING\n");
}

size_t CountDirs(const fs::path& dir) {
  size_t n = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) n += e.is_directory() ? 1 : 0;
  return n;
}

// Defect 4: rendered drives live as long as their session's pipeline, and
// drives a killed server left behind are removed when the next one starts.
TEST(Contract, RenderedDrivesAreDeletedWithTheirSessionAndStaleOnesAtStartup) {
  const ScopedTempDir dir("contract_disk");
  const fs::path synthetic = dir / "work" / "synthetic";
  fs::create_directories(synthetic / "left-by-a-killed-server" / "2024_05_17");
  WriteFile(synthetic / "left-by-a-killed-server" / "2024_05_17" / "big.png", std::string(4096, 'x'));
  ServerProcess server(dir);
  ASSERT_GT(server.port(), 0) << server.log();
  EXPECT_EQ(CountDirs(synthetic), 0u) << "stale drive not removed at start-up";
  auto stub = v1::Localization::NewStub(server.NewChannel());
  for (int round = 0; round < 3; ++round) {
    const v1::Session s = StartSynthetic(stub.get(), "", 30);
    v1::Session done;
    for (int i = 0; i < 600; ++i) {
      done = Get(stub.get(), s.id());
      if (done.state() == v1::SESSION_STATE_FINISHED || done.state() == v1::SESSION_STATE_FAILED) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_EQ(done.state(), v1::SESSION_STATE_FINISHED) << done.error();
    for (int i = 0; i < 100 && CountDirs(synthetic) > 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    EXPECT_EQ(CountDirs(synthetic), 0u) << "round " << round << ": the finished session's drive is still on disk";
  }
}

// Defect 5: ended sessions are kept for a while, not forever. StopSession
// answers STOPPED at once; the session has ended (ended_unix_ns set) once its
// thread is done, and only ended sessions count against the caps, so the
// test waits for that event (bounded) before it lists.
TEST(Contract, EndedSessionsAreCappedByCountAndAge) {
  const ScopedTempDir dir("contract_ended");
  ServerProcess server(dir, {"--max-ended-sessions", "3"});
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  auto start_and_stop = [&] {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 10);
    v1::StartSessionRequest req;
    *req.mutable_live() = SmallCamera();
    v1::Session s;
    EXPECT_TRUE(stub->StartSession(&ctx, req, &s).ok());
    grpc::ClientContext stop_ctx;
    SetDeadline(&stop_ctx, 10);
    v1::StopSessionRequest stop;
    stop.set_session_id(s.id());
    v1::Session out;
    EXPECT_TRUE(stub->StopSession(&stop_ctx, stop, &out).ok());
    v1::Session now = Get(stub.get(), s.id());
    for (int i = 0; i < 1000 && now.ended_unix_ns() == 0; ++i) {  // at most 10 s
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      now = Get(stub.get(), s.id());
    }
    EXPECT_GT(now.ended_unix_ns(), 0) << s.id() << " never ended after StopSession";
    return s.id();
  };
  auto list = [&] {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 10);
    v1::ListSessionsResponse r;
    EXPECT_TRUE(stub->ListSessions(&ctx, v1::ListSessionsRequest{}, &r).ok());
    return r;
  };
  std::vector<std::string> ids;
  for (int i = 0; i < 6; ++i) ids.push_back(start_and_stop());
  const auto kept = list();
  ASSERT_EQ(kept.sessions_size(), 3);
  for (const auto& s : kept.sessions()) {
    EXPECT_TRUE(s.id() == ids[3] || s.id() == ids[4] || s.id() == ids[5]) << s.id() << ": not one of the newest";
  }
  ServerProcess ttl(dir / "ttl", {"--ended-session-ttl-s", "0"});
  ASSERT_GT(ttl.port(), 0) << ttl.log();
  stub = v1::Localization::NewStub(ttl.NewChannel());
  start_and_stop();
  EXPECT_EQ(list().sessions_size(), 0) << "ended_session_ttl_s 0 keeps nothing once it ended";
}

// Operator metrics: a live scrape passes Debian's promtool and carries the
// session's figures; the endpoint is set by flag, YAML key or the container's
// LOCAID_METRICS_LISTEN (entrypoint).
int MetricsPortFromLog(const std::string& log) {
  const auto at = log.find("metrics on 127.0.0.1:");
  return at == std::string::npos ? 0 : std::atoi(log.c_str() + at + std::string("metrics on 127.0.0.1:").size());
}

std::string Scrape(int port) {
  const CliResult r = RunShell("/usr/bin/python3 -c \"import urllib.request,sys; sys.stdout.write("
                               "urllib.request.urlopen('http://127.0.0.1:" + std::to_string(port) +
                               "/metrics', timeout=10).read().decode())\"");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out;
}

TEST(Contract, MetricsScrapePassesPromtoolAndCarriesTheSession) {
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("promtool"),
                    "promtool not installed (deploy/install-deps.sh installs Debian's prometheus package)");
  const ScopedTempDir dir("contract_metrics");
  WriteFile(dir / "server.yaml", "metrics_listen: 127.0.0.1:0\n");
  ServerProcess server(dir, {"--config", (dir / "server.yaml").string()});
  ASSERT_GT(server.port(), 0) << server.log();
  int port = 0;
  for (int i = 0; i < 200 && port == 0; ++i) {
    port = MetricsPortFromLog(server.log());
    if (port == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_GT(port, 0) << "no 'metrics on' in the log:\n" << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  const v1::Session s = StartSynthetic(stub.get(), "", 40);
  for (int i = 0; i < 600 && Get(stub.get(), s.id()).state() != v1::SESSION_STATE_FINISHED; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const std::string text = Scrape(port);
  WriteFile(dir / "scrape.txt", text);
  const CliResult lint = RunShell("promtool check metrics < " + ShellQuote((dir / "scrape.txt").string()));
  EXPECT_EQ(lint.exit_code, 0) << lint.out << lint.err << "\n" << text.substr(0, 2000);
  const std::vector<std::string> expected_lines = {
       std::string("locaid_sessions{state=\"finished\"} 1"),
        "locaid_session_frames_total{session=\"" + s.id() + "\",kind=\"processed\"} 40",
        "locaid_session_processing_latency_seconds_count{session=\"" + s.id() + "\"} 40",
        "locaid_session_mode{session=\"" + s.id() + "\",mode=\"gps_fused\"}",
        "locaid_session_gps_nis{session=\"" + s.id() + "\"}", "locaid_session_vo_inliers{session=\"",
        "locaid_session_position_sigma_meters{", "locaid_render_queue 0", "locaid_resident_memory_bytes ",
        "locaid_session_vo_noise_scale{session=\"" + s.id() + "\",axis=\"ry\"}",
        "locaid_session_gps_noise_scale{session=\"" + s.id() + "\",component=\"horizontal\"}"};
  for (const std::string& expected : expected_lines) {
    EXPECT_NE(text.find(expected), std::string::npos) << "missing: " << expected << "\n" << text.substr(0, 3000);
  }
  // The flag and the container variable reach the same setting.
  ServerProcess by_flag(dir / "flag", {"--metrics-listen", "127.0.0.1:0"});
  ASSERT_GT(by_flag.port(), 0) << by_flag.log();
  for (int i = 0; i < 200 && MetricsPortFromLog(by_flag.log()) == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_NE(Scrape(MetricsPortFromLog(by_flag.log())).find("locaid_sessions{"), std::string::npos);
  const fs::path entry_dir = dir / "entry";
  const auto entry = StartEntrypoint(entry_dir, {"LOCAID_METRICS_LISTEN=127.0.0.1:0"}, {});
  auto entry_log = [&] { return Slurp(entry_dir / "entry.out") + Slurp(entry_dir / "entry.err"); };
  for (int i = 0; i < 1000 && MetricsPortFromLog(entry_log()) == 0 && !entry->Wait(0); ++i)  // at most 10 s
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GT(MetricsPortFromLog(entry_log()), 0) << entry_log();
  EXPECT_TRUE(entry->Signal(SIGTERM));
  EXPECT_TRUE(entry->Wait(30)) << "the entrypoint's server did not exit after SIGTERM";
}

// The container's LOCAID_MAX_CPU_CORES is the server's --max-cpu-cores: with
// a budget below one session's prior, a real-time session is refused.
TEST(Contract, EntrypointPassesLocaidMaxCpuCoresToTheServer) {
  const ScopedTempDir dir("contract_max_cpu");
  const fs::path port_file = dir / "port";
  const auto entry = StartEntrypoint(dir / "entry", {"LOCAID_MAX_CPU_CORES=0.2"}, {"--port-file", port_file.string()});
  const int port = EntrypointPort(*entry, port_file);
  ASSERT_GT(port, 0) << Slurp(dir / "entry" / "entry.err");
  auto stub = MakeStub(port);
  v1::StartSessionRequest req;
  req.mutable_live()->CopyFrom(SmallCamera());
  v1::Session s;
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  const grpc::Status st = stub->StartSession(&ctx, req, &s);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  EXPECT_NE(st.error_message().find("max_cpu_cores (0.2)"), std::string::npos) << st.error_message();
  EXPECT_TRUE(entry->Signal(SIGTERM));
  EXPECT_TRUE(entry->Wait(30)) << "the entrypoint's server did not exit after SIGTERM";
}

}  // namespace
}  // namespace locaid::server::testing
