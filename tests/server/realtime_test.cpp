// Keeping real time (issue 32): the RealTimeMonitor's arithmetic, a paced
// session that cannot keep its rate saying so in every place a user looks
// (PoseUpdate, GetStats, `locaid stats`, the metrics), an unpaced one never
// late, and admission by measured CPU through the flag and the YAML key.
// Sessions that must fall behind ask for 1000 x real time, which no machine
// keeps: nothing here depends on how fast or loaded the machine is.
#include "test_support.hpp"

#include "server/realtime_monitor.hpp"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;
using Clock = RealTimeMonitor::Clock;
using std::chrono::milliseconds;

constexpr int64_t kFrameNs = 100'000'000;  // 10 Hz

TEST(RealTimeMonitor, LatenessIsPublishTimeMinusDueTimeAndAStallGrowsIt) {
  RealTimeMonitor m(1.0, 0.1);
  const Clock::time_point w0{};
  EXPECT_EQ(m.NotePose(0, std::nullopt, w0), 0.0) << "the first pose sets the pace";
  EXPECT_EQ(m.NotePose(kFrameNs, w0 + milliseconds(100), w0 + milliseconds(100)), 0.0) << "on time";
  EXPECT_NEAR(m.NotePose(2 * kFrameNs, w0 + milliseconds(200), w0 + milliseconds(250)), 0.05, 1e-9);
  EXPECT_FALSE(m.FallingBehind(w0 + milliseconds(250)));
  // The next pose was due at 300 ms: at 450 ms it is 150 ms overdue, beyond the threshold.
  EXPECT_NEAR(m.BehindNow(w0 + milliseconds(450)), 0.15, 1e-9);
  EXPECT_TRUE(m.FallingBehind(w0 + milliseconds(450)));
  v1::SessionStats s;
  m.Fill(&s, w0 + milliseconds(450));
  EXPECT_TRUE(s.falling_behind());
  EXPECT_NEAR(s.behind_real_time_s(), 0.15, 1e-9);
  EXPECT_NEAR(s.behind_real_time_max_s(), 0.15, 1e-9);
  // Sensor 0.2 s over 0.45 s of wall time.
  EXPECT_NEAR(s.realtime_factor(), 0.2 / 0.45, 1e-9);
  // An ended session has nothing overdue; its newest pose's lateness stays.
  m.NoteEnded();
  EXPECT_NEAR(m.BehindNow(w0 + milliseconds(5000)), 0.05, 1e-9);
}

// A gap in the input (KITTI's missing frames): the session sleeps until the
// next pose's due time and is not behind meanwhile.
TEST(RealTimeMonitor, WaitingForALaterDueTimeIsNotBeingBehind) {
  RealTimeMonitor m(1.0, 0.1);
  const Clock::time_point w0{};
  m.NotePose(0, std::nullopt, w0);
  m.NotePose(kFrameNs, w0 + milliseconds(100), w0 + milliseconds(100));
  // Frames 2 and 3 are missing: frame 4 is due at 400 ms, and the session waits for it.
  m.NoteWaiting(w0 + milliseconds(400));
  EXPECT_EQ(m.BehindNow(w0 + milliseconds(350)), 0.0);
  EXPECT_FALSE(m.FallingBehind(w0 + milliseconds(350)));
  // Had it not been waiting, 350 ms would be 150 ms past the estimated 200 ms.
  RealTimeMonitor stalled(1.0, 0.1);
  stalled.NotePose(0, std::nullopt, w0);
  stalled.NotePose(kFrameNs, w0 + milliseconds(100), w0 + milliseconds(100));
  EXPECT_TRUE(stalled.FallingBehind(w0 + milliseconds(350)));
}

TEST(RealTimeMonitor, UnpacedSessionsAreNeverLate) {
  RealTimeMonitor m(0.0, 0.1);
  const Clock::time_point w0{};
  for (int i = 0; i < 20; ++i) EXPECT_EQ(m.NotePose(i * kFrameNs, std::nullopt, w0 + milliseconds(10 * i)), 0.0);
  EXPECT_EQ(m.BehindNow(w0 + milliseconds(100000)), 0.0);
  v1::SessionStats s;
  m.Fill(&s, w0 + milliseconds(150));
  EXPECT_FALSE(s.falling_behind());
  // Sampled every 50 ms (poses at 0, 50, 100, 150 ms): 1.5 s of sensor time in 0.15 s.
  EXPECT_NEAR(s.realtime_factor(), 10.0, 1e-6);
  // Later, with no new pose, the factor falls (up to now, not to the newest pose).
  m.Fill(&s, w0 + milliseconds(300));
  EXPECT_NEAR(s.realtime_factor(), 5.0, 1e-6);
}

