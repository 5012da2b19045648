// InjectCameraFault against the real locaid-server on 127.0.0.1: a window
// injected with the real CLI drops the images of its frames (VO LOST there
// and only there), a scenario's `camera:` list does the same, bad requests
// are INVALID_ARGUMENT naming the field, unknown sessions NOT_FOUND, stopped
// ones FAILED_PRECONDITION (as InjectOutage); `locaid subscribe --format
// csv` records what the cameras gave VO (vo_health).
#include "test_support.hpp"

#include <cmath>
#include <functional>
#include <sstream>
#include <limits>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 60;                 // 6 s at 10 Hz
constexpr int64_t kNsPerS = 1'000'000'000;
// The fault window, s from the first frame.
constexpr double kWindowStartS = 2.5, kWindowDurationS = 1.0;

class CameraFaultRequests : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = v1::Localization::NewStub(server_->NewChannel());
  }
  // A session on a rendered 320x96 synthetic drive at `rate` x real time.
  v1::Session StartDrive(double rate, const std::string& scenario_yaml = "") {
    std::string error;
    if (drive_.empty()) drive_ = RenderSynthDrive(dir_ / "drive", kFrames, 3, 320, 96, &error);
    EXPECT_FALSE(drive_.empty()) << error;
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    v1::StartSessionRequest req;
    req.mutable_kitti()->set_path(drive_.string());
    req.set_playback_rate(rate);
    if (!scenario_yaml.empty()) req.mutable_scenario()->set_yaml(scenario_yaml);
    v1::Session s;
    const grpc::Status st = stub_->StartSession(&ctx, req, &s);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return s;
  }
  grpc::Status Inject(const v1::InjectCameraFaultRequest& req) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 10);
    v1::Session out;
    return stub_->InjectCameraFault(&ctx, req, &out);
  }
  // Every pose's VO status, the session's poses from the start to its end.
  std::vector<v1::PoseUpdate> AllPoses(const std::string& id) {
    PoseCollector poses(server_->NewChannel(1), id, true);
    EXPECT_TRUE(poses.WaitDone(120)) << "the session did not end";
    return poses.poses();
  }
  // Checks that the frames inside the window, and only most of the others,
  // are LOST (the synthetic drive tracks outside it).
  void ExpectLostExactlyInWindow(const std::vector<v1::PoseUpdate>& poses) {
    ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
    const int64_t t0 = poses.front().t_ns();
    int in_window = 0, tracked_outside = 0;
    for (const v1::PoseUpdate& p : poses) {
      const double t_s = static_cast<double>(p.t_ns() - t0) / kNsPerS;
      if (t_s >= kWindowStartS + 1e-3 && t_s < kWindowStartS + kWindowDurationS - 1e-3) {
        ++in_window;
        EXPECT_EQ(p.vo_status(), v1::VO_STATUS_LOST) << "frame " << p.frame_index() << " at " << t_s << " s";
      } else if (p.vo_status() != v1::VO_STATUS_LOST) {
        ++tracked_outside;
      }
    }
    EXPECT_GE(in_window, 9);
    EXPECT_GE(tracked_outside, (kFrames - in_window) / 2) << "VO should track outside the window";
  }

  const ScopedTempDir dir_{"camera_fault"};  // outlives the server
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
  fs::path drive_;
};

TEST_F(CameraFaultRequests, WindowInjectedWithTheCliDropsTheImagesOfItsFrames) {
  // Real time: the window (2.5 s after the first frame) is well ahead of the RPC.
  const v1::Session session = StartDrive(1.0);
  const CliResult r = RunCli(server_->port(), {"camera-fault", "window", session.id(), "--kind", "drop", "--start",
                                               std::to_string(kWindowStartS), "--duration",
                                               std::to_string(kWindowDurationS)});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ExpectLostExactlyInWindow(AllPoses(session.id()));
}

TEST_F(CameraFaultRequests, ScenarioCameraListDropsTheImagesOfItsWindow) {
  const v1::Session session = StartDrive(0, "name: cams\ncamera: [{start_s: 2.5, duration_s: 1, fault: drop}]\n");
  ExpectLostExactlyInWindow(AllPoses(session.id()));
}

// `locaid subscribe --format csv` says what the cameras gave VO, as the
// print format does: a camera the scenario freezes 2.5-3.5 s is FROZEN in
// the CSV's vo_health there and TRACKING around it, line for line what
// `--format print` shows for the same poses.
TEST_F(CameraFaultRequests, SubscribeCsvHasTheVoHealthThePrintFormatShows) {
  const v1::Session session = StartDrive(0, "name: cams\ncamera: [{start_s: 2.5, duration_s: 1, fault: frozen}]\n");
  const fs::path csv = dir_ / "poses.csv";
  const CliResult recorded =
      RunCli(server_->port(), {"subscribe", session.id(), "--from-start", "--format", "csv", "--out", csv.string()});
  ASSERT_EQ(recorded.exit_code, 0) << recorded.err;
  const CliResult printed = RunCli(server_->port(), {"subscribe", session.id(), "--from-start"});
  ASSERT_EQ(printed.exit_code, 0) << printed.err;

  const std::string text = Slurp(csv);
  const std::vector<std::string> health = CsvColumn(text, "vo_health"), t_s = CsvColumn(text, "t_s");
  ASSERT_EQ(health.size(), static_cast<size_t>(kFrames)) << text.substr(0, text.find('\n'));
  std::vector<std::string> shown;
  std::istringstream lines(printed.out);
  for (std::string line; std::getline(lines, line);) {
    const size_t at = line.find(" vo_health=");
    ASSERT_NE(at, std::string::npos) << line;
    const size_t from = at + std::string(" vo_health=").size();
    shown.push_back(line.substr(from, line.find(' ', from) - from));
  }
  EXPECT_EQ(health, shown);

  int frozen = 0, tracking_outside = 0;
  for (size_t i = 0; i < health.size(); ++i) {
    const double t = std::stod(t_s[i]) - std::stod(t_s.front());
    if (t >= kWindowStartS + 1e-3 && t < kWindowStartS + kWindowDurationS - 1e-3) {
      EXPECT_EQ(health[i], "FROZEN") << "pose " << i << " at " << t << " s";
      ++frozen;
    } else if (health[i] == "TRACKING") {
      ++tracking_outside;
    }
  }
  EXPECT_GE(frozen, 9);
  EXPECT_GE(tracking_outside, (kFrames - frozen) / 2) << "VO should track outside the window";
}

