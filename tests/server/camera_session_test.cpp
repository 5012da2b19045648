// Live sessions whose stereo cameras the server reads itself through
// GStreamer (LiveSource.cameras), end to end as a user runs them: the real
// locaid-server, the real `locaid session start --live` flags, camera_info
// files written by clients/kitti_camera_info.py from the real excerpt's
// calibration, and multifilesrc playing the excerpt's raw images at 10 Hz in
// place of cameras (no hardware). Runs when ../shared is there.
#include "test_support.hpp"

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

const fs::path kDate = fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26";
const fs::path kDrive = kDate / "2011_09_26_drive_unknown_extract";
// Frames 24.. : the excerpt lacks left frame 23 and right frame 22, and
// multifilesrc ends at a missing file.
constexpr int kFirst = 24;

// A camera: the excerpt's raw images of one side, `frames` of them at `fps`.
std::string Play(const std::string& side, int frames, int fps = 10, bool loop = false) {
  return "multifilesrc location=" + (kDrive / side / "data/%010d.png").string() + " index=" +
         std::to_string(kFirst) + " stop-index=" + std::to_string(kFirst + frames - 1) +
         (loop ? " loop=true" : "") + " caps=image/png,framerate=" + std::to_string(fps) + "/1 ! pngdec";
}

class CameraSession : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kDrive / "image_00")) GTEST_SKIP() << "shared real KITTI excerpt absent: " << kDrive;
    const auto r = RunShell("python3 " + ShellQuote(std::string(LOCAID_SOURCE_DIR) + "/clients/kitti_camera_info.py") +
                            " " + ShellQuote((kDate / "calib_cam_to_cam.txt").string()) + " " +
                            ShellQuote(dir_.path().string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    server_ = std::make_unique<ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
  }

  // `locaid session start --live ...`: the session id, or "" with `error`.
  std::string Start(const std::vector<std::string>& camera_flags, std::string* error = nullptr,
                    const std::string& left_info = "", const std::string& right_info = "") {
    std::vector<std::string> args = {"session", "start", "--live"};
    args.insert(args.end(), camera_flags.begin(), camera_flags.end());
    args.insert(args.end(), {"--camera-info-left", left_info.empty() ? (dir_ / "left.yaml").string() : left_info,
                             "--camera-info-right", right_info.empty() ? (dir_ / "right.yaml").string() : right_info});
    const CliResult r = RunCli(server_->port(), args);
    if (error) *error = r.err;
    if (r.exit_code != 0) return "";
    std::string id = r.out;
    id.erase(std::remove(id.begin(), id.end(), '\n'), id.end());
    return id;
  }

  std::unique_ptr<v1::Localization::Stub> Stub() { return v1::Localization::NewStub(server_->NewChannel()); }

  ScopedTempDir dir_{"camera_session"};
  std::unique_ptr<ServerProcess> server_;
};

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
  const std::string id = Start({"--vo", "thesis", "--camera-left", Play("image_00", 60, 100, true), "--camera-right",
                                Play("image_01", 60, 100, true)});
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

}  // namespace
}  // namespace locaid::server::testing