TEST(RealTimeMonitor, CpuCoresIsTheThreadsCpuTimeOverWallTime) {
  RealTimeMonitor m(1.0, 0.1);
  const Clock::time_point w0{};
  m.NoteCpu(w0);
  // Burn CPU on this thread until its CPU clock moved 30 ms (no wall-clock assumption).
  timespec start{}, now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &start);
  volatile double sink = 0;
  do {
    for (int i = 0; i < 100000; ++i) sink = sink + i * 1e-9;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  } while ((now.tv_sec - start.tv_sec) * 1e9 + (now.tv_nsec - start.tv_nsec) < 30e6);
  m.NoteCpu(w0 + milliseconds(100));
  // >= 30 ms of CPU in 100 ms of (stated) wall time.
  EXPECT_GE(m.CpuCores(w0 + milliseconds(100)), 0.3);
  m.NoteEnded();
  EXPECT_EQ(m.CpuCores(w0 + milliseconds(100)), 0.0) << "an ended session costs nothing";
}

// A synthetic drive the real server can play (no shared data needed).
fs::path SmallDrive(const fs::path& dir, int frames) {
  std::string error;
  const fs::path drive = RenderSynthDrive(dir, frames, 5, 320, 96, &error);
  EXPECT_FALSE(drive.empty()) << error;
  return drive;
}

v1::StartSessionRequest PacedKitti(const fs::path& drive, double rate) {
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  req.set_playback_rate(rate);
  return req;
}

grpc::Status Start(v1::Localization::Stub* stub, const v1::StartSessionRequest& req, v1::Session* out) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 30);
  return stub->StartSession(&ctx, req, out);
}

