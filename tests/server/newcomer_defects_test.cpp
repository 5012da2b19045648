// What a new user and a broken peer ran into (issue 30), each against the
// real locaid-server process and the real CLI: a second server on a port in
// use, huge-but-finite typed input, a gpsd that accepts and sends garbage,
// and the CLI's exit codes, scenario paths and unknown ids.
#include "test_support.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <atomic>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kT0 = 1'700'000'000'000'000'000LL;
constexpr int64_t kFrameNs = 100'000'000;

TEST(NewcomerDefects, ASecondServerOnAPortInUseFailsAtStartup) {
  const ScopedTempDir dir("port_in_use");
  ServerProcess first(dir / "first");
  ASSERT_GT(first.port(), 0) << first.log();
  const std::string listen = "127.0.0.1:" + std::to_string(first.port());
  ChildProcess second({std::string(LOCAID_BIN_DIR) + "/locaid-server", "--listen", listen, "--work-dir",
                       (dir / "second_work").string()},
                      {dir / "second.out", dir / "second.err", 0});
  ASSERT_TRUE(second.Wait(30)) << "the second server kept running on a port in use";
  EXPECT_EQ(second.exit_code(), 1);
  const std::string err = Slurp(dir / "second.err");
  EXPECT_NE(err.find("listen " + listen + ": cannot bind: address already in use"), std::string::npos) << err;
  // The first one still answers, alone.
  EXPECT_EQ(RunCli(first.port(), {"health"}).out, "SERVING\n");
}

v1::PushRequest Imu(int64_t t_ns) {
  v1::PushRequest r;
  r.mutable_imu()->set_t_ns(t_ns);
  r.mutable_imu()->mutable_accel_mps2()->set_z(9.81);
  return r;
}

v1::PushRequest Fix(int64_t t_ns) {
  v1::PushRequest r;
  auto* g = r.mutable_gps();
  g->set_t_ns(t_ns);
  g->set_fix_type(v1::GPS_FIX_3D);
  g->set_latitude_deg(49.0);
  g->set_longitude_deg(8.4);
  g->set_altitude_m(110);
  g->set_sigma_horizontal_m(1.5);
  return r;
}

// Squares of 1e300 overflow: such values are refused by name, and no pose
// ever carries a non-finite number.
TEST(NewcomerDefects, HugeButFiniteSensorValuesAreRefusedByName) {
  const ScopedTempDir dir("huge_input");
  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  Pusher push(stub.get(), "");
  ASSERT_TRUE(push.ok());
  std::vector<v1::PushRequest> bad;
  int64_t t = kT0;
  auto imu = [&t](auto set) {
    v1::PushRequest r = Imu(t += 1000);
    set(r.mutable_imu());
    return r;
  };
  auto fix = [&t](auto set) {
    v1::PushRequest r = Fix(t += 1000);
    set(r.mutable_gps());
    return r;
  };
  bad.push_back(imu([](v1::ImuSample* m) { m->set_accel_noise_mps2_sqrt_hz(1e300); }));
  bad.push_back(imu([](v1::ImuSample* m) { m->set_gyro_noise_radps_sqrt_hz(1e300); }));
  bad.push_back(imu([](v1::ImuSample* m) { m->set_accel_noise_mps2_sqrt_hz(std::nan("")); }));
  bad.push_back(fix([](v1::GpsFix* g) { g->set_sigma_horizontal_m(1e300); }));
  bad.push_back(fix([](v1::GpsFix* g) { g->set_sigma_vertical_m(1e300); }));
  bad.push_back(fix([](v1::GpsFix* g) {
    for (int i = 0; i < 9; ++i) g->add_covariance_enu_m2(i % 4 == 0 ? 1e300 : 0.0);
  }));
  bad.push_back(fix([](v1::GpsFix* g) {
    g->set_has_velocity(true);
    g->set_sigma_velocity_mps(1e300);
  }));
  for (const auto& r : bad) ASSERT_TRUE(push.Write(r));
  // Then good input: frames with IMU and fixes, so the filter runs.
  for (int f = 1; f <= 20; ++f) {
    const int64_t tf = t + f * kFrameNs;
    for (int k = 9; k >= 0; --k) ASSERT_TRUE(push.Write(Imu(tf - k * kFrameNs / 10)));
    ASSERT_TRUE(push.Write(Fix(tf - kFrameNs / 2)));
    ASSERT_TRUE(push.Write(Gray8Frame(tf)));
  }
  ASSERT_TRUE(push.WaitPoses(20));
  ASSERT_TRUE(push.Close().ok());
  std::vector<std::string> reasons;
  for (const auto& r : push.rejected()) reasons.push_back(r.kind() + ": " + r.reason());
  ASSERT_EQ(reasons.size(), bad.size()) << ::testing::PrintToString(reasons);
  EXPECT_EQ(reasons[0], "imu: accel_noise_mps2_sqrt_hz: must be <= 10, got 1e+300");
  EXPECT_EQ(reasons[1], "imu: gyro_noise_radps_sqrt_hz: must be <= 1, got 1e+300");
  EXPECT_EQ(reasons[2], "imu: accel_noise_mps2_sqrt_hz: must be > 0 (or 0 for the default), got nan");
  EXPECT_EQ(reasons[3], "gps: sigma_horizontal_m: must be <= 10000, got 1e+300");
  EXPECT_EQ(reasons[4], "gps: sigma_vertical_m: must be <= 10000, got 1e+300");
  EXPECT_NE(reasons[5].find("gps: covariance_enu_m2: every value must be finite with |value| <= 1e+08"),
            std::string::npos) << reasons[5];
  EXPECT_EQ(reasons[6], "gps: sigma_velocity_mps: must be <= 1000, got 1e+300");
  for (const auto& p : push.poses()) EXPECT_TRUE(NonFinitePoseFields(p).empty()) << p.ShortDebugString();
}

