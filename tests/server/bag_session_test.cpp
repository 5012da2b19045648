// A ROS 2 bag as a session's source (StartSessionRequest.bag): the real
// KITTI excerpt written as a bag by the field's own libraries
// (tests/rosbag/js/kitti_to_bag.mjs), played by the real locaid-server on
// 127.0.0.1 (the production estimator), started over gRPC and with the real
// CLI; and every bad request refused with its precise status, no session made.
#include "needs_tool.hpp"
#include "test_support.hpp"

#include "kitti/dataset.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <functional>
#include <limits>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

const fs::path kDrive = fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/2011_09_26_drive_unknown_extract";
// Image frames written into the bag (kitti_to_bag.mjs --max-frames): 6 s,
// about 35 m; the filter starts from fixes over 15 m or more, which the car
// (4 m/s at first) has not driven after 30 frames.
constexpr int kFrames = 60;

#define REQUIRE_DATA_AND_NODE()                                                               \
  do {                                                                                        \
    if (!fs::exists(kDrive)) GTEST_SKIP() << "shared real KITTI excerpt absent: " << kDrive;  \
    LOCAID_NEEDS_TOOL(test_support::HaveCommand("node"), "node not installed (the bag writer runs on it)"); \
  } while (false)

class BagSessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = v1::Localization::NewStub(server_->NewChannel());
  }
  static void TearDownTestSuite() { bag_dir_.reset(); }

  // The excerpt's first kFrames frames as a bag: written once for the whole
  // program, in a folder removed after the last test.
  static fs::path Bag() {
    if (!bag_dir_) {
      bag_dir_ = std::make_unique<ScopedTempDir>("bag_session");
      const fs::path bag = *bag_dir_ / "drive.mcap";
      const CliResult r = RunShell("node " + ShellQuote(std::string(LOCAID_ROSBAG_JS_DIR) + "/kitti_to_bag.mjs") +
                                   " --drive " + ShellQuote(kDrive.string()) + " --out " + ShellQuote(bag.string()) +
                                   " --max-frames " + std::to_string(kFrames));
      EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    }
    return *bag_dir_ / "drive.mcap";
  }

  grpc::Status Start(const v1::StartSessionRequest& req, v1::Session* session = nullptr) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 60);
    v1::Session ignored;
    return stub_->StartSession(&ctx, req, session ? session : &ignored);
  }
  static v1::StartSessionRequest BagRequest(const fs::path& path) {
    v1::StartSessionRequest req;
    req.mutable_bag()->set_path(path.string());
    req.mutable_scenario()->set_name("open-sky");
    req.set_history_size(1000);
    return req;
  }
  size_t Sessions() {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 10);
    v1::ListSessionsResponse list;
    EXPECT_TRUE(stub_->ListSessions(&ctx, {}, &list).ok());
    return static_cast<size_t>(list.sessions_size());
  }
  // The excerpt's frames in [0, kFrames) with both images: the bag's stereo pairs.
  static size_t StereoFrames() {
    const auto drive = kitti::OpenDataset(kDrive);
    size_t n = 0;
    for (size_t i = 0; i < static_cast<size_t>(kFrames) && i < drive->size(); ++i) n += drive->has_stereo(i) ? 1 : 0;
    return n;
  }

  static std::unique_ptr<ScopedTempDir> bag_dir_;
  ScopedTempDir dir_{"bag_session_server"};
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};
std::unique_ptr<ScopedTempDir> BagSessionTest::bag_dir_;

