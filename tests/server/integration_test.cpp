// The real server on 127.0.0.1 (port picked by the OS), driven by the real
// `locaid` CLI (subprocess), the Python client and a C++ push client. The
// estimator is a deterministic fake so the tests check the service, not VO.
#include "test_support.hpp"

#include "kitti/dataset.hpp"
#include "needs_tool.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <csignal>
#include <thread>

namespace locaid::server::testing {
namespace {

constexpr int64_t kFramePeriodNs = 100'000'000;  // 10 Hz

class ServerTest : public ::testing::Test {
 protected:
  void StartServer(const ServerConfig& config) {
    server_ = std::make_unique<LocalizationServer>(config, FakeFactory());
    port_ = server_->port();
    stub_ = MakeStub(port_);
  }
  void SetUp() override { StartServer(LoopbackConfig(dir_ / "work")); }
  void TearDown() override {
    if (server_) server_->Shutdown();
  }

  std::string StartLiveSession(uint32_t history = 0) {
    v1::StartSessionRequest req;
    *req.mutable_live() = SmallCamera();
    req.set_history_size(history);
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session resp;
    const grpc::Status s = stub_->StartSession(&ctx, req, &resp);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return resp.id();
  }

  v1::SessionStats Stats(const std::string& id) { return GetStats(stub_.get(), id); }

  // Waits (bounded) until the session has `n` subscribers.
  void WaitForSubscribers(const std::string& id, uint32_t n) {
    ASSERT_GE(WaitStats(stub_.get(), id, 5, [n](const v1::SessionStats& s) { return s.subscribers() >= n; })
                  .subscribers(),
              n);
  }

  const ScopedTempDir dir_{"server_test"};  // the test's files; outlives the server
  std::unique_ptr<LocalizationServer> server_;
  int port_ = 0;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

TEST_F(ServerTest, HealthIsServingThroughTheCli) {
  const CliResult r = RunCli(port_, {"health"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "SERVING\n");
}

TEST_F(ServerTest, PushedFramesComeBackAsPosesAndBadInputIsCountedNotFatal) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  constexpr int kFrames = 12;
  int expected_poses = 0;
  for (int i = 0; i < kFrames; ++i) {
    const int64_t t = (i + 1) * kFramePeriodNs;
    ASSERT_TRUE(push.Write(Oxts(t - kFramePeriodNs / 2, OxtsLine())));
    if (i == 3) {  // corrupt PNG bytes
      v1::PushRequest bad = Gray8Frame(t);
      bad.mutable_frame()->set_encoding(v1::IMAGE_ENCODING_PNG);
      bad.mutable_frame()->set_left("not a png");
      ASSERT_TRUE(push.Write(bad));
    } else if (i == 5) {  // wrong raw size
      v1::PushRequest bad = Gray8Frame(t);
      bad.mutable_frame()->set_right("short");
      ASSERT_TRUE(push.Write(bad));
    } else {
      ASSERT_TRUE(push.Write(Gray8Frame(t)));
      ++expected_poses;
    }
  }
  ASSERT_TRUE(push.Write(Oxts(kFrames * kFramePeriodNs + 1, "1 2 3")));                           // 3 fields
  ASSERT_TRUE(push.Write(Oxts(kFrames * kFramePeriodNs + 2, OxtsLine(std::nan(""), 8.4))));       // NaN
  ASSERT_TRUE(push.Write(Gray8Frame((kFrames + 1) * kFramePeriodNs)));
  ++expected_poses;
  ASSERT_TRUE(push.WaitPoses(static_cast<size_t>(expected_poses)));
  const grpc::Status end = push.Close();
  EXPECT_TRUE(end.ok()) << end.error_message();
  const auto poses = push.poses();
  ASSERT_EQ(poses.size(), static_cast<size_t>(expected_poses));
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(poses[i].sequence(), i);
    EXPECT_EQ(poses[i].session_id(), id);
    EXPECT_EQ(poses[i].covariance_size(), 36);
    EXPECT_DOUBLE_EQ(poses[i].position_enu_m().x(), static_cast<double>(i));
  }
  EXPECT_GT(poses.back().gps_used(), 0u);  // OXTS records reached the estimator