// A TCP listener on 127.0.0.1 that accepts, writes garbage and hangs up;
// records when each connection arrived.
class GarbageGpsd {
 public:
  GarbageGpsd() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a));
    ::listen(fd_, 8);
    socklen_t len = sizeof(a);
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] {
      for (;;) {
        const int c = ::accept(fd_, nullptr, nullptr);
        if (c < 0) return;  // shut down
        {
          std::lock_guard lock(mu_);
          accepted_.push_back(std::chrono::steady_clock::now());
        }
        const char junk[] = "{\"class\":\x01\x02 not json at all\r\n\xff\xfe}}}\n";
        (void)!::write(c, junk, sizeof(junk) - 1);
        ::close(c);
      }
    });
  }
  ~GarbageGpsd() {
    ::shutdown(fd_, SHUT_RDWR);
    ::close(fd_);
    thread_.join();
  }
  int port() const { return port_; }
  std::vector<std::chrono::steady_clock::time_point> accepted() {
    std::lock_guard lock(mu_);
    return accepted_;
  }

 private:
  int fd_ = -1, port_ = 0;
  std::thread thread_;
  std::mutex mu_;
  std::vector<std::chrono::steady_clock::time_point> accepted_;
};

// Each failed connection doubles the wait before the next (0.5, 1, 2 s):
// asserted as lower bounds on the gaps, which load can only lengthen.
TEST(NewcomerDefects, AGpsdSendingGarbageIsRetriedWithGrowingBackoff) {
  GarbageGpsd gpsd;
  const ScopedTempDir dir("gpsd_backoff");
  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  v1::StartSessionRequest req;
  *req.mutable_live() = SmallCamera();
  req.mutable_live()->mutable_gps_source()->mutable_gpsd()->set_host("127.0.0.1");
  req.mutable_live()->mutable_gps_source()->mutable_gpsd()->set_port(static_cast<uint32_t>(gpsd.port()));
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  v1::Session session;
  ASSERT_TRUE(stub->StartSession(&ctx, req, &session).ok());
  for (int i = 0; i < 600 && gpsd.accepted().size() < 4; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const auto at = gpsd.accepted();
  // (Before the fix the first hang-up killed the server with SIGPIPE.)
  ASSERT_FALSE(server.process().Wait(0)) << "the server died, signal " << server.process().term_signal();
  ASSERT_GE(at.size(), 4u) << "the server stopped retrying\n" << server.log();
  double expected_s = 0.5;
  for (size_t i = 1; i < 4; ++i, expected_s *= 2) {
    const double gap_s = std::chrono::duration<double>(at[i] - at[i - 1]).count();
    EXPECT_GE(gap_s, 0.9 * expected_s) << "gap " << i << " after a garbage connection";
  }
  const v1::SessionStats stats = GetStats(stub.get(), session.id());
  EXPECT_GE(stats.gpsd().connection_losses() + stats.gpsd().connects(), 3u);
}

// The CLI as the README tells a newcomer to use it.
class CliUsage : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
  }
  const ScopedTempDir dir_{"cli_usage"};
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(CliUsage, UsageErrorsExit2) {
  const int port = server_->port();
  EXPECT_EQ(RunCli(port, {"sesion", "list"}).exit_code, 2);                      // misspelt subcommand
  EXPECT_EQ(RunCli(port, {"session", "get"}).exit_code, 2);                      // missing id
  EXPECT_EQ(RunCli(port, {"subscribe", "x", "--format", "json"}).exit_code, 2);  // not a format
  EXPECT_EQ(RunCli(port, {"--help"}).exit_code, 0);
}