TEST(KeepingRealTime, APacedSessionThatCannotKeepItsRateSaysSoEverywhere) {
  const ScopedTempDir dir("realtime_behind");
  const fs::path drive = SmallDrive(dir.path() / "drive", 60);
  ASSERT_FALSE(drive.empty());
  // The threshold from the YAML file (the flag's range check is below).
  std::ofstream(dir.path() / "server.yaml") << "behind_threshold_s: 0.05\n";
  ServerProcess server(dir.path() / "server",
                       {"--metrics-listen", "127.0.0.1:0", "--config", (dir.path() / "server.yaml").string()});
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());

  // 1000 x real time: each 100 ms frame is due 0.1 ms after the previous one.
  v1::Session paced, unpaced;
  ASSERT_TRUE(Start(stub.get(), PacedKitti(drive, 1000), &paced).ok());
  PoseCollector collector(server.NewChannel(1), paced.id(), true);
  ASSERT_TRUE(collector.WaitDone(180)) << "the session did not end";
  const auto poses = collector.poses();
  ASSERT_EQ(poses.size(), 60u);
  EXPECT_EQ(poses.front().behind_real_time_s(), 0.0) << "the first pose sets the pace";
  EXPECT_GT(poses.back().behind_real_time_s(), 0.05);
  EXPECT_TRUE(poses.back().falling_behind());
  for (size_t i = 1; i < poses.size(); ++i)
    EXPECT_EQ(poses[i].falling_behind(), poses[i].behind_real_time_s() > 0.05) << "pose " << i;
  const v1::SessionStats stats = GetStats(stub.get(), paced.id());
  EXPECT_TRUE(stats.falling_behind());
  EXPECT_EQ(stats.behind_real_time_s(), poses.back().behind_real_time_s()) << "ended: the newest pose's lateness";
  EXPECT_GE(stats.behind_real_time_max_s(), stats.behind_real_time_s());
  EXPECT_LT(stats.realtime_factor(), 1000.0);

  const CliResult cli = RunCli(server.port(), {"stats", paced.id()});
  ASSERT_EQ(cli.exit_code, 0) << cli.err;
  EXPECT_NE(cli.out.find("\nfalling_behind true\n"), std::string::npos) << cli.out;
  EXPECT_NE(cli.out.find("\nbehind_real_time_s "), std::string::npos) << cli.out;
  EXPECT_NE(cli.out.find("\ncpu_cores "), std::string::npos) << cli.out;

  int metrics_port = 0;
  const std::string marker = "metrics on 127.0.0.1:";
  for (int i = 0; i < 200 && metrics_port == 0; ++i) {
    const std::string log = server.log();
    if (const auto at = log.find(marker); at != std::string::npos) metrics_port = std::atoi(log.c_str() + at + marker.size());
    else std::this_thread::sleep_for(milliseconds(10));
  }
  ASSERT_GT(metrics_port, 0) << server.log();
  const CliResult scrape = RunShell("/usr/bin/python3 -c \"import urllib.request,sys; sys.stdout.write("
                                    "urllib.request.urlopen('http://127.0.0.1:" + std::to_string(metrics_port) +
                                    "/metrics', timeout=10).read().decode())\"");
  ASSERT_EQ(scrape.exit_code, 0) << scrape.err;
  EXPECT_NE(scrape.out.find("locaid_session_falling_behind{session=\"" + paced.id() + "\"} 1"), std::string::npos)
      << scrape.out.substr(0, 3000);
  for (const char* name : {"locaid_session_behind_real_time_seconds{", "locaid_session_realtime_factor{",
                           "locaid_session_cpu_cores{", "locaid_realtime_cpu_cores ", "locaid_realtime_cpu_cores_limit 0"})
    EXPECT_NE(scrape.out.find(name), std::string::npos) << name;

  // Unpaced: as fast as it can, never late.
  ASSERT_TRUE(Start(stub.get(), PacedKitti(drive, 0), &unpaced).ok());
  PoseCollector unpaced_collector(server.NewChannel(2), unpaced.id(), true);
  ASSERT_TRUE(unpaced_collector.WaitDone(180));
  for (const v1::PoseUpdate& p : unpaced_collector.poses()) {
    EXPECT_EQ(p.behind_real_time_s(), 0.0);
    EXPECT_FALSE(p.falling_behind());
  }
  EXPECT_FALSE(GetStats(stub.get(), unpaced.id()).falling_behind());
}

// max_cpu_cores by flag and by YAML key: with a prior of 0.5 core per
// real-time session, a 0.3-core budget admits none (whatever the machine
// measures: nothing runs yet), while unpaced (batch) sessions are not counted.
TEST(KeepingRealTime, MaxCpuCoresRefusesRealTimeSessionsBeyondTheBudget) {
  const ScopedTempDir dir("realtime_admission");
  const fs::path drive = SmallDrive(dir.path() / "drive", 20);
  ASSERT_FALSE(drive.empty());
  std::ofstream(dir.path() / "server.yaml") << "max_cpu_cores: 0.3\nsession_cpu_cores_prior: 0.5\n";
  for (const bool by_flag : {true, false}) {
    SCOPED_TRACE(by_flag ? "flags" : "YAML");
    const std::vector<std::string> args =
        by_flag ? std::vector<std::string>{"--max-cpu-cores", "0.3", "--session-cpu-cores-prior", "0.5"}
                : std::vector<std::string>{"--config", (dir.path() / "server.yaml").string()};
    ServerProcess server(dir.path() / (by_flag ? "flag" : "yaml"), args);
    ASSERT_GT(server.port(), 0) << server.log();
    auto stub = v1::Localization::NewStub(server.NewChannel());
    v1::Session s;
    const grpc::Status refused = Start(stub.get(), PacedKitti(drive, 1), &s);
    EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(refused.error_message().find("max_cpu_cores (0.3)"), std::string::npos) << refused.error_message();
    EXPECT_NE(refused.error_message().find("the prior"), std::string::npos) << refused.error_message();
    EXPECT_TRUE(Start(stub.get(), PacedKitti(drive, 0), &s).ok()) << "batch sessions are not counted";
  }
}