  const CliResult stats = RunCli(port_, {"stats", id});
  ASSERT_EQ(stats.exit_code, 0) << stats.err;
  EXPECT_NE(stats.out.find("frames_corrupt 2\n"), std::string::npos) << stats.out;
  EXPECT_NE(stats.out.find("oxts_bad_lines 2\n"), std::string::npos) << stats.out;
  EXPECT_NE(stats.out.find("frames_processed " + std::to_string(expected_poses) + "\n"), std::string::npos)
      << stats.out;
  const CliResult list = RunCli(port_, {"session", "list"});
  EXPECT_NE(list.out.find(id + " FINISHED"), std::string::npos) << list.out;
}

// An estimator that throws fails the session: the pose stream and the push
// stream both end with ABORTED naming the error, after the poses made before.
TEST_F(ServerTest, AFailedSessionEndsItsStreamsWithAborted) {
  v1::StartSessionRequest req;
  *req.mutable_live() = SmallCamera();
  req.set_vo_method("fake-fail-at-3");
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  v1::Session session;
  ASSERT_TRUE(stub_->StartSession(&ctx, req, &session).ok());
  PoseCollector poses(MakeChannel(port_), session.id(), true);
  WaitForSubscribers(session.id(), 1);
  Pusher push(stub_.get(), session.id());
  ASSERT_TRUE(push.ok());
  // Frames 0-3 reach a running session (frame 3 fails it); once it has
  // failed the server ends the push stream, so writing frames 4 and 5 may
  // already be refused: their result is not checked.
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs))) << "frame " << i;
  for (int i = 4; i < 6; ++i) push.Write(Gray8Frame((i + 1) * kFramePeriodNs));
  const grpc::Status push_end = push.Close();
  EXPECT_EQ(push_end.error_code(), grpc::ABORTED) << push_end.error_message();
  EXPECT_NE(push_end.error_message().find("fake estimator failed at frame 3"), std::string::npos)
      << push_end.error_message();
  ASSERT_TRUE(poses.WaitDone(30));
  EXPECT_EQ(poses.status().error_code(), grpc::ABORTED) << poses.status().error_message();
  EXPECT_NE(poses.status().error_message().find("session " + session.id() + " failed"), std::string::npos)
      << poses.status().error_message();
  EXPECT_EQ(poses.count(), 3u);
  EXPECT_EQ(push.poses().size(), 3u);
}

