// The frame loop without a network: what reaches the estimator and when
// (skipped frames, typed data between frames, outage controls on the drive
// clock through the scenario stage, ground truth), over scripted items, a
// rendered drive and a live source.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include "kitti/dataset.hpp"
#include "kitti/raw_drive.hpp"
#include "pipeline/frame_loop.hpp"
#include "pipeline/live_frame_source.hpp"
#include "pipeline/oxts_adapter.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace locaid::pipeline {
namespace {

namespace fs = std::filesystem;

// Records what the loop asks of it: "fuse I G" (IMU samples, fixes) and
// "process T". Each fix comes back as a used feed with the next pose.
class RecordingEstimator : public Estimator {
 public:
  struct Log {
    std::vector<std::string> calls;
    std::vector<int64_t> frame_t_ns;
    std::vector<bool> had_left, had_right;  // the images each processed frame had
    size_t imu_samples = 0;
    fusion::EnuFrame enu;  // the test sets its origin
  };
  explicit RecordingEstimator(std::shared_ptr<Log> log) : log_(std::move(log)) {}

  void Fuse(const Measurements& m) override {
    log_->calls.push_back("fuse " + std::to_string(m.imu.size()) + " " + std::to_string(m.gps.size()));
    log_->imu_samples += m.imu.size();
    for (const auto& f : m.gps) {
      GpsFeed feed;
      feed.fix = f;
      feed.update.used = true;
      feeds_.push_back(feed);
    }
  }
  FrameResult Process(const vo::StereoFrame& frame) override {
    log_->calls.push_back("process " + std::to_string(frame.t_ns));
    log_->frame_t_ns.push_back(frame.t_ns);
    log_->had_left.push_back(!frame.left.empty());
    log_->had_right.push_back(!frame.right.empty());
    FrameResult r;
    r.pose.t_ns = frame.t_ns;
    r.vo.status = vo::Status::kOk;
    r.gps_feeds = std::exchange(feeds_, {});
    return r;
  }
  const fusion::EnuFrame& enu() const override { return log_->enu; }

 private:
  std::shared_ptr<Log> log_;
  std::vector<GpsFeed> feeds_;
};

// Hands out the items it was given, then kEnd.
class ScriptedSource : public FrameSource {
 public:
  explicit ScriptedSource(std::deque<SourceItem> items) : items_(std::move(items)) {}
  SourceItem Next() override {
    if (items_.empty()) {
      SourceItem end;
      end.kind = SourceItem::Kind::kEnd;
      return end;
    }
    SourceItem item = std::move(items_.front());
    items_.pop_front();
    return item;
  }
  const StereoCamera& camera() const override { return camera_; }
  Eigen::Isometry3d T_cam0_imu() const override { return Eigen::Isometry3d::Identity(); }

 private:
  std::deque<SourceItem> items_;
  StereoCamera camera_{400, 400, 160, 48, 0.5, 320, 96};
};

SourceItem Frame(int64_t index, int64_t t_ns) {
  SourceItem item;
  item.kind = SourceItem::Kind::kFrame;
  item.index = index;
  item.t_ns = t_ns;
  return item;
}

ArrivedFix Fix(int64_t t_ns) {
  ArrivedFix f;
  f.fix.t_ns = t_ns;
  return f;
}

// A 12-frame drive rendered by locaid-synth into `dir`; the drive folder, or
// empty (the failure recorded) when rendering failed.
fs::path RenderDrive(const fs::path& dir) {
  const auto rendered = test::RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-synth -q --out " + dir.string() +
                                         " --frames 12 --width 320 --height 96 --seed 3");
  EXPECT_EQ(rendered.exit_code, 0) << rendered.out;
  if (rendered.exit_code == 0) {
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_directory()) return e.path();
  }
  return {};
}

constexpr int64_t kT0 = 1'000'000'000'000;  // first frame, ns
constexpr int64_t kPeriod = 100'000'000;    // 10 Hz