TEST_F(BagSessionTest, StreamsAPosePerStereoFrameUntilTheBagEnds) {
  REQUIRE_DATA_AND_NODE();
  const fs::path bag = Bag();
  v1::Session session;
  const grpc::Status s = Start(BagRequest(bag), &session);
  ASSERT_TRUE(s.ok()) << s.error_message() << "\n" << server_->log();
  EXPECT_EQ(session.source(), "bag:" + bag.string());

  PoseCollector collector(server_->NewChannel(1), session.id(), /*from_start=*/true, 300);
  ASSERT_TRUE(collector.WaitDone(300)) << "the stream must end with the bag";
  EXPECT_TRUE(collector.status().ok()) << collector.status().error_message();
  const auto poses = collector.poses();
  EXPECT_EQ(poses.size(), StereoFrames());
  bool fused = false;
  int64_t previous_ns = std::numeric_limits<int64_t>::min();
  for (const auto& p : poses) {
    fused = fused || p.mode() == v1::MODE_GPS_FUSED;
    EXPECT_GT(p.t_ns(), previous_ns) << "header stamps, in order";
    previous_ns = p.t_ns();
    EXPECT_TRUE(NonFinitePoseFields(p).empty()) << "frame " << p.frame_index();
  }
  EXPECT_TRUE(fused) << "the bag's NavSatFix fixes reach the filter";
  ASSERT_FALSE(poses.empty());
  EXPECT_GT(poses.back().gps_used(), 0u);
  EXPECT_GT(poses.back().t_ns(), 1'000'000'000'000'000'000) << "Unix epoch ns from header.stamp";

  const v1::Session ended = GetSession(stub_.get(), session.id());
  EXPECT_EQ(ended.state(), v1::SESSION_STATE_FINISHED) << ended.error();
  EXPECT_EQ(ended.stats().frames_processed(), poses.size());
  EXPECT_GT(ended.stats().imu_samples(), poses.size()) << "sensor_msgs/Imu picked by type (the excerpt's OXTS: ~16 Hz)";
  EXPECT_GE(ended.stats().gps_fixes_in(), poses.back().gps_used());
  EXPECT_EQ(ended.stats().gps_no_fix(), 0u);
}

TEST_F(BagSessionTest, CliStartsABagSessionWithATopicsFile) {
  REQUIRE_DATA_AND_NODE();
  const fs::path bag = Bag();
  const fs::path topics = dir_ / "topics.yaml";
  std::ofstream(topics) << "left_image: /camera/left/image_raw\ngps: /gps/fix\nimu: none\n";
  const CliResult r = RunCli(server_->port(), {"session", "start", "--bag", bag.string(), "--bag-topics",
                                               topics.string(), "--scenario", "open-sky", "--history", "1000"});
  ASSERT_EQ(r.exit_code, 0) << r.err << "\n" << server_->log();
  const std::string id = r.out.substr(0, r.out.find('\n'));
  const fs::path csv = dir_ / "poses.csv";
  const CliResult sub = RunCli(server_->port(), {"subscribe", id, "--from-start", "--format", "csv", "--out",
                                                 csv.string()});
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const v1::Session ended = GetSession(stub_.get(), id);
  EXPECT_EQ(ended.state(), v1::SESSION_STATE_FINISHED) << ended.error();
  EXPECT_EQ(ended.source(), "bag:" + bag.string());
  EXPECT_EQ(ended.stats().imu_samples(), 0u) << "imu: none in the topics file";
  // Without an IMU topic the filter is the odometry model, as --no-imu.
  const CliResult replay = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-replay") + " --bag " +
                                    ShellQuote(bag.string()) + " --bag-topics " + ShellQuote(topics.string()) +
                                    " --json 2>/dev/null | grep use_imu");
  EXPECT_EQ(replay.out, "  \"use_imu\": false,\n");
  const std::string text = Slurp(csv);
  EXPECT_EQ(static_cast<size_t>(std::count(text.begin(), text.end(), '\n')), StereoFrames() + 1);  // + header

  // The CLI reads the YAML itself: a bad key is its error, before any call.
  std::ofstream(topics) << "left: /camera/left/image_raw\n";
  const CliResult bad = RunCli(server_->port(), {"session", "start", "--bag", bag.string(), "--bag-topics",
                                                 topics.string()});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("unknown key 'left'"), std::string::npos) << bad.err;
}

struct Refusal {
  std::string what;
  grpc::StatusCode code;
  std::string message;  // a part of the status message
};

void ExpectRefused(const grpc::Status& s, const Refusal& r) {
  EXPECT_EQ(s.error_code(), r.code) << r.what << ": " << s.error_message();
  EXPECT_NE(s.error_message().find(r.message), std::string::npos) << r.what << ": " << s.error_message();
}

