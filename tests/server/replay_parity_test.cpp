// One frame loop (pipeline/frame_loop.hpp) serves the service and
// locaid-replay: a drive played by a real server session gives the poses
// locaid-replay computes offline for the same drive and scenario, frame for
// frame, including a frame the drive lacks an image of.
#include "test_support.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

TEST(ReplayParity, AServerSessionStreamsThePosesLocaidReplayComputes) {
  const ScopedTempDir dir("replay_parity");
  std::string error;
  const fs::path drive = RenderSynthDrive(dir / "drive", 40, 5, 320, 96, &error);
  ASSERT_FALSE(drive.empty()) << error;
  fs::remove(drive / "image_01" / "data" / "0000000012.png");  // frame 12: skipped by both

  // Offline.
  const fs::path tum = dir / "replay.tum";
  const CliResult replay = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-replay") + " --drive " +
                                    ShellQuote(drive.string()) + " --scenario open-sky --json --out-tum " +
                                    ShellQuote(tum.string()));
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_NE(replay.err.find("frame 12: left or right image missing"), std::string::npos) << replay.err;
  std::map<long long, Eigen::Vector3d> offline;  // by TUM time, microseconds
  {
    std::ifstream in(tum);
    double t = 0, x = 0, y = 0, z = 0, qx = 0, qy = 0, qz = 0, qw = 0;
    while (in >> t >> x >> y >> z >> qx >> qy >> qz >> qw) offline[std::llround(t * 1e6)] = {x, y, z};
  }
  ASSERT_GT(offline.size(), 20u) << replay.out;

  // The same drive through a session of the real server.
  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  req.mutable_scenario()->set_name("open-sky");
  req.set_history_size(100);
  v1::Session session;
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  ASSERT_TRUE(stub->StartSession(&ctx, req, &session).ok());
  PoseCollector collector(server.NewChannel(1), session.id(), /*from_start=*/true);
  ASSERT_TRUE(collector.WaitDone(120));
  const auto poses = collector.poses();
  ASSERT_EQ(poses.size(), 39u);  // 40 frames, one skipped
  EXPECT_NE(replay.out.find("\"frames\": 39"), std::string::npos) << replay.out;

  // TUM time: seconds since the drive's first frame; every initialised pose
  // is in the file (6 decimals).
  const int64_t t0_ns = poses.front().t_ns();
  size_t compared = 0;
  for (const auto& p : poses) {
    EXPECT_NE(p.frame_index(), 12);
    const auto it = offline.find(std::llround(static_cast<double>(p.t_ns() - t0_ns) * 1e-3));
    if (it == offline.end()) continue;  // before the filter's start-up
    ++compared;
    EXPECT_NEAR(p.position_enu_m().x(), it->second.x(), 1e-6) << "frame " << p.frame_index();
    EXPECT_NEAR(p.position_enu_m().y(), it->second.y(), 1e-6) << "frame " << p.frame_index();
    EXPECT_NEAR(p.position_enu_m().z(), it->second.z(), 1e-6) << "frame " << p.frame_index();
  }
  EXPECT_EQ(compared, offline.size());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace locaid::server::testing