// The loop with the real scenario stage: `scenario` with no noise worth
// speaking of, so the fixes it makes are where the truth was.
FrameLoop MakeLoop(std::deque<SourceItem> items, std::shared_ptr<RecordingEstimator::Log> log,
                   sim::Scenario scenario = {}) {
  return FrameLoop(std::make_unique<ScriptedSource>(std::move(items)), ScenarioStage(std::move(scenario)),
                   std::make_unique<RecordingEstimator>(std::move(log)));
}

// Frames at kT0 + i * kPeriod, each with a typed fix at its time.
std::deque<SourceItem> FramesWithFixes(int n) {
  std::deque<SourceItem> items;
  for (int i = 0; i < n; ++i) {
    SourceItem f = Frame(i, kT0 + i * kPeriod);
    f.samples.gps = {Fix(kT0 + i * kPeriod)};
    items.push_back(std::move(f));
  }
  return items;
}

TEST(FrameLoop, OutageWindowsGivenBeforeTheFirstFrameCountFromIt) {
  auto log = std::make_shared<RecordingEstimator::Log>();
  FrameLoop loop = MakeLoop(FramesWithFixes(40), log);
  loop.AddOutageWindow(0.5, 0.25);  // before any frame: relative to the first one, [0.5, 0.75) s
  std::vector<bool> out;
  size_t fixes = 0;
  for (StepResult r = loop.Step(); r.kind != StepResult::Kind::kEnd; r = loop.Step()) {
    ASSERT_EQ(r.kind, StepResult::Kind::kPose);
    out.push_back(r.frame.in_outage);
    fixes += r.frame.gps_feeds.size();
    if (r.frame_index == 10) loop.StartOutageNow(1.0);  // from the newest frame (1.0 s) for 1 s: [1.0, 2.0)
    if (r.frame_index == 25) loop.StartOutageNow(0);    // until stopped: from frame 26
    if (r.frame_index == 30) loop.StopOutage();         // frames 31 on have GPS again
  }
  ASSERT_EQ(out.size(), 40u);
  for (int i = 0; i < 40; ++i) {
    const bool expected = (i >= 5 && i < 8) || (i >= 11 && i < 20) || (i >= 26 && i <= 30);
    EXPECT_EQ(out[static_cast<size_t>(i)], expected) << "frame " << i;
  }
  EXPECT_EQ(fixes, 40u - 3 - 9 - 5) << "a fix inside an outage never reaches the filter";
}

// Frames at kT0 + i * kPeriod with a small grey pair each.
std::deque<SourceItem> FramesWithImages(int n) {
  std::deque<SourceItem> items;
  for (int i = 0; i < n; ++i) {
    SourceItem f = Frame(i, kT0 + i * kPeriod);
    f.left = cv::Mat(4, 8, CV_8UC1, cv::Scalar(100 + i));
    f.right = cv::Mat(4, 8, CV_8UC1, cv::Scalar(50 + i));
    items.push_back(std::move(f));
  }
  return items;
}

sim::CameraFaultWindow CameraFault(sim::CameraFaultKind kind, double start_s, double duration_s) {
  sim::CameraFaultWindow w;
  w.kind = kind;
  w.start_s = start_s;
  w.duration_s = duration_s;
  return w;
}