TEST_F(ServerTest, ManySubscribersThatKeepUpLoseNothingAndAStalledOneIsBounded) {
  const std::string id = StartLiveSession();
  constexpr int kSubscribers = 20;
  constexpr int kFrames = 300;
  std::vector<std::vector<v1::PoseUpdate>> got(kSubscribers);
  std::vector<grpc::Status> status(kSubscribers);
  std::vector<grpc::ClientContext> contexts(kSubscribers);
  auto channel = MakeChannel(port_);
  auto stub = v1::Localization::NewStub(channel);
  std::vector<std::thread> readers;
  // A failed ASSERT returns early: cancel and join the readers instead of
  // destroying running threads (std::terminate).
  struct JoinAll {
    std::vector<grpc::ClientContext>& contexts;
    std::vector<std::thread>& threads;
    ~JoinAll() {
      for (auto& t : threads) {
        if (!t.joinable()) continue;
        for (auto& c : contexts) c.TryCancel();
        t.join();
      }
    }
  } join_all{contexts, readers};
  for (int s = 0; s < kSubscribers; ++s) {
    readers.emplace_back([&, s] {
      grpc::ClientContext& ctx = contexts[static_cast<size_t>(s)];
      SetDeadline(&ctx, 60);
      v1::StreamPosesRequest req;
      req.set_session_id(id);
      req.set_queue_size(kFrames);  // room for everything: keeping up is guaranteed
      auto reader = stub->StreamPoses(&ctx, req);
      v1::PoseUpdate p;
      while (reader->Read(&p)) got[static_cast<size_t>(s)].push_back(p);
      status[static_cast<size_t>(s)] = reader->Finish();
    });
  }
  // A subscriber that never reads, on its own connection with a tiny window.
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1024);
  args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  auto stalled_stub = v1::Localization::NewStub(
      grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port_), grpc::InsecureChannelCredentials(), args));
  grpc::ClientContext stalled_ctx;
  SetDeadline(&stalled_ctx, 60);
  v1::StreamPosesRequest stalled_req;
  stalled_req.set_session_id(id);
  stalled_req.set_queue_size(2);
  auto stalled = stalled_stub->StreamPoses(&stalled_ctx, stalled_req);
  WaitForSubscribers(id, kSubscribers + 1);

  Pusher push(stub_.get(), id);
  ASSERT_TRUE(push.ok());
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs)));
  ASSERT_TRUE(push.WaitSequence(kFrames - 1));  // every frame has been processed
  const v1::SessionStats before_end = Stats(id);
  EXPECT_TRUE(push.Close().ok());
  for (auto& t : readers) t.join();
  for (int s = 0; s < kSubscribers; ++s) {
    EXPECT_TRUE(status[static_cast<size_t>(s)].ok()) << status[static_cast<size_t>(s)].error_message();
    ASSERT_EQ(got[static_cast<size_t>(s)].size(), static_cast<size_t>(kFrames)) << "subscriber " << s;
    for (int i = 0; i < kFrames; ++i) {
      ASSERT_EQ(got[static_cast<size_t>(s)][static_cast<size_t>(i)].sequence(), static_cast<uint64_t>(i));
    }
    EXPECT_EQ(got[static_cast<size_t>(s)].back().dropped_for_subscriber(), 0u);
  }
  // The stalled subscriber: bounded queue, drops counted, session unaffected.
  bool found = false;
  for (const auto& sub : before_end.subscriber()) {
    if (sub.delivered() + sub.dropped() + sub.queued() < static_cast<uint64_t>(kFrames) / 2) continue;
    if (sub.dropped() > 0) {
      found = true;
      EXPECT_LE(sub.queued(), 2u);
    }
  }
  EXPECT_TRUE(found) << "no subscriber with drops: the stalled one should have lost poses";
  EXPECT_EQ(before_end.frames_processed(), static_cast<uint64_t>(kFrames));
  stalled_ctx.TryCancel();
}