// Field checks need no bag content (any existing file will do), so they run
// without the shared data.
TEST_F(BagSessionTest, BadFieldsAreInvalidArgumentNamingTheField) {
  const fs::path text = dir_ / "notes.txt";
  std::ofstream(text) << "not a bag\n";
  const auto with = [&](const std::function<void(v1::BagSource*)>& edit) {
    v1::StartSessionRequest req = BagRequest(text);
    edit(req.mutable_bag());
    return req;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::pair<v1::StartSessionRequest, Refusal>> cases = {
      {with([](v1::BagSource* b) { b->clear_path(); }),
       {"no path", grpc::INVALID_ARGUMENT, "bag.path: required"}},
      {with([](v1::BagSource* b) { b->set_path(std::string(PATH_MAX + 1, 'a')); }),
       {"path over PATH_MAX", grpc::INVALID_ARGUMENT, "longer than PATH_MAX"}},
      {with([](v1::BagSource* b) { b->set_path("/nonexistent/drive.mcap"); }),
       {"absent path", grpc::INVALID_ARGUMENT, "bag.path '/nonexistent/drive.mcap': does not exist on the server"}},
      {with([](v1::BagSource* b) { b->set_path("drive.mcap"); }),
       {"relative path", grpc::INVALID_ARGUMENT, "a relative path is resolved from the server's working directory"}},
      {with([](v1::BagSource* b) { b->set_stereo_tolerance_ms(-1); }),
       {"negative tolerance", grpc::INVALID_ARGUMENT, "bag.stereo_tolerance_ms: must be in [0, 1000] ms"}},
      {with([](v1::BagSource* b) { b->set_stereo_tolerance_ms(1000.5); }),
       {"tolerance over 1 s", grpc::INVALID_ARGUMENT, "bag.stereo_tolerance_ms"}},
      {with([nan](v1::BagSource* b) { b->set_stereo_tolerance_ms(nan); }),
       {"NaN tolerance", grpc::INVALID_ARGUMENT, "bag.stereo_tolerance_ms"}},
      {with([](v1::BagSource* b) { b->set_reorder_window_ms(60001); }),
       {"window over 60 s", grpc::INVALID_ARGUMENT, "bag.reorder_window_ms: must be in [0, 60000] ms"}},
      {with([](v1::BagSource* b) { b->mutable_topics()->set_imu("imu/data"); }),
       {"topic without /", grpc::INVALID_ARGUMENT, "bag.topics.imu 'imu/data': must be empty"}},
      {with([](v1::BagSource* b) { b->mutable_topics()->set_gps("/gps fix"); }),
       {"topic with a space", grpc::INVALID_ARGUMENT, "bag.topics.gps"}},
      {with([](v1::BagSource* b) { b->mutable_topics()->set_left_image("none"); }),
       {"camera none", grpc::INVALID_ARGUMENT, "bag.topics.left_image: the cameras cannot be \"none\""}},
      {BagRequest(text), {"a text file", grpc::FAILED_PRECONDITION, "cannot open bag: "}},
      {v1::StartSessionRequest{}, {"no source", grpc::INVALID_ARGUMENT, "one of kitti, bag, synthetic or live"}},
  };
  for (const auto& [req, refusal] : cases) ExpectRefused(Start(req), refusal);
  EXPECT_EQ(Sessions(), 0u) << "a refused request makes no session";
  EXPECT_EQ(RunCli(server_->port(), {"health"}).out, "SERVING\n");
}

// What only the bag can tell: its topics do not fit the request.
TEST_F(BagSessionTest, TopicsTheBagCannotGiveAreFailedPrecondition) {
  REQUIRE_DATA_AND_NODE();
  const fs::path bag = Bag();
  const auto with = [&](const std::function<void(v1::BagTopics*)>& edit) {
    v1::StartSessionRequest req = BagRequest(bag);
    edit(req.mutable_bag()->mutable_topics());
    return req;
  };
  const std::vector<std::pair<v1::StartSessionRequest, Refusal>> cases = {
      {with([](v1::BagTopics* t) { t->set_imu("/gps/fix"); }),
       {"imu of the wrong type", grpc::FAILED_PRECONDITION,
        "cannot open bag: imu: topic /gps/fix has type sensor_msgs/msg/NavSatFix"}},
      {with([](v1::BagTopics* t) { t->set_left_image("/camera/left/camera_info"); }),
       {"image of the wrong type", grpc::FAILED_PRECONDITION, "cannot open bag: left_image: topic"}},
  };
  for (const auto& [req, refusal] : cases) ExpectRefused(Start(req), refusal);
  EXPECT_EQ(Sessions(), 0u);
}

}  // namespace
}  // namespace locaid::server::testing
