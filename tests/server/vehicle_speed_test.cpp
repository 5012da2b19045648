// Vehicle speed and vehicle options (issue 27) over gRPC on 127.0.0.1: pushed
// SpeedSample items are counted, bad ones refused by name (PushRejected, kind
// "speed") or, when their time goes back, counted as rejected sensor items;
// bad VehicleOptions and LiveSource.speed_sensor are INVALID_ARGUMENT before
// a session starts; and a synthetic drive with a scenario `speed:` sensor
// streams poses that fuse the readings and say what VO saw (vo_health).
#include "test_support.hpp"

#include <cmath>
#include <map>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kT0 = 1'700'000'000'000'000'000LL;
constexpr int64_t kFrameNs = 100'000'000;

v1::PushRequest Speed(int64_t t_ns, double speed_mps, double sigma_mps = 0.05) {
  v1::PushRequest r;
  r.mutable_speed()->set_t_ns(t_ns);
  r.mutable_speed()->set_speed_mps(speed_mps);
  r.mutable_speed()->set_sigma_mps(sigma_mps);
  return r;
}

class VehicleSpeedInput : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<LocalizationServer>(LoopbackConfig(dir_ / "work"), FakeFactory());
    stub_ = MakeStub(server_->port());
  }
  void TearDown() override { server_->Shutdown(); }
  grpc::Status Start(const v1::StartSessionRequest& req) {
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session out;
    return stub_->StartSession(&ctx, req, &out);
  }
  const ScopedTempDir dir_{"vehicle_speed"};  // the server's work_dir; outlives the server
  std::unique_ptr<LocalizationServer> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

TEST_F(VehicleSpeedInput, SpeedSamplesAreCountedAndBadOnesRefusedByName) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  // 5 frames, speed at 50 Hz before each.
  for (int f = 1; f <= 5; ++f) {
    const int64_t t = kT0 + f * kFrameNs;
    for (int k = 4; k >= 0; --k) ASSERT_TRUE(push.Write(Speed(t - k * kFrameNs / 5, 8.0)));
    ASSERT_TRUE(push.Write(Gray8Frame(t)));
  }
  ASSERT_TRUE(push.WaitPoses(5));
  const int64_t t_last = kT0 + 5 * kFrameNs;
  // Refused by value: answered on the stream, never counted.
  ASSERT_TRUE(push.Write(Speed(t_last + 1, std::nan(""))));
  ASSERT_TRUE(push.Write(Speed(t_last + 2, 500.0)));
  ASSERT_TRUE(push.Write(Speed(t_last + 3, 8.0, -1.0)));
  ASSERT_TRUE(push.Write(Speed(t_last + 4, 8.0, std::nan(""))));
  ASSERT_TRUE(push.Write(Speed(t_last + 5, -3.0)));  // reversing: a valid reading
  ASSERT_TRUE(push.Write(Gray8Frame(t_last + kFrameNs)));
  ASSERT_TRUE(push.WaitPoses(6));
  const grpc::Status end = push.Close();
  ASSERT_TRUE(end.ok()) << end.error_message();

  std::map<std::string, std::string> reasons;
  for (const auto& r : push.rejected()) reasons[r.kind() + std::to_string(r.index())] = r.reason();
  ASSERT_EQ(reasons.size(), 4u);
  // Items 0-24 are the 25 good readings.
  EXPECT_EQ(reasons["speed25"], "speed_mps: must be finite and within 100 m/s, got nan");
  EXPECT_EQ(reasons["speed26"], "speed_mps: must be finite and within 100 m/s, got 500");
  EXPECT_EQ(reasons["speed27"], "sigma_mps: must be > 0 (or 0 for the default), got -1");
  EXPECT_EQ(reasons["speed28"], "sigma_mps: must be > 0 (or 0 for the default), got nan");

  const v1::SessionStats stats = GetStats(stub_.get(), id);
  EXPECT_EQ(stats.speed_samples(), 26u) << "25 + the reversing one; refused ones never reach the session";
  EXPECT_EQ(stats.sensor_items_rejected(), 0u);
}

TEST_F(VehicleSpeedInput, ASpeedSampleGoingBackInTimeIsCountedAsRejected) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  ASSERT_TRUE(push.Write(Speed(kT0 + 50'000'000, 8.0)));
  ASSERT_TRUE(push.Write(Gray8Frame(kT0 + kFrameNs)));
  ASSERT_TRUE(push.WaitPoses(1));
  ASSERT_TRUE(push.Write(Speed(kT0 + 150'000'000, 8.0)));
  ASSERT_TRUE(push.Write(Speed(kT0 + 120'000'000, 8.0)));  // before the previous one
  ASSERT_TRUE(push.Write(Speed(kT0 + 150'000'000, 8.0)));  // the same time again
  ASSERT_TRUE(push.Write(Gray8Frame(kT0 + 2 * kFrameNs)));
  ASSERT_TRUE(push.WaitPoses(2));
  ASSERT_TRUE(push.Close().ok());
  EXPECT_TRUE(push.rejected().empty()) << "valid values: not refused on the stream";
  const v1::SessionStats stats = GetStats(stub_.get(), id);
  EXPECT_EQ(stats.speed_samples(), 4u);
  EXPECT_EQ(stats.sensor_items_rejected(), 2u);
  EXPECT_NE(stats.last_input_error().find("pushed speed sample"), std::string::npos) << stats.last_input_error();
  EXPECT_NE(stats.last_input_error().find("not after the previous sample"), std::string::npos)
      << stats.last_input_error();
}