TEST_F(ServerTest, LiveOutageFromTheCliSwitchesModeAtTheNextFrame) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  int64_t t = 0;
  auto push_n = [&](int n) {
    for (int i = 0; i < n; ++i) ASSERT_TRUE(push.Write(Gray8Frame(t += kFramePeriodNs)));
  };
  push_n(5);
  ASSERT_TRUE(push.WaitPoses(5));
  CliResult r = RunCli(port_, {"outage", "start", id});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  push_n(5);
  ASSERT_TRUE(push.WaitPoses(10));
  r = RunCli(port_, {"outage", "stop", id});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  push_n(5);
  ASSERT_TRUE(push.WaitPoses(15));
  // A window on the sensor clock: first frame at 0.1 s, so [1.65 s, 1.85 s) holds poses 16 and 17.
  r = RunCli(port_, {"outage", "window", id, "--start", "1.55", "--duration", "0.2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  push_n(5);
  ASSERT_TRUE(push.WaitPoses(20));
  EXPECT_TRUE(push.Close().ok());
  const auto poses = push.poses();
  ASSERT_EQ(poses.size(), 20u);
  // gps_outage_active is the scenario stage's verdict (the mode is the fake
  // filter's: frames only, no GPS, so VO_ONLY throughout).
  for (size_t i = 0; i < poses.size(); ++i) {
    const bool outage = (i >= 5 && i < 10) || (i >= 16 && i < 18);
    EXPECT_EQ(poses[i].gps_outage_active(), outage) << "pose " << i;
  }
}

TEST_F(ServerTest, SubscribeRecordsEveryFormatAndFromStartReplaysHistory) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  constexpr int kFrames = 15;
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs)));
  ASSERT_TRUE(push.WaitPoses(kFrames));
  ASSERT_TRUE(push.Close().ok());  // session finished: history stays
  for (const std::string format : {"csv", "tum", "kitti", "geojson"}) {
    const auto out = dir_ / ("poses." + format);
    const CliResult r = RunCli(port_, {"subscribe", id, "--from-start", "--format", format, "--out", out.string()});
    ASSERT_EQ(r.exit_code, 0) << format << ": " << r.err;
    const std::string text = Slurp(out);
    size_t lines = 0;
    for (char c : text) lines += c == '\n' ? 1 : 0;
    if (format == "geojson") {
      const auto json = nlohmann::json::parse(text);
      ASSERT_EQ(json.at("features").size(), static_cast<size_t>(kFrames));
      EXPECT_DOUBLE_EQ(json["features"][0]["geometry"]["coordinates"][0].get<double>(), 8.4);
    } else {
      EXPECT_EQ(lines, static_cast<size_t>(kFrames) + (format == "csv" ? 1 : 0)) << format;
    }
    if (format == "tum" || format == "csv") {  // times to the nanosecond: t_ns exactly
      std::istringstream rows(text);
      std::string row;
      if (format == "csv") std::getline(rows, row);
      for (int i = 0; i < kFrames && std::getline(rows, row); ++i) {
        const int64_t t_ns = (i + 1) * kFramePeriodNs;
        char expected[32];
        std::snprintf(expected, sizeof expected, "%lld.%09lld", static_cast<long long>(t_ns / 1000000000),
                      static_cast<long long>(t_ns % 1000000000));
        EXPECT_EQ(row.substr(0, row.find_first_of(" ,")), expected) << format << " row " << i;
      }
    }
    if (format == "kitti") {
      std::istringstream first(text);
      std::vector<double> v(12);
      for (double& x : v) first >> x;
      EXPECT_DOUBLE_EQ(v[0], 1.0);  // identity rotation
      EXPECT_DOUBLE_EQ(v[3], 0.0);  // first pose at x = 0
    }
  }
}

TEST_F(ServerTest, PythonClientRecordsCsvWithTheCliColumns) {
  LOCAID_NEEDS_TOOL(std::system("/usr/bin/python3 -c 'import grpc' 2>/dev/null") == 0, "python3-grpcio not installed");
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  constexpr int kFrames = 8;
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs)));
  ASSERT_TRUE(push.WaitPoses(kFrames));
  ASSERT_TRUE(push.Close().ok());
  const auto py_csv = dir_ / "python.csv", cli_csv = dir_ / "cli.csv";
  const CliResult py = RunShell("PYTHONPATH=" + ShellQuote(LOCAID_PYTHON_STUBS) + " /usr/bin/python3 " +
                                ShellQuote(std::string(LOCAID_SOURCE_DIR) + "/clients/python/locaid_client.py") +
                                " --server 127.0.0.1:" + std::to_string(port_) + " subscribe " + id +
                                " --from-start --csv " + ShellQuote(py_csv.string()));
  ASSERT_EQ(py.exit_code, 0) << py.out << py.err;
  const CliResult cli = RunCli(port_, {"subscribe", id, "--from-start", "--format", "csv", "--out", cli_csv.string()});
  ASSERT_EQ(cli.exit_code, 0) << cli.err;
  const std::string a = Slurp(py_csv), b = Slurp(cli_csv);
  EXPECT_EQ(a.substr(0, a.find('\n')), b.substr(0, b.find('\n')));  // same header
  EXPECT_EQ(std::count(a.begin(), a.end(), '\n'), kFrames + 1);
  for (const char* column : {"t_s", "sequence", "mode", "vo_health"}) {
    EXPECT_EQ(CsvColumn(a, column), CsvColumn(b, column)) << column;  // the same values
  }
}

