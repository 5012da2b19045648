// Learned noise through the real server (PoseUpdate.noise, SessionStats.noise,
// StartSessionRequest.noise): a receiver that states a third of its noise is
// found, and the fixed models stay fixed when a client asks for them.
#include "test_support.hpp"

#include <chrono>
#include <cmath>
#include <map>
#include <thread>
#include <filesystem>
#include <fstream>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr char kOverconfidentReceiver[] =
    "name: overconfident\ngps: {rate_hz: 10, sigma_h_m: 3.0, sigma_v_m: 5.0, stated_sigma_scale: 0.3333333333}\n";

std::vector<v1::PoseUpdate> RunSession(v1::Localization::Stub* stub, ServerProcess& server, const fs::path& drive,
                                       bool fixed, v1::SessionStats* stats) {
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  req.set_playback_rate(0);
  req.mutable_scenario()->set_yaml(kOverconfidentReceiver);
  req.mutable_noise()->set_fixed_vo_noise(fixed);
  req.mutable_noise()->set_fixed_gps_noise(fixed);
  v1::Session session;
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 30);
  const grpc::Status st = stub->StartSession(&ctx, req, &session);
  EXPECT_TRUE(st.ok()) << st.error_message();
  if (!st.ok()) return {};
  PoseCollector collector(server.NewChannel(1), session.id(), true);
  EXPECT_TRUE(collector.WaitDone(180)) << "the session did not end";
  *stats = GetStats(stub, session.id());
  return collector.poses();
}

TEST(NoiseLearningSession, PosesAndStatsShowTheLearnedNoiseAndFixedStaysFixed) {
  constexpr int kFrames = 200;  // 20 s at 10 Hz, fixes at 10 Hz
  const ScopedTempDir dir("noise_learning_session");  // outlives the server
  ServerProcess server(dir.path() / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  std::string error;
  const fs::path drive = RenderSynthDrive(dir.path() / "drive", kFrames, 4, 320, 96, &error);
  ASSERT_FALSE(drive.empty()) << error;

  v1::SessionStats learned_stats, fixed_stats;
  const auto learned = RunSession(stub.get(), server, drive, false, &learned_stats);
  const auto fixed = RunSession(stub.get(), server, drive, true, &fixed_stats);
  ASSERT_EQ(learned.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(fixed.size(), static_cast<size_t>(kFrames));

  const v1::NoiseLearning& last = learned.back().noise();
  ASSERT_EQ(last.vo_scale_size(), 6);
  for (double v : last.vo_scale()) EXPECT_GE(v, 1.0) << "never below the model";
  // True 9; 15 s of 10 Hz fixes after initialisation.
  EXPECT_GT(last.gps_horizontal_scale(), 4.0);
  EXPECT_LT(last.gps_horizontal_scale(), 20.0);
  EXPECT_TRUE(last.vo_learning()) << "GPS holds the state at the end";
  EXPECT_EQ(learned_stats.noise().gps_horizontal_scale(), last.gps_horizontal_scale()) << "GetStats: the newest pose";
  EXPECT_EQ(learned_stats.noise().vo_scale_size(), 6);

  for (const v1::PoseUpdate& p : fixed) {
    ASSERT_EQ(p.noise().vo_scale_size(), 6);
    for (double v : p.noise().vo_scale()) EXPECT_EQ(v, 1.0) << "frame " << p.frame_index();
    EXPECT_EQ(p.noise().gps_horizontal_scale(), 1.0);
    EXPECT_EQ(p.noise().gps_vertical_scale(), 1.0);
    EXPECT_FALSE(p.noise().vo_learning());
  }
  EXPECT_EQ(fixed_stats.noise().gps_horizontal_scale(), 1.0);
  // The fixes it believes are refused and reset to, where the learned filter takes them.
  EXPECT_GT(fixed.back().gps_rejected(), learned.back().gps_rejected());
}

// The CLI a user types: `locaid session start ... --fixed-gps-noise`, then
// `locaid stats` prints the learned (here: fixed) noise.
TEST(NoiseLearningSession, TheCliStartsFixedSessionsAndStatsPrintsTheNoise) {
  const ScopedTempDir dir("noise_learning_cli");
  ServerProcess server(dir.path() / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  std::string error;
  const fs::path drive = RenderSynthDrive(dir.path() / "drive", 120, 4, 320, 96, &error);
  ASSERT_FALSE(drive.empty()) << error;
  const fs::path scenario = dir.path() / "overconfident.yaml";
  std::ofstream(scenario) << kOverconfidentReceiver;
  auto stub = v1::Localization::NewStub(server.NewChannel());
  std::map<std::string, std::string> printed;
  for (const std::string flag : {"", "--fixed-gps-noise"}) {
    std::vector<std::string> args = {"session", "start", "--kitti", drive.string(), "--scenario", scenario.string()};
    if (!flag.empty()) args.push_back(flag);
    const CliResult r = RunCli(server.port(), args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string id = r.out.substr(0, r.out.find('\n'));
    for (int i = 0; i < 600 && GetSession(stub.get(), id).state() != v1::SESSION_STATE_FINISHED; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const CliResult stats = RunCli(server.port(), {"stats", id});
    ASSERT_EQ(stats.exit_code, 0) << stats.err;
    const auto at = stats.out.find("noise vo_scale=");
    ASSERT_NE(at, std::string::npos) << stats.out;
    printed[flag] = stats.out.substr(at, stats.out.find('\n', at) - at);
  }
  EXPECT_NE(printed["--fixed-gps-noise"].find("gps_horizontal_scale=1 gps_vertical_scale=1 "), std::string::npos)
      << printed["--fixed-gps-noise"];
  EXPECT_EQ(printed[""].find("gps_horizontal_scale=1 "), std::string::npos) << "learned: " << printed[""];
}

}  // namespace
}  // namespace locaid::server::testing