TEST_F(CameraFaultRequests, BadRequestsAreInvalidArgumentNamingTheField) {
  const v1::Session session = StartDrive(1.0);
  using Req = v1::InjectCameraFaultRequest;
  // A request for `kind` with `set` applied to its fault.
  const auto request = [&](Req::Action action, v1::CameraFault::Kind kind,
                           const std::function<void(v1::CameraFault*)>& set = nullptr) {
    v1::InjectCameraFaultRequest req;
    req.set_session_id(session.id());
    req.set_action(action);
    req.mutable_fault()->set_kind(kind);
    if (set) set(req.mutable_fault());
    return req;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  struct Case {
    v1::InjectCameraFaultRequest req;
    std::string expected;
  };
  v1::InjectCameraFaultRequest no_fault = request(Req::WINDOW, v1::CameraFault::DROP);
  no_fault.clear_fault();
  const std::vector<Case> cases = {
      {request(Req::START_NOW, v1::CameraFault::KIND_UNSPECIFIED),
       "fault.kind: must be DARK, NOISE, BLUR, FROZEN, DROP, LEFT_ONLY or RIGHT_ONLY, got 0"},
      {request(Req::ACTION_UNSPECIFIED, v1::CameraFault::DARK), "action: must be START_NOW, STOP_NOW or WINDOW"},
      {request(Req::START_NOW, v1::CameraFault::DARK, [](auto* f) { f->set_gain(1.5); }),
       "fault.gain: must be in (0, 1], got 1.5"},
      {request(Req::START_NOW, v1::CameraFault::NOISE, [&](auto* f) { f->set_noise_dn(nan); }),
       "fault.noise_dn: must be in [0, 255], got nan"},
      {request(Req::START_NOW, v1::CameraFault::BLUR, [](auto* f) { f->set_blur_sigma_px(-2); }),
       "fault.blur_sigma_px: must be in (0, 50], got -2"},
      {request(Req::START_NOW, v1::CameraFault::FROZEN, [](auto* f) { f->set_gain(0.1); }),
       "fault.gain: applies to DARK only, got 0.1 for FROZEN"},
      {request(Req::START_NOW, v1::CameraFault::DROP, [](auto* f) { f->set_start_s(3); }),
       "fault.start_s: applies to WINDOW only"},
      {request(Req::START_NOW, v1::CameraFault::DROP, [&](auto* f) { f->set_duration_s(inf); }),
       "fault.duration_s: must be in [0, 1e6] s, got inf"},
      {request(Req::WINDOW, v1::CameraFault::DROP, [](auto* f) { f->set_start_s(1); }),
       "fault.duration_s: a WINDOW needs duration_s > 0"},
      {no_fault, "fault: required for START_NOW and WINDOW"},
  };
  for (const Case& c : cases) {
    const grpc::Status s = Inject(c.req);
    EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << c.expected << " / " << s.error_message();
    EXPECT_NE(s.error_message().find(c.expected), std::string::npos) << s.error_message();
  }
  // Good ones: a dark fault with its defaults now, and stop.
  EXPECT_TRUE(Inject(request(Req::START_NOW, v1::CameraFault::DARK)).ok());
  v1::InjectCameraFaultRequest stop;
  stop.set_session_id(session.id());
  stop.set_action(v1::InjectCameraFaultRequest::STOP_NOW);
  EXPECT_TRUE(Inject(stop).ok());
  // The CLI refuses an unknown kind before calling.
  const CliResult r = RunCli(server_->port(), {"camera-fault", "start", session.id(), "--kind", "fog"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
}

TEST_F(CameraFaultRequests, UnknownSessionIsNotFoundStoppedIsFailedPrecondition) {
  v1::InjectCameraFaultRequest req;
  req.set_session_id("s-nope");
  req.set_action(v1::InjectCameraFaultRequest::STOP_NOW);
  EXPECT_EQ(Inject(req).error_code(), grpc::NOT_FOUND);
  const v1::Session session = StartDrive(1.0);
  const CliResult stopped = RunCli(server_->port(), {"session", "stop", session.id()});
  ASSERT_EQ(stopped.exit_code, 0) << stopped.err;
  req.set_session_id(session.id());
  const grpc::Status s = Inject(req);
  EXPECT_EQ(s.error_code(), grpc::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("InjectCameraFault"), std::string::npos) << s.error_message();
}

}  // namespace
}  // namespace locaid::server::testing