// The Python recorder on a 1 KiB file-size limit (`ulimit -f 1`; Python
// ignores SIGXFSZ, so the write fails with EFBIG): exit 4, a message naming
// the file and the poses kept, and a CSV that ends with its last complete row.
TEST_F(ServerTest, PythonRecorderKeepsAValidCsvWhenTheFileCannotGrow) {
  LOCAID_NEEDS_TOOL(std::system("/usr/bin/python3 -c 'import grpc' 2>/dev/null") == 0, "python3-grpcio not installed");
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  constexpr int kFrames = 20;
  for (int i = 0; i < kFrames; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs)));
  ASSERT_TRUE(push.WaitPoses(kFrames));
  ASSERT_TRUE(push.Close().ok());
  const auto csv = dir_ / "python_limited.csv";
  const CliResult py = RunShell("ulimit -f 1; PYTHONPATH=" + ShellQuote(LOCAID_PYTHON_STUBS) + " /usr/bin/python3 " +
                                ShellQuote(std::string(LOCAID_SOURCE_DIR) + "/clients/python/locaid_client.py") +
                                " --server 127.0.0.1:" + std::to_string(port_) + " subscribe " + id +
                                " --from-start --csv " + ShellQuote(csv.string()));
  EXPECT_EQ(py.exit_code, 4) << py.out << py.err;
  EXPECT_NE(py.err.find(csv.string()), std::string::npos) << py.err;
  EXPECT_NE(py.err.find("EFBIG"), std::string::npos) << py.err;
  EXPECT_NE(py.err.find("complete poses"), std::string::npos) << py.err;
  const std::string text = Slurp(csv);
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n') << "the file must end with a complete row";
  EXPECT_LE(text.size(), 1024u);
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);
  const auto columns = std::count(line.begin(), line.end(), ',');
  int rows = 0;
  while (std::getline(lines, line)) {
    EXPECT_EQ(std::count(line.begin(), line.end(), ','), columns) << "row " << rows;
    ++rows;
  }
  EXPECT_GE(rows, 1);
  EXPECT_LT(rows, kFrames);
  EXPECT_NE(py.err.find("kept " + std::to_string(rows) + " complete poses"), std::string::npos) << py.err;
}

// `locaid subscribe` printing to a full device (/dev/full): exit 4 and a
// message saying how many poses were printed, not a silent success.
TEST_F(ServerTest, PrintToAFullDeviceExitsWithARecordError) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(push.Write(Gray8Frame((i + 1) * kFramePeriodNs)));
  ASSERT_TRUE(push.WaitPoses(3));
  ASSERT_TRUE(push.Close().ok());
  // A subshell, so RunShell's own redirection of stdout does not replace ours.
  const CliResult r = RunShell("(" + ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid") + " --server 127.0.0.1:" +
                               std::to_string(port_) + " subscribe " + id + " --from-start > /dev/full)");
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_NE(r.err.find("to standard output failed (No space left on device); 0 poses were printed"),
            std::string::npos)
      << r.err;
}

