// GstCapture on real GStreamer pipelines, no hardware: videotestsrc and
// multifilesrc stand in for cameras (a file played with sync=true arrives at
// its frame rate, as a camera's frames do). What a user meets: a bad
// description, a missing element or appsink, a device that is not there,
// each named with GStreamer's own message; frames with their PTS on the
// clock; a stereo pipeline's two named appsinks; a camera that errors in the
// middle; a restart after the end; the real excerpt's raw images.
#include "sensors/gst_camera.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using locaid::sensors::CameraFrame;
using locaid::sensors::GstCapture;
using locaid::sensors::PullResult;

constexpr int64_t kSecond = 1'000'000'000;
constexpr int64_t kFrameNs = 100'000'000;  // 10 Hz

// A 10 Hz test pattern of `frames` frames, w x h.
std::string TestPattern(int frames, int w = 64, int h = 48) {
  return "videotestsrc num-buffers=" + std::to_string(frames) + " ! video/x-raw,width=" + std::to_string(w) +
         ",height=" + std::to_string(h) + ",framerate=10/1";
}

// Pulls until the end (or a failure), at most `limit` frames.
std::vector<CameraFrame> PullAll(GstCapture& c, size_t sink, PullResult& last, std::string& why, size_t limit = 50) {
  std::vector<CameraFrame> frames;
  for (;;) {
    CameraFrame f;
    last = c.Pull(sink, 5 * kSecond, f, why);
    if (last != PullResult::kFrame || frames.size() >= limit) return frames;
    frames.push_back(f);
  }
}

// Starts the capture and pulls its one sink to the end of the stream.
std::vector<CameraFrame> PlayToTheEnd(GstCapture& c) {
  EXPECT_EQ(c.Start(), "");
  PullResult last{};
  std::string why;
  auto frames = PullAll(c, 0, last, why);
  EXPECT_EQ(last, PullResult::kEnded) << why;
  return frames;
}

TEST(GstCapture, ABadDescriptionIsNamedWithGStreamersMessage) {
  GstCapture bad("left camera", "videotestsrc ! ! fakesink");
  const std::string why = bad.Start();
  EXPECT_EQ(why.rfind("left camera: bad pipeline description: ", 0), 0u) << why;
  EXPECT_FALSE(bad.running());
  EXPECT_TRUE(bad.description_error());

  GstCapture missing("right camera", "nosuchcamerasrc device=/dev/video0");
  const std::string missing_why = missing.Start();
  EXPECT_EQ(missing_why.rfind("right camera: bad pipeline description: ", 0), 0u) << missing_why;
  EXPECT_NE(missing_why.find("nosuchcamerasrc"), std::string::npos) << "GStreamer names the element: " << missing_why;

  GstCapture empty("left camera", "  ");
  EXPECT_EQ(empty.Start(), "left camera: empty pipeline description");
}

TEST(GstCapture, AMissingAppsinkIsNamed) {
  GstCapture c("stereo camera", TestPattern(3) + " ! videoconvert ! appsink name=left", {"left", "right"});
  EXPECT_EQ(c.Start(), "stereo camera: no appsink named 'right': the description must end that camera in "
                       "appsink name=right");
  EXPECT_TRUE(c.description_error());
}

TEST(GstCapture, ADeviceThatIsNotThereFailsToStartWithItsMessage) {
  GstCapture c("left camera", "v4l2src device=/dev/locaid-no-such-video");
  const std::string why = c.Start();
  EXPECT_EQ(why.rfind("left camera: cannot start: ", 0), 0u) << why;
  EXPECT_NE(why.find("locaid-no-such-video"), std::string::npos) << "v4l2src names the device: " << why;
  EXPECT_FALSE(c.running());
  EXPECT_FALSE(c.description_error()) << "the description is fine; the device is not there";
}

TEST(GstCapture, FramesArriveAtTheirRateStampedWithTheirPts) {
  GstCapture c("left camera", TestPattern(8));
  const auto frames = PlayToTheEnd(c);
  ASSERT_EQ(frames.size(), 8u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].gray.type(), CV_8UC1);
    EXPECT_EQ(frames[i].gray.cols, 64);
    EXPECT_EQ(frames[i].gray.rows, 48);
    EXPECT_EQ(frames[i].sequence, i + 1);
    if (i > 0) {
      EXPECT_EQ(frames[i].clock_ns - frames[i - 1].clock_ns, kFrameNs) << "PTS, not arrival time";
    }
  }
  // The stamps are on the clock ClockNowNs() reads: played with sync, the
  // last frame was due before the end was seen, and not long before.
  const int64_t now = locaid::sensors::ClockNowNs();
  EXPECT_LE(frames.back().clock_ns, now);
  EXPECT_GT(frames.back().clock_ns, now - 5 * kSecond);
}