TEST(FrameLoop, CameraFaultsOfTheScenarioInjectedAndReplacedReachTheEstimator) {
  auto log = std::make_shared<RecordingEstimator::Log>();
  sim::Scenario scenario;
  scenario.camera_faults = {CameraFault(sim::CameraFaultKind::kDrop, 0.2, 0.2)};  // frames 2, 3
  FrameLoop loop = MakeLoop(FramesWithImages(20), log, scenario);
  loop.InjectCameraFault(CameraFaultAction::kWindow, CameraFault(sim::CameraFaultKind::kLeftOnly, 0.5, 0.1));
  for (StepResult r = loop.Step(); r.kind != StepResult::Kind::kEnd; r = loop.Step()) {
    ASSERT_EQ(r.kind, StepResult::Kind::kPose);
    if (r.frame_index == 7) loop.InjectCameraFault(CameraFaultAction::kStartNow,
                                                   CameraFault(sim::CameraFaultKind::kRightOnly, 0, 0.2));
    if (r.frame_index == 10) {
      // The new scenario's faults on the same clock (from frame 0); the injected ones stay.
      sim::Scenario next;
      next.camera_faults = {CameraFault(sim::CameraFaultKind::kDrop, 1.5, 0.1)};  // frame 15
      loop.SetScenario(next);
      loop.InjectCameraFault(CameraFaultAction::kStartNow, CameraFault(sim::CameraFaultKind::kDrop, 0, 0));
    }
    if (r.frame_index == 12) loop.InjectCameraFault(CameraFaultAction::kStop, {});
  }
  ASSERT_EQ(log->had_left.size(), 20u);
  for (int i = 0; i < 20; ++i) {
    const bool drop = i == 2 || i == 3 || i == 11 || i == 12 || i == 15;
    const bool left = !drop && !(i == 8 || i == 9);  // right_only from frame 8 for 0.2 s
    const bool right = !drop && i != 5;              // left_only at frame 5
    EXPECT_EQ(log->had_left[static_cast<size_t>(i)], left) << "frame " << i;
    EXPECT_EQ(log->had_right[static_cast<size_t>(i)], right) << "frame " << i;
  }
  sim::Scenario bad;
  bad.camera_faults = {CameraFault(sim::CameraFaultKind::kDark, 0, 1)};
  bad.camera_faults[0].gain = 0;
  EXPECT_THROW(loop.SetScenario(bad), std::invalid_argument);
}

TEST(FrameLoop, SensorDataReachesTheFilterBeforeItsFrameAndFixesComeWithThePose) {
  auto log = std::make_shared<RecordingEstimator::Log>();
  SourceItem between;  // samples between frames: fused, no pose
  between.kind = SourceItem::Kind::kSamples;
  between.t_ns = kT0 + 50'000'000;
  between.samples.gps = {Fix(kT0 + 40'000'000)};
  SourceItem frame = Frame(1, kT0 + kPeriod);
  frame.samples.gps = {Fix(kT0 + 90'000'000), Fix(kT0 + 95'000'000)};
  kitti::OxtsSample oxts;  // a recorded drive's reference unit at the frame time
  oxts.t_ns = kT0 + kPeriod;
  oxts.record.lat_deg = 49.0;
  oxts.record.lon_deg = 8.4;
  AppendOxts(oxts, frame.samples);
  FrameLoop loop = MakeLoop({Frame(0, kT0), between, frame}, log);
  EXPECT_EQ(loop.Step().kind, StepResult::Kind::kPose);
  const StepResult fused = loop.Step();
  EXPECT_EQ(fused.kind, StepResult::Kind::kFused);
  EXPECT_TRUE(fused.frame.gps_feeds.empty());  // reported with the next pose
  const StepResult pose = loop.Step();
  ASSERT_EQ(pose.kind, StepResult::Kind::kPose);
  // The truth pose became the scenario's fix (10 Hz: one due at 0.1 s),
  // its IMU one IMU sample; in time order, after the fix fused between frames.
  ASSERT_EQ(pose.frame.gps_feeds.size(), 4u);
  const std::vector<int64_t> order = {kT0 + 40'000'000, kT0 + 90'000'000, kT0 + 95'000'000, kT0 + kPeriod};
  for (size_t i = 0; i < order.size(); ++i) EXPECT_EQ(pose.frame.gps_feeds[i].fix.t_ns, order[i]) << i;
  EXPECT_NEAR(pose.frame.gps_feeds[3].fix.lat_deg, 49.0, 1e-3);  // degraded, not the truth itself
  const std::vector<std::string> calls = {"process " + std::to_string(kT0), "fuse 0 1", "fuse 1 3",
                                          "process " + std::to_string(kT0 + kPeriod)};
  EXPECT_EQ(log->calls, calls);
}