TEST_F(ServerTest, BadRequestsGetPreciseStatusesAndTheServerKeepsServing) {
  // Unknown session.
  CliResult r = RunCli(port_, {"session", "get", "s999"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("NOT_FOUND: session 's999' not found"), std::string::npos) << r.err;
  r = RunCli(port_, {"subscribe", "s999"});
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  r = RunCli(port_, {"outage", "start", "nope"});
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  // Bad paths.
  r = RunCli(port_, {"session", "start", "--kitti", "/nonexistent/drive_0001_sync"});
  EXPECT_NE(r.err.find("INVALID_ARGUMENT: kitti.path '/nonexistent/drive_0001_sync': does not exist"),
            std::string::npos)
      << r.err;
  const auto empty = dir_ / "not_a_drive";
  std::filesystem::create_directories(empty);
  r = RunCli(port_, {"session", "start", "--kitti", empty.string()});
  EXPECT_NE(r.err.find("FAILED_PRECONDITION"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("not_a_drive"), std::string::npos) << r.err;
  // Bad parameters.
  auto start = [&](const v1::StartSessionRequest& req) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session resp;
    return stub_->StartSession(&ctx, req, &resp);
  };
  v1::StartSessionRequest req;
  *req.mutable_live() = SmallCamera();
  req.set_playback_rate(std::nan(""));
  grpc::Status s = start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("playback_rate"), std::string::npos) << s.error_message();
  req.set_playback_rate(1);
  req.mutable_live()->set_fx(std::nan(""));
  s = start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("live.fx"), std::string::npos) << s.error_message();
  *req.mutable_live() = SmallCamera();
  req.mutable_scenario()->set_name("no-such-scenario");
  s = start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("no-such-scenario"), std::string::npos) << s.error_message();
  req.clear_scenario();
  req.set_vo_method("no-such-vo");
  s = start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("no-such-vo"), std::string::npos) << s.error_message();
  s = start(v1::StartSessionRequest{});
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  // Push stream that does not start with 'start'.
  {
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    auto stream = stub_->PushSensorData(&ctx);
    stream->Write(Gray8Frame(1));
    stream->WritesDone();
    v1::PushResponse resp;
    while (stream->Read(&resp)) {
    }
    s = stream->Finish();
    EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
    EXPECT_NE(s.error_message().find("first message must be 'start'"), std::string::npos) << s.error_message();
  }
  // Still serving.
  r = RunCli(port_, {"health"});
  EXPECT_EQ(r.out, "SERVING\n");
}

TEST_F(ServerTest, PngDeclaringAnotherSizeEndsThePushWithInvalidArgument) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  // A real 32x24 PNG whose IHDR is rewritten to declare 30000x30000 px.
  cv::Mat img(24, 32, CV_8UC1, cv::Scalar(9));
  std::vector<uint8_t> buf;
  ASSERT_TRUE(cv::imencode(".png", img, buf));
  std::string png(buf.begin(), buf.end());
  for (int i = 0; i < 4; ++i) {
    png[static_cast<size_t>(16 + i)] = static_cast<char>((30000u >> (24 - 8 * i)) & 0xff);
    png[static_cast<size_t>(20 + i)] = static_cast<char>((30000u >> (24 - 8 * i)) & 0xff);
  }
  v1::PushRequest frame = Gray8Frame(kFramePeriodNs);
  frame.mutable_frame()->set_encoding(v1::IMAGE_ENCODING_PNG);
  frame.mutable_frame()->set_left(png);
  frame.mutable_frame()->set_right(std::string(buf.begin(), buf.end()));
  push.Write(frame);
  const grpc::Status s = push.Close();
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << s.error_message();
  EXPECT_NE(s.error_message().find("30000x30000"), std::string::npos) << s.error_message();
  EXPECT_NE(s.error_message().find("32x24"), std::string::npos) << s.error_message();
  EXPECT_EQ(RunCli(port_, {"health"}).out, "SERVING\n");
}