TEST_F(CliUsage, SubscribingToAnUnknownIdFailsAndWritesNothing) {
  const fs::path out = dir_ / "poses.csv";
  const CliResult r = RunCli(server_->port(), {"subscribe", "s000000000000", "--format", "csv", "--out", out.string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(CliUsage, ScenarioTakesAYamlPathAndRelativeKittiPathsAreTheCallers) {
  std::string error;
  const fs::path drive = RenderSynthDrive(dir_ / "drive", 12, 2, 320, 120, &error);
  ASSERT_FALSE(drive.empty()) << error;
  std::ofstream(dir_ / "mine.yaml") << "name: mine\nbase: open-sky\noutages: [{start_s: 0.5, duration_s: 0.3}]\n";
  // `cd` into the test folder: the path is relative to the CLI, not to the server.
  const std::string cli = ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid") + " --server 127.0.0.1:" +
                          std::to_string(server_->port());
  const CliResult r = RunShell("cd " + ShellQuote(dir_.path().string()) + " && " + cli + " session start --kitti " +
                               ShellQuote(fs::relative(drive, dir_.path()).string()) + " --scenario mine.yaml");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  const CliResult get = RunCli(server_->port(), {"session", "get", id});
  EXPECT_NE(get.out.find("scenario=mine"), std::string::npos) << get.out;
  EXPECT_NE(get.out.find("source=kitti:" + drive.string()), std::string::npos) << get.out;
  // A path the server cannot see says where a relative one would be looked for.
  auto stub = v1::Localization::NewStub(server_->NewChannel());
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path("no/such/drive");
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  v1::Session out;
  const grpc::Status s = stub->StartSession(&ctx, req, &out);
  EXPECT_NE(s.error_message().find("resolved from the server's working directory"), std::string::npos)
      << s.error_message();
}

// A scenario whose outage covers the whole drive: the session says so.
TEST_F(CliUsage, AnOutageCoveringTheDriveIsExplained) {
  std::string error;
  const fs::path drive = RenderSynthDrive(dir_ / "drive", 12, 2, 320, 120, &error);
  ASSERT_FALSE(drive.empty()) << error;
  const CliResult r = RunCli(server_->port(), {"session", "start", "--kitti", drive.string(), "--scenario", "tunnel-30s"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  auto stub = v1::Localization::NewStub(server_->NewChannel());
  v1::Session s;
  for (int i = 0; i < 600; ++i) {  // until the first pose was made
    ASSERT_TRUE(FetchSession(stub.get(), id, &s).ok());
    if (s.stats().frames_processed() > 0 || s.state() != v1::SESSION_STATE_RUNNING) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_NE(s.error().find("never gets a GPS fix to start from"), std::string::npos) << s.ShortDebugString();
  // locaid-replay says the same, and explains its metrics instead of "nan".
  const CliResult replay = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-replay") + " --drive " +
                                    ShellQuote(drive.string()) + " --scenario tunnel-30s");
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_NE(replay.err.find("warning: scenario tunnel-30s: its outages cover the whole"), std::string::npos)
      << replay.err;
  EXPECT_NE(replay.out.find("n/a (no frame had GPS in use"), std::string::npos) << replay.out;
  EXPECT_EQ(replay.out.find("nan"), std::string::npos) << replay.out;
  EXPECT_EQ(replay.out.find("-1 s"), std::string::npos) << replay.out;
}

}  // namespace
}  // namespace locaid::server::testing