// Sessions started together: the young ones count with the estimate, so the
// budget is not overrun before any measurement exists.
TEST(KeepingRealTime, SessionsStartedTogetherCountWithTheEstimate) {
  const ScopedTempDir dir("realtime_together");
  const fs::path drive = SmallDrive(dir.path() / "drive", 40);
  ASSERT_FALSE(drive.empty());
  ServerProcess server(dir.path() / "server", {"--max-cpu-cores", "1.0", "--session-cpu-cores-prior", "0.6"});
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  v1::Session first, second;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(Start(stub.get(), PacedKitti(drive, 1), &first).ok());
  const grpc::Status st = Start(stub.get(), PacedKitti(drive, 1), &second);
  if (std::chrono::steady_clock::now() - t0 >= std::chrono::seconds(4)) {
    GTEST_SKIP() << "the two starts took >= 4 s (machine overloaded): the first session may be measured already";
  }
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
}

// The nice values of the server's threads (field 19 of /proc/PID/task/TID/stat).
std::vector<int> ThreadNiceValues(pid_t pid) {
  std::vector<int> out;
  for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(pid) + "/task")) {
    std::string stat = Slurp(task.path() / "stat");
    const auto close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    std::string field;
    for (int i = 3; i <= 19 && rest >> field; ++i) {
      if (i == 19) out.push_back(std::stoi(field));
    }
  }
  return out;
}

// The overload policy: a batch session's threads (its pipeline thread and
// its decode helper) run at nice +10, a paced one's at the server's own
// priority.
TEST(KeepingRealTime, BatchSessionsRunAtLowerPriority) {
  const ScopedTempDir dir("realtime_nice");
  const fs::path drive = SmallDrive(dir.path() / "drive", 40);
  ASSERT_FALSE(drive.empty());
  ServerProcess server(dir.path() / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  const pid_t pid = server.process().pid();
  const auto count = [&](int nice) {
    const auto v = ThreadNiceValues(pid);
    return std::count(v.begin(), v.end(), nice);
  };
  // The server inherits this test's nice (e.g. a run under `nice -n 10`);
  // batch threads go kBatchNice above it.
  const std::vector<int> before = ThreadNiceValues(pid);
  ASSERT_FALSE(before.empty());
  const int base = *std::min_element(before.begin(), before.end());
  if (base >= 19) GTEST_SKIP() << "the server already runs at nice 19: nothing lower to see";
  const int batch_nice = std::min(19, base + kBatchNice);
  ASSERT_EQ(count(batch_nice), 0) << "no session yet";
  v1::Session paced, batch;
  ASSERT_TRUE(Start(stub.get(), PacedKitti(drive, 0.5), &paced).ok());  // 40 frames at half speed: 8 s
  std::this_thread::sleep_for(milliseconds(300));
  EXPECT_EQ(count(batch_nice), 0) << "a paced session runs at the server's priority";
  // A batch session ends as soon as it has run its frames; its thread is
  // seen at nice +10 while it runs (or the session is already over).
  ASSERT_TRUE(Start(stub.get(), PacedKitti(drive, 0), &batch).ok());
  bool seen = false;
  for (int i = 0; i < 2000 && !seen; ++i) {
    seen = count(batch_nice) == 2;
    if (!seen && GetSession(stub.get(), batch.id()).state() == v1::SESSION_STATE_FINISHED) break;
  }
  EXPECT_TRUE(seen) << "not two threads at nice " << batch_nice << " (server at " << base
                    << ") while the batch session ran";
  EXPECT_EQ(GetSession(stub.get(), paced.id()).state(), v1::SESSION_STATE_RUNNING);
}

TEST(KeepingRealTime, BadValuesAreRefusedAtStartNamingTheSetting) {
  const ScopedTempDir dir("realtime_config");
  for (const auto& [flag, value] : std::vector<std::pair<std::string, std::string>>{
           {"--max-cpu-cores", "-1"}, {"--behind-threshold-s", "0"}, {"--session-cpu-cores-prior", "100"}}) {
    const std::string setting = flag.substr(2);
    const CliResult r = RunShell("timeout 20 " + std::string(LOCAID_BIN_DIR) + "/locaid-server --listen 127.0.0.1:0 " + flag + " " +
                                 value);
    EXPECT_NE(r.exit_code, 0) << flag;
    std::string key = setting;
    for (char& c : key) c = c == '-' ? '_' : c;
    EXPECT_NE(r.err.find(key + ": must be"), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace locaid::server::testing