TEST_F(ServerTest, FramesBeforeARefusedFrameAreStillPublished) {
  // Issue 18, defect 13: frames 0-4 are good, frame 5 declares another size.
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  for (int i = 0; i < 5; ++i) push.Write(Gray8Frame((i + 1) * kFramePeriodNs));
  std::vector<uint8_t> buf;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(48, 64, CV_8UC1, cv::Scalar(9)), buf));
  v1::PushRequest bad = Gray8Frame(6 * kFramePeriodNs);
  bad.mutable_frame()->set_encoding(v1::IMAGE_ENCODING_PNG);
  bad.mutable_frame()->set_left(std::string(buf.begin(), buf.end()));
  bad.mutable_frame()->set_right(std::string(buf.begin(), buf.end()));
  push.Write(bad);
  const grpc::Status s = push.Close();
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << s.error_message();
  EXPECT_NE(s.error_message().find("frame 5"), std::string::npos) << s.error_message();
  const auto poses = push.poses();
  ASSERT_EQ(poses.size(), 5u) << "the poses of frames 0-4 come before the status";
  for (size_t k = 0; k < poses.size(); ++k) EXPECT_EQ(poses[k].frame_index(), static_cast<int64_t>(k));
}

TEST_F(ServerTest, OxtsOlderThanTheLastAcceptedIsCountedNotUsed) {
  // Issue 18, defect 12: the record at 0.05 s arrives after the frame at
  // 0.2 s consumed the one at 0.1 s (the buffer is empty then).
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  push.Write(Oxts(kFramePeriodNs, OxtsLine()));
  push.Write(Gray8Frame(2 * kFramePeriodNs));
  push.Write(Oxts(kFramePeriodNs / 2, OxtsLine()));
  push.Write(Gray8Frame(3 * kFramePeriodNs));
  ASSERT_TRUE(push.WaitPoses(2));
  const v1::SessionStats stats = Stats(push.session().id());
  EXPECT_EQ(stats.oxts_bad_lines(), 1u);
  EXPECT_NE(stats.last_input_error().find("not after the previous record"), std::string::npos)
      << stats.last_input_error();
  EXPECT_EQ(push.poses().back().gps_used(), 1u) << "the late record never reached the estimator";
  EXPECT_TRUE(push.Close().ok());
}

TEST_F(ServerTest, OversizeMessageIsRejectedAndTheStreamEnds) {
  server_->Shutdown();
  ServerConfig c = LoopbackConfig(dir_ / "work");
  c.max_receive_mb = 1;
  StartServer(c);
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  v1::PushRequest big = Gray8Frame(kFramePeriodNs);
  big.mutable_frame()->set_left(std::string(2 * 1024 * 1024, 'x'));
  push.Write(big);
  const grpc::Status s = push.Close();
  EXPECT_EQ(s.error_code(), grpc::RESOURCE_EXHAUSTED) << s.error_message();
  EXPECT_EQ(RunCli(port_, {"health"}).out, "SERVING\n");
}

