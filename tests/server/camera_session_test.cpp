// Live sessions whose stereo cameras the server reads itself through
// GStreamer (LiveSource.cameras), end to end as a user runs them: the real
// locaid-server, the real `locaid session start --live` flags, camera_info
// files written by clients/kitti_camera_info.py from the real excerpt's
// calibration, and multifilesrc playing the excerpt's raw images at 10 Hz in
// place of cameras (no hardware). Runs when ../shared is there.
#include "camera_test_support.hpp"

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

namespace locaid::server::testing {
namespace {

size_t CountHealth(const std::vector<v1::PoseUpdate>& poses, v1::VoHealth h) {
  return static_cast<size_t>(std::count_if(poses.begin(), poses.end(), [&](const auto& p) { return p.vo_health() == h; }));
}

double MeanInliers(const std::vector<v1::PoseUpdate>& poses) {
  double sum = 0;
  size_t n = 0;
  for (const auto& p : poses)
    if (p.vo_health() == v1::VO_HEALTH_TRACKING) sum += p.vo_inliers(), ++n;
  return n ? sum / static_cast<double>(n) : 0;
}

// Two pipelines, one per camera: the rectified pairs reach VO at the
// cameras' rate, stamped from their PTS; at the end of the stream the poses
// say NO_IMAGES within 1 s and keep coming, the camera is restarted (a
// second play) and VO tracks again.
TEST_F(CameraSession, TwoPipelinesTrackEndAndComeBack) {
  constexpr int kFrames = 30;
  const std::string id = Start({"--camera-left", Play("image_00", kFrames), "--camera-right", Play("image_01", kFrames)});
  ASSERT_FALSE(id.empty()) << server_->log();
  PoseCollector poses(server_->NewChannel(1), id, /*from_start=*/true);
  auto stub = Stub();
  // The first play, the end, a restart after 0.5 s and part of the second play.
  const auto stats = WaitStats(stub.get(), id, 60, [](const v1::SessionStats& s) {
    return s.camera().restarts() >= 1 && s.camera().pairs() >= kFrames + 10;
  });
  ASSERT_GE(stats.camera().restarts(), 1u) << stats.DebugString();
  const std::string& why = stats.camera().last_error();
  EXPECT_TRUE(why == "left camera: end of stream" || why == "right camera: end of stream") << why;
  EXPECT_LE(stats.camera().unpaired(), 2u);
  const auto all = poses.poses();
  ASSERT_GT(all.size(), static_cast<size_t>(kFrames));

  // The first play: tracked, 100 ms apart (the PTS, not the arrival times).
  size_t first_no_images = 0;
  while (first_no_images < all.size() && all[first_no_images].vo_health() != v1::VO_HEALTH_NO_IMAGES) ++first_no_images;
  ASSERT_LT(first_no_images, all.size()) << "the end of the stream shows as NO_IMAGES";
  const std::vector<v1::PoseUpdate> play(all.begin(), all.begin() + static_cast<long>(first_no_images));
  EXPECT_GE(play.size(), static_cast<size_t>(kFrames - 2));
  EXPECT_GE(CountHealth(play, v1::VO_HEALTH_TRACKING), play.size() - 2) << "first frame and at most one more";
  EXPECT_GT(MeanInliers(play), 50.0);
  for (size_t i = 1; i < play.size(); ++i) {
    const int64_t step = play[i].t_ns() - play[i - 1].t_ns();
    EXPECT_NEAR(static_cast<double>(step), 1e8, 1e6) << "pose " << i;
  }
  // The end: NO_IMAGES within 1 s, poses go on (mode and all), then tracking again.
  EXPECT_LE(all[first_no_images].t_ns() - play.back().t_ns(), 1'000'000'000);
  const auto back = std::find_if(all.begin() + static_cast<long>(first_no_images), all.end(),
                                 [](const auto& p) { return p.vo_health() == v1::VO_HEALTH_TRACKING; });
  ASSERT_NE(back, all.end()) << "VO tracks again after the restart";
  EXPECT_GE(back - (all.begin() + static_cast<long>(first_no_images)), 2) << "NO_IMAGES ticks while the camera was down";
  EXPECT_FALSE(poses.done()) << "a camera's end does not end the session";
}

// One pipeline whose two appsinks are named left and right gives VO the
// same pairs as two pipelines.
TEST_F(CameraSession, OneStereoPipelineWithTwoNamedAppsinks) {
  constexpr int kFrames = 30;
  const std::string stereo = Play("image_00", kFrames) + " ! videoconvert ! appsink name=left " +
                             Play("image_01", kFrames) + " ! videoconvert ! appsink name=right";
  const std::string id = Start({"--camera-stereo", stereo});
  ASSERT_FALSE(id.empty()) << server_->log();
  PoseCollector poses(server_->NewChannel(1), id, /*from_start=*/true);
  ASSERT_TRUE(poses.WaitPoses(kFrames - 2, 30)) << poses.count();
  const auto play = poses.poses();
  EXPECT_GE(CountHealth(play, v1::VO_HEALTH_TRACKING), static_cast<size_t>(kFrames - 4));
  EXPECT_GT(MeanInliers(play), 50.0);
  const auto stats = GetStats(Stub().get(), id);
  EXPECT_GE(stats.camera().pairs(), static_cast<uint64_t>(kFrames - 2));
  EXPECT_EQ(stats.camera().unpaired(), 0u);
}

// A camera that cannot start, or whose calibration does not fit it, is
// refused before the session exists, naming the camera and the reason.
TEST_F(CameraSession, CamerasThatCannotStartAreRefusedByName) {
  const std::string good = Play("image_01", 5);
  struct Case {
    std::vector<std::string> flags;
    std::string status, message;
  };
  const std::vector<Case> cases = {
      {{"--camera-left", "multifilesrc ! ! pngdec", "--camera-right", good},
       "INVALID_ARGUMENT", "live.cameras: left camera: bad pipeline description: "},
      {{"--camera-left", Play("image_00", 5), "--camera-right", "nosuchcamerasrc"},
       "INVALID_ARGUMENT", "nosuchcamerasrc"},
      {{"--camera-left", "v4l2src device=/dev/locaid-no-such-video", "--camera-right", good},
       "FAILED_PRECONDITION", "live.cameras: left camera: cannot start: "},
      {{"--camera-stereo", Play("image_00", 5) + " ! videoconvert ! appsink name=left"},
       "INVALID_ARGUMENT", "live.cameras: stereo camera: no appsink named 'right'"},
      {{"--camera-left", good}, "INVALID_ARGUMENT", "live.cameras.right_pipeline: missing"},
  };
  std::string usage;
  EXPECT_EQ(Start({"--camera-left", good, "--camera-right", good, "--gpsd", "127.0.0.1:gps"}, &usage), "");
  EXPECT_EQ(usage, "error: --gpsd '127.0.0.1:gps': expected HOST:PORT\n") << "a usage error, before any call";
  for (const auto& c : cases) {
    std::string error;
    EXPECT_EQ(Start(c.flags, &error), "") << c.flags[1];
    EXPECT_NE(error.find("error: " + c.status + ": "), std::string::npos) << error;
    EXPECT_NE(error.find(c.message), std::string::npos) << error;
  }
  // camera_info files of another size than the cameras' frames.
  for (const std::string side : {"left", "right"}) {
    std::string yaml = Slurp(dir_ / (side + ".yaml"));
    yaml.replace(yaml.find("image_width: 1392"), 17, "image_width: 1242");
    std::ofstream(dir_ / ("small_" + side + ".yaml")) << yaml;
  }
  std::string error;
  EXPECT_EQ(Start({"--camera-left", Play("image_00", 5), "--camera-right", good}, &error,
                  (dir_ / "small_left.yaml").string(), (dir_ / "small_right.yaml").string()),
            "");
  EXPECT_NE(error.find("INVALID_ARGUMENT: live.cameras: left camera: frames are 1392x512 px, its camera_info "
                       "says 1242x512 px"),
            std::string::npos)
      << error;
  // A camera_info that is not one.
  std::ofstream(dir_ / "bad.yaml") << "image_width: 1392\n";
  EXPECT_EQ(Start({"--camera-left", good, "--camera-right", good}, &error, (dir_ / "bad.yaml").string()), "");
  EXPECT_NE(error.find("INVALID_ARGUMENT: live.cameras.left_camera_info: image_height: missing"), std::string::npos)
      << error;
  // Two calibrations that are not one stereo pair.
  EXPECT_EQ(Start({"--camera-left", good, "--camera-right", good}, &error, (dir_ / "small_left.yaml").string()), "");
  EXPECT_NE(error.find("INVALID_ARGUMENT: live.cameras: left and right camera_info sizes differ"), std::string::npos)
      << error;
  v1::ListSessionsResponse list;
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  ASSERT_TRUE(Stub()->ListSessions(&ctx, v1::ListSessionsRequest(), &list).ok());
  EXPECT_EQ(list.sessions_size(), 0) << "no session was started";
}

// Cameras far faster than the session can take (100 Hz into the thesis VO):
// the late pairs are dropped and counted, never queued; the server's memory
// stays level.
TEST_F(CameraSession, CamerasFasterThanTheSessionAreDroppedAndCounted) {
  const std::string id = Start({"--vo", "thesis", "--camera-left", Play("image_00", 60, "100/1", true), "--camera-right",
                                Play("image_01", 60, "100/1", true)});
  ASSERT_FALSE(id.empty()) << server_->log();
  auto stub = Stub();
  const auto early = WaitStats(stub.get(), id, 30, [](const v1::SessionStats& s) { return s.camera().pairs() >= 20; });
  const long rss_early = VmRssKb(server_->process().pid());
  const auto later = WaitStats(stub.get(), id, 60, [&](const v1::SessionStats& s) {
    return s.camera().pairs() >= early.camera().pairs() + 60;
  });
  const long rss_later = VmRssKb(server_->process().pid());
  EXPECT_GT(later.camera().dropped_late(), 0u) << later.DebugString();
  EXPECT_GE(later.camera().pairs(), early.camera().pairs() + 60);
  EXPECT_LT(rss_later - rss_early, 64 * 1024) << "kB: a bounded queue, not a growing one";
}

// A car that boots into localisation: the server's YAML names the cameras
// (`live_cameras`, the keys of `locaid session start --live`) and the server
// starts the session itself; a camera that is not there yet is retried
// while the server serves, and said in its log.
TEST_F(CameraSession, TheServersYamlStartsACameraSessionAtBoot) {
  const fs::path yaml = dir_ / "server.yaml";
  std::ofstream(yaml) << "live_cameras:\n"
                      << "  left_pipeline: \"" << Play("image_00", 60) << "\"\n"
                      << "  right_pipeline: \"" << Play("image_01", 60) << "\"\n"
                      << "  left_camera_info: " << (dir_ / "left.yaml").string() << "\n"
                      << "  right_camera_info: " << (dir_ / "right.yaml").string() << "\n";
  ServerProcess booted(dir_ / "booted", {"--config", yaml.string()});
  ASSERT_GT(booted.port(), 0) << booted.log();
  auto stub = v1::Localization::NewStub(booted.NewChannel());
  v1::ListSessionsResponse list;
  for (int i = 0; i < 300 && list.sessions_size() == 0; ++i) {  // at most 30 s
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    ASSERT_TRUE(stub->ListSessions(&ctx, v1::ListSessionsRequest(), &list).ok());
    if (list.sessions_size() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(list.sessions_size(), 1) << booted.log();
  EXPECT_EQ(list.sessions(0).source(), "live+cameras");
  PoseCollector poses(booted.NewChannel(1), list.sessions(0).id(), /*from_start=*/true);
  ASSERT_TRUE(poses.WaitPoses(20, 30)) << poses.count();
  EXPECT_GE(CountHealth(poses.poses(), v1::VO_HEALTH_TRACKING), 15u);
  EXPECT_NE(booted.log().find("live camera session " + list.sessions(0).id() + " started (live_cameras)"),
            std::string::npos)
      << booted.log();
  // No IMU pushed and no `no_imu: true`: after 50 frames the stats say so.
  ASSERT_TRUE(poses.WaitPoses(52, 30)) << poses.count();
  EXPECT_EQ(GetStats(stub.get(), list.sessions(0).id()).last_input_error(),
            "50 frames and no IMU sample: the filter is IMU-driven and drifts fast without one; a car without IMU "
            "starts its session with live.no_imu");

  // Cameras that are not there: the server serves, logs why, and starts nothing yet.
  const fs::path absent = dir_ / "absent.yaml";
  std::ofstream(absent) << "live_cameras:\n"
                        << "  left_pipeline: \"v4l2src device=/dev/locaid-no-such-video\"\n"
                        << "  right_pipeline: \"v4l2src device=/dev/locaid-no-such-video\"\n"
                        << "  left_camera_info: " << (dir_ / "left.yaml").string() << "\n"
                        << "  right_camera_info: " << (dir_ / "right.yaml").string() << "\n";
  ServerProcess waiting(dir_ / "waiting", {"--config", absent.string()});
  ASSERT_GT(waiting.port(), 0) << waiting.log();
  for (int i = 0; i < 100 && waiting.log().find("cannot start yet") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_NE(waiting.log().find("live_cameras: cannot start yet, retrying every 5 s: live.cameras: left camera: "
                               "cannot start: "),
            std::string::npos)
      << waiting.log();
  EXPECT_EQ(RunCli(waiting.port(), {"health"}).out, "SERVING\n");

  // A YAML with a malformed gpsd, or without camera_info, is a config error: the server does not start.
  const fs::path bad_gpsd = dir_ / "bad_gpsd.yaml";
  std::ofstream(bad_gpsd) << Slurp(yaml) << "  gpsd: localhost:twenty\n";
  const CliResult g = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-server") +
                               " --listen 127.0.0.1:0 --config " + ShellQuote(bad_gpsd.string()));
  EXPECT_EQ(g.exit_code, 2);
  EXPECT_NE(g.err.find("key 'live_cameras': live_cameras.gpsd 'localhost:twenty': expected HOST:PORT"),
            std::string::npos)
      << g.err;
  const fs::path bad = dir_ / "bad.yaml";
  std::ofstream(bad) << "live_cameras:\n  left_pipeline: videotestsrc\n  right_pipeline: videotestsrc\n";
  const CliResult r = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-server") + " --listen 127.0.0.1:0 "
                               "--config " + ShellQuote(bad.string()));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("live_cameras: left_camera_info and right_camera_info are required"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace locaid::server::testing