TEST(FrameLoop, TruthIsInTheFiltersEnuFrameOnceItHasOne) {
  auto log = std::make_shared<RecordingEstimator::Log>();
  SourceItem a = Frame(0, kT0), b = Frame(1, kT0 + kPeriod);
  fusion::TruthSample truth;
  truth.lat_deg = 49.0;
  truth.lon_deg = 8.4;
  truth.alt_m = 100.0;
  a.truth = truth;
  truth.lat_deg = 49.0 + 10.0 / 111'200.0;  // ~10 m north
  b.truth = truth;
  FrameLoop loop = MakeLoop({a, b}, log);
  const StepResult first = loop.Step();
  ASSERT_TRUE(first.truth.has_value());
  EXPECT_FALSE(first.truth->T_enu_body.has_value());  // no origin yet
  EXPECT_DOUBLE_EQ(first.truth->lat_deg, 49.0);
  log->enu.SetOrigin(49.0, 8.4, 100.0);
  const StepResult second = loop.Step();
  ASSERT_TRUE(second.truth && second.truth->T_enu_body);
  EXPECT_NEAR(second.truth->T_enu_body->translation().y(), 10.0, 0.05);
  EXPECT_NEAR(second.truth->T_enu_body->translation().x(), 0.0, 1e-6);
}

// A rendered drive with two frames missing an image and one corrupt image:
// the loop skips the three, and the OXTS samples that came with them still
// reach the estimator (as IMU samples, one each); none is lost.
TEST(FrameLoop, OxtsOfSkippedFramesStillReachTheEstimator) {
  const test_support::ScopedTempDir dir("frame_loop");
  const fs::path drive = RenderDrive(dir);
  ASSERT_FALSE(drive.empty());
  auto png = [&](const char* camera, int i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%010d.png", i);
    return drive / camera / "data" / name;
  };
  ASSERT_TRUE(fs::remove(png("image_00", 3)));
  ASSERT_TRUE(fs::remove(png("image_01", 4)));
  fs::resize_file(png("image_00", 7), 100);
  const auto reference = kitti::OpenDataset(drive);
  size_t expected = 0;
  for (const auto& o : reference->oxts())
    expected += o.t_ns >= reference->time_ns(0) && o.t_ns <= reference->time_ns(11) ? 1 : 0;
  ASSERT_GE(expected, 11u);

  auto log = std::make_shared<RecordingEstimator::Log>();
  FrameLoop loop(std::make_unique<DatasetFrameSource>(kitti::OpenDataset(drive), 0, -1), ScenarioStage({}),
                 std::make_unique<RecordingEstimator>(log));
  std::vector<int64_t> skipped;
  for (StepResult r = loop.Step(); r.kind != StepResult::Kind::kEnd; r = loop.Step()) {
    if (r.kind == StepResult::Kind::kPose) continue;
    skipped.push_back(r.frame_index);
    EXPECT_FALSE(r.error.empty());
  }
  EXPECT_EQ(skipped, (std::vector<int64_t>{3, 4, 7}));
  EXPECT_EQ(log->frame_t_ns.size(), 9u);
  EXPECT_EQ(log->imu_samples, expected);
}