TEST_F(VehicleSpeedInput, BadVehicleOptionsAndSpeedSensorAreInvalidArgument) {
  v1::StartSessionRequest req;
  *req.mutable_live() = SmallCamera();
  for (int i = 0; i < 8; ++i) req.mutable_vehicle()->add_r_vehicle_body(i % 4 == 0 ? 1.0 : 0.0);
  grpc::Status s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "vehicle.R_vehicle_body: expected 0 or 9 values (row-major 3x3), got 8");

  req.mutable_vehicle()->clear_r_vehicle_body();
  for (double v : {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0}) req.mutable_vehicle()->add_r_vehicle_body(v);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "vehicle.R_vehicle_body: not a rotation (R^T R must be I to 1e-6, det +1)");

  req.mutable_vehicle()->clear_r_vehicle_body();  // a reflection: orthogonal, det -1
  for (double v : {1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0}) req.mutable_vehicle()->add_r_vehicle_body(v);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("not a rotation"), std::string::npos) << s.error_message();

  req.mutable_vehicle()->clear_r_vehicle_body();
  for (double v : {1.0, 0.0, 0.0, 0.0, std::nan(""), 0.0, 0.0, 0.0, 1.0}) req.mutable_vehicle()->add_r_vehicle_body(v);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "vehicle.R_vehicle_body: values must be finite");

  req.clear_vehicle();
  req.mutable_live()->mutable_speed_sensor()->set_sigma_mps(-0.1);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "live.speed_sensor.sigma_mps: must be finite and >= 0");
  req.mutable_live()->mutable_speed_sensor()->set_sigma_mps(0.05);
  req.mutable_live()->mutable_speed_sensor()->set_scale_factor_sigma(0.7);
  s = Start(req);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "live.speed_sensor.scale_factor_sigma: must be <= 0.5");

  // Good options start a session: a 90 degree yaw mounting, constraints off, a speed sensor.
  req.mutable_live()->mutable_speed_sensor()->set_scale_factor_sigma(0.01);
  req.mutable_live()->mutable_speed_sensor()->set_rate_hz(50);
  for (double v : {0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0}) req.mutable_vehicle()->add_r_vehicle_body(v);
  req.mutable_vehicle()->set_constraints_off(true);
  s = Start(req);
  EXPECT_TRUE(s.ok()) << s.error_message();
}

// The real server process and filter on a rendered synthetic drive whose
// scenario has a speed sensor.
TEST(VehicleSpeedSession, ScenarioSpeedSensorIsFusedAndPosesCarryVoHealth) {
  constexpr int kFrames = 150;  // 15 s at 10 Hz: the filter initialises within it
  const ScopedTempDir dir("vehicle_speed_session");  // outlives the server
  ServerProcess server(dir.path() / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  auto stub = v1::Localization::NewStub(server.NewChannel());
  std::string error;
  const fs::path drive = RenderSynthDrive(dir.path() / "drive", kFrames, 3, 320, 96, &error);
  ASSERT_FALSE(drive.empty()) << error;
  v1::StartSessionRequest req;
  req.mutable_kitti()->set_path(drive.string());
  req.set_playback_rate(0);
  req.mutable_scenario()->set_yaml("name: speedy\nspeed: {rate_hz: 50, sigma_mps: 0.05, scale_error: 0.005}\n");
  v1::Session session;
  {
    grpc::ClientContext ctx;
    SetDeadline(&ctx, 30);
    const grpc::Status st = stub->StartSession(&ctx, req, &session);
    ASSERT_TRUE(st.ok()) << st.error_message();
  }
  PoseCollector collector(server.NewChannel(1), session.id(), true);
  ASSERT_TRUE(collector.WaitDone(180)) << "the session did not end";
  const std::vector<v1::PoseUpdate> poses = collector.poses();
  ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
  uint32_t previous_used = 0;
  int tracking = 0, grew = 0;
  for (const v1::PoseUpdate& p : poses) {
    EXPECT_NE(p.vo_health(), v1::VO_HEALTH_UNSPECIFIED) << "frame " << p.frame_index();
    if (p.vo_status() == v1::VO_STATUS_OK) {
      EXPECT_EQ(p.vo_health(), v1::VO_HEALTH_TRACKING) << "frame " << p.frame_index();
    }
    if (p.vo_health() == v1::VO_HEALTH_TRACKING) ++tracking;
    EXPECT_GE(p.speed_samples_used(), previous_used) << "cumulative, frame " << p.frame_index();
    if (p.speed_samples_used() > previous_used) ++grew;
    previous_used = p.speed_samples_used();
    EXPECT_TRUE(std::isfinite(p.speed_scale_error()));
  }
  EXPECT_GE(tracking, kFrames / 2) << "the synthetic drive tracks";
  EXPECT_GT(poses.back().speed_samples_used(), 100u) << "50 Hz readings once the filter is initialised";
  EXPECT_GT(grew, 30) << "the count grows frame after frame";
  EXPECT_NE(poses.back().mode(), v1::MODE_DEAD_RECKONING) << "GPS and VO are fine on this drive";
  const v1::SessionStats stats = GetStats(stub.get(), session.id());
  EXPECT_EQ(stats.speed_samples(), 0u) << "speed_samples counts pushed readings; a scenario sensor pushes none";
}

}  // namespace
}  // namespace locaid::server::testing