TEST_F(ServerTest, KittiDriveFromSharedDataSkipsMissingFramesAndCountsThem) {
  const std::filesystem::path drive =
      std::filesystem::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/2011_09_26_drive_unknown_extract";
  if (!std::filesystem::exists(drive)) GTEST_SKIP() << "shared KITTI excerpt not found at " << drive;
  std::unique_ptr<kitti::StereoDataset> dataset;
  ASSERT_NO_THROW(dataset = kitti::OpenDataset(drive)) << "the reader must open the excerpt";
  constexpr int64_t kLast = 30;
  uint64_t missing = 0;
  for (size_t i = 0; i <= kLast; ++i) missing += dataset->has_stereo(i) ? 0 : 1;
  const CliResult r = RunCli(port_, {"session", "start", "--kitti", drive.string(), "--last", std::to_string(kLast),
                                     "--history", "1000"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  const auto csv = dir_ / "kitti.csv";
  const CliResult sub = RunCli(port_, {"subscribe", id, "--from-start", "--format", "csv", "--out", csv.string()});
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  const v1::SessionStats stats = Stats(id);
  EXPECT_EQ(stats.frames_in(), static_cast<uint64_t>(kLast + 1));
  EXPECT_EQ(stats.frames_skipped() + stats.frames_corrupt(), missing);
  const std::string text = Slurp(csv);
  EXPECT_EQ(static_cast<uint64_t>(std::count(text.begin(), text.end(), '\n')), stats.frames_processed() + 1);
}

TEST_F(ServerTest, TokenIsRequiredWhenConfigured) {
  server_->Shutdown();
  ServerConfig c = LoopbackConfig(dir_ / "work");
  c.token = "s3cret";
  StartServer(c);
  CliResult r = RunCli(port_, {"session", "list"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAUTHENTICATED: missing"), std::string::npos) << r.err;
  r = RunCli(port_, {"session", "list"}, {"--token", "wrong"});
  EXPECT_NE(r.err.find("UNAUTHENTICATED: invalid bearer token"), std::string::npos) << r.err;
  r = RunCli(port_, {"session", "list"}, {"--token", "s3cret"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = RunCli(port_, {"stats", "s1"}, {"--token", "s3cret"});
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;  // authenticated, then looked up
}

TEST_F(ServerTest, TlsWithSelfSignedCertificate) {
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("openssl"), "openssl not installed");
  const auto cert = dir_ / "cert.pem", key = dir_ / "key.pem";
  const CliResult gen = RunShell("openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=localhost -addext "
                                 "subjectAltName=IP:127.0.0.1,DNS:localhost -keyout " +
                                 key.string() + " -out " + cert.string());
  ASSERT_EQ(gen.exit_code, 0) << gen.err;
  server_->Shutdown();
  ServerConfig c = LoopbackConfig(dir_ / "work");
  c.tls_cert_file = cert.string();
  c.tls_key_file = key.string();
  StartServer(c);
  CliResult r = RunCli(port_, {"health"}, {"--tls-ca", cert.string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "SERVING\n");
  r = RunCli(port_, {"session", "list"}, {"--timeout-s", "3"});  // plaintext client against TLS
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;
}

// The real locaid-server binary: SIGTERM ends open streams with a status and
// the process exits (bounded wait; the 2 s target is measured in bench/).
TEST(ServerProcess, SigtermEndsStreamsAndExits) {
  const ScopedTempDir dir("sigterm");
  const auto port_file = dir / "port";
  const std::string bin = std::string(LOCAID_BIN_DIR) + "/locaid-server";
  const std::string pf = port_file.string(), work = (dir / "work").string();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(bin.c_str(), bin.c_str(), "--listen", "127.0.0.1:0", "--port-file", pf.c_str(), "--work-dir", work.c_str(),
          "--shutdown-grace-s", "1", static_cast<char*>(nullptr));
    _exit(127);
  }
  int port = 0;
  for (int i = 0; i < 500 && port == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::ifstream in(port_file);
    in >> port;
  }
  ASSERT_GT(port, 0) << "server did not write its port";
  EXPECT_EQ(RunCli(port, {"health"}).out, "SERVING\n");
  // Open a push stream (a live session) if the server can localize; else a
  // plain pose stream on an unknown session is enough to see the exit.
  auto stub = MakeStub(port);
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 30);
  auto stream = stub->PushSensorData(&ctx);
  v1::PushRequest start;
  *start.mutable_start()->mutable_live() = SmallCamera();
  stream->Write(start);
  v1::PushResponse first;
  const bool live = stream->Read(&first);
  ASSERT_EQ(kill(pid, SIGTERM), 0);
  v1::PushResponse r;
  while (stream->Read(&r)) {
  }
  const grpc::Status s = stream->Finish();
  if (live) {
    EXPECT_EQ(s.error_code(), grpc::UNAVAILABLE) << s.error_message();
  }
  int status = 0;
  pid_t done = 0;
  for (int i = 0; i < 1000 && done == 0; ++i) {  // at most 10 s
    done = waitpid(pid, &status, WNOHANG);
    if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (done == 0) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    FAIL() << "locaid-server did not exit after SIGTERM";
  }
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

}  // namespace
}  // namespace locaid::server::testing