// The server opens KITTI drives with skip_bad_oxts: the OXTS files the reader
// left out are reported by the frame source, once, as bad OXTS lines.
TEST(DatasetFrameSource, CountsTheOxtsFilesTheReaderSkipped) {
  const test_support::ScopedTempDir dir("dataset_source");
  const fs::path drive = RenderDrive(dir);
  ASSERT_FALSE(drive.empty());
  std::ofstream(drive / "oxts" / "data" / "0000000004.txt", std::ios::trunc) << "1 2 3\n";  // 3 fields
  {
    const fs::path seven = drive / "oxts" / "data" / "0000000007.txt";
    std::string line;
    std::getline(std::ifstream(seven) >> std::ws, line);
    line = "nan" + line.substr(line.find(' '));  // latitude NaN
    std::ofstream(seven, std::ios::trunc) << line << "\n";
  }
  kitti::RawDriveOptions options;
  options.skip_bad_oxts = true;
  const auto reference = kitti::OpenDataset(drive, options);
  ASSERT_EQ(reference->oxts().size(), 10u);  // 12 records, 2 unreadable
  size_t expected_oxts = 0;
  for (const auto& o : reference->oxts())
    expected_oxts += o.t_ns >= reference->time_ns(0) && o.t_ns <= reference->time_ns(11) ? 1 : 0;
  DatasetFrameSource source(kitti::OpenDataset(drive, options), 0, -1);
  int bad = 0, frames = 0;
  size_t oxts = 0;
  std::string first_error;
  for (SourceItem item = source.Next(); item.kind != SourceItem::Kind::kEnd; item = source.Next()) {
    if (frames++ == 0) first_error = item.error;
    bad += item.oxts_bad_lines;
    oxts += item.samples.truth_poses.size();
    EXPECT_EQ(item.samples.truth_imu.size(), item.samples.truth_poses.size());
  }
  EXPECT_EQ(frames, 12);
  EXPECT_EQ(bad, 2);
  EXPECT_EQ(oxts, expected_oxts);
  EXPECT_NE(first_error.find("OXTS"), std::string::npos) << first_error;
}

TEST(LiveFrameSource, OrderingAndBadRecordsAreCountedNotFatal) {
  LiveCameraSetup setup;
  setup.camera = StereoCamera{30, 30, 4, 3, 0.5, 8, 6};
  LiveFrameSource source(setup);
  auto frame = [](int64_t t_ns) {
    LiveItem item;
    item.kind = LiveItem::Kind::kFrame;
    item.t_ns = t_ns;
    item.png = false;
    item.left = item.right = std::string(8 * 6, '\x80');
    return item;
  };
  LiveItem bad_oxts;
  bad_oxts.kind = LiveItem::Kind::kOxts;
  bad_oxts.t_ns = kT0;
  bad_oxts.oxts_line = "1 2 3";
  ASSERT_TRUE(source.Push(bad_oxts, {}));
  ASSERT_TRUE(source.Push(frame(kT0 + kPeriod), {}));
  ASSERT_TRUE(source.Push(frame(kT0), {}));  // older than the previous frame
  LiveItem late_fix;
  late_fix.kind = LiveItem::Kind::kGps;
  late_fix.t_ns = kT0 - 10 * kPeriod;  // 1.1 s older than the newest frame (limit 0.5 s)
  late_fix.gps.t_ns = late_fix.t_ns;
  ASSERT_TRUE(source.Push(late_fix, {}));
  source.CloseInput();

  const SourceItem first = source.Next();
  EXPECT_EQ(first.kind, SourceItem::Kind::kFrame);
  EXPECT_EQ(first.oxts_bad_lines, 1);
  EXPECT_NE(first.error.find("pushed oxts record 0"), std::string::npos) << first.error;
  const SourceItem second = source.Next();
  EXPECT_EQ(second.kind, SourceItem::Kind::kCorrupt);
  EXPECT_NE(second.error.find("not after the previous frame"), std::string::npos) << second.error;
  EXPECT_EQ(source.Next().kind, SourceItem::Kind::kEnd);
  const LiveInputStats stats = source.input_stats();
  EXPECT_EQ(stats.gps_fixes_in, 1u);
  EXPECT_EQ(stats.gps_fixes_late, 1u);
  EXPECT_NE(stats.last_error.find("older than the newest frame"), std::string::npos) << stats.last_error;
}

}  // namespace
}  // namespace locaid::pipeline