TEST(GstCapture, AStereoPipelineGivesBothNamedSinksTheSameStamps) {
  GstCapture c("stereo camera",
               TestPattern(5, 32, 24) +
                   " ! tee name=t t. ! queue ! videoconvert ! appsink name=left t. ! queue ! videoconvert ! "
                   "appsink name=right",
               {"left", "right"});
  ASSERT_EQ(c.Start(), "");
  EXPECT_EQ(c.sink_count(), 2u);
  // Pulled in turn, as a consumer does: a sink left unread keeps its newest
  // 4 frames only (bounded), so pulling one side to the end first would lose one.
  std::vector<CameraFrame> left, right;
  std::string why;
  for (;;) {
    CameraFrame l, r;
    const PullResult a = c.Pull(0, 5 * kSecond, l, why), b = c.Pull(1, 5 * kSecond, r, why);
    if (a != PullResult::kFrame || b != PullResult::kFrame) break;
    left.push_back(l);
    right.push_back(r);
  }
  ASSERT_EQ(left.size(), 5u) << why;
  ASSERT_EQ(right.size(), 5u) << why;
  for (size_t i = 0; i < left.size(); ++i) EXPECT_EQ(left[i].clock_ns, right[i].clock_ns);
}

TEST(GstCapture, ACameraThatErrorsMidStreamIsFailedWithGStreamersMessage) {
  // identity error-after=4: the stream breaks at its 4th buffer, as an
  // unplugged camera's does.
  GstCapture c("left camera", TestPattern(10) + " ! identity error-after=4");
  ASSERT_EQ(c.Start(), "");
  PullResult last{};
  std::string why;
  const auto frames = PullAll(c, 0, last, why);
  EXPECT_LE(frames.size(), 3u);
  EXPECT_EQ(last, PullResult::kFailed);
  EXPECT_EQ(why.rfind("left camera: identity", 0), 0u) << "the element, then its message: " << why;
}

TEST(GstCapture, ARestartAfterTheEndPlaysAgainAndCountsOn) {
  const locaid::test_support::ScopedTempDir dir("gst_camera_restart");
  const cv::Mat image(24, 32, CV_8UC1, cv::Scalar(90));
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(cv::imwrite((dir.path() / (std::to_string(i) + ".png")).string(), image));
  GstCapture c("left camera", "multifilesrc location=" + (dir.path() / "%d.png").string() +
                                  " index=0 stop-index=2 caps=image/png,framerate=10/1 ! pngdec");
  EXPECT_EQ(PlayToTheEnd(c).size(), 3u);
  ASSERT_EQ(c.Start(), "") << "restart after the end";
  CameraFrame f;
  std::string why;
  ASSERT_EQ(c.Pull(0, 5 * kSecond, f, why), PullResult::kFrame) << why;
  EXPECT_EQ(f.sequence, 4u) << "the sequence counts on across a restart";
  EXPECT_EQ(cv::countNonZero(f.gray != 90), 0);
}

TEST(GstCapture, TheRealExcerptsRawImagesArriveUnchanged) {
  const fs::path images =
      fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/2011_09_26_drive_unknown_extract/image_00/data";
  if (!fs::exists(images)) GTEST_SKIP() << "shared real KITTI excerpt absent: " << images;
  GstCapture c("left camera", "multifilesrc location=" + (images / "%010d.png").string() +
                                  " index=0 stop-index=4 caps=image/png,framerate=10/1 ! pngdec");
  const auto frames = PlayToTheEnd(c);
  ASSERT_EQ(frames.size(), 5u);
  for (size_t i = 0; i < frames.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%010zu.png", i);
    const cv::Mat expected = cv::imread((images / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(frames[i].gray.size(), expected.size());
    EXPECT_EQ(cv::countNonZero(frames[i].gray != expected), 0) << name;
    if (i > 0) {
      EXPECT_EQ(frames[i].clock_ns - frames[i - 1].clock_ns, kFrameNs);
    }
  }
}

}  // namespace
