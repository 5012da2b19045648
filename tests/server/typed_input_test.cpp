// Typed live input (issue 20): ImuSample and GpsFix messages pushed beside the
// frames. The real server on 127.0.0.1 with the fake estimator: these tests
// check the service's contract (validation, ordering, counters, the no-fix
// outage); tests/server/gpsd_test.cpp runs the real filter with a real gpsd.
#include "server/live_source_request.hpp"
#include "test_support.hpp"

#include <cmath>

namespace locaid::server::testing {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000'000LL;  // UTC, as a receiver's fixes are
constexpr int64_t kFrameNs = 100'000'000;

v1::PushRequest Imu(int64_t t_ns, double az = 9.81) {
  v1::PushRequest r;
  auto* m = r.mutable_imu();
  m->set_t_ns(t_ns);
  m->mutable_accel_mps2()->set_z(az);
  m->mutable_gyro_radps()->set_z(0.01);
  return r;
}

v1::PushRequest Fix(int64_t t_ns, v1::GpsFixType type = v1::GPS_FIX_3D, double lat = 49.0) {
  v1::PushRequest r;
  auto* g = r.mutable_gps();
  g->set_t_ns(t_ns);
  g->set_fix_type(type);
  g->set_latitude_deg(lat);
  g->set_longitude_deg(8.4);
  g->set_altitude_m(110);
  g->set_sigma_horizontal_m(1.5);
  return r;
}

class TypedInput : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<LocalizationServer>(LoopbackConfig(dir_ / "work"), FakeFactory());
    stub_ = MakeStub(server_->port());
  }
  void TearDown() override { server_->Shutdown(); }
  const ScopedTempDir dir_{"typed_input"};  // the server's work_dir; outlives the server
  std::unique_ptr<LocalizationServer> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

TEST_F(TypedInput, SamplesAndFixesReachTheFilterAndBadOnesAreRefusedByName) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  const std::string id = push.session().id();
  // 10 frames, IMU at 100 Hz, a fix every 5th frame.
  for (int f = 1; f <= 10; ++f) {
    const int64_t t = kT0 + f * kFrameNs;
    for (int k = 9; k >= 0; --k) ASSERT_TRUE(push.Write(Imu(t - k * kFrameNs / 10)));
    if (f % 5 == 0) {
      ASSERT_TRUE(push.Write(Fix(t - 5 * kFrameNs)));
    }
    ASSERT_TRUE(push.Write(Gray8Frame(t)));
  }
  ASSERT_TRUE(push.WaitPoses(10));
  const int64_t t_last = kT0 + 10 * kFrameNs;
  // Refused by value: the stream answers each and goes on.
  v1::PushRequest nan_imu = Imu(t_last + 1);
  nan_imu.mutable_imu()->mutable_accel_mps2()->set_x(std::nan(""));
  ASSERT_TRUE(push.Write(nan_imu));
  ASSERT_TRUE(push.Write(Fix(t_last + 2, v1::GPS_FIX_3D, 91.0)));
  v1::PushRequest short_cov = Fix(t_last + 3);
  for (int i = 0; i < 8; ++i) short_cov.mutable_gps()->add_covariance_enu_m2(1.0);
  ASSERT_TRUE(push.Write(short_cov));
  v1::PushRequest neg_sigma = Fix(t_last + 4);
  neg_sigma.mutable_gps()->set_sigma_vertical_m(-2);
  ASSERT_TRUE(push.Write(neg_sigma));
  // Refused by order / age: counted.
  ASSERT_TRUE(push.Write(Imu(t_last - 5 * kFrameNs)));             // before the newest sample
  ASSERT_TRUE(push.Write(Fix(t_last - 2'000'000'000LL)));           // 2 s older than the newest frame
  v1::PushRequest nan_cov = Fix(t_last - 100'000'000LL);               // 0.1 s late: fused
  for (int i = 0; i < 9; ++i) nan_cov.mutable_gps()->add_covariance_enu_m2(std::nan(""));  // not stated
  ASSERT_TRUE(push.Write(nan_cov));
  ASSERT_TRUE(push.Write(Gray8Frame(t_last + kFrameNs)));
  ASSERT_TRUE(push.WaitPoses(11));
  const grpc::Status end = push.Close();
  ASSERT_TRUE(end.ok()) << end.error_message();

  std::map<std::string, std::string> reasons;
  for (const auto& r : push.rejected()) reasons[r.kind() + std::to_string(r.index())] = r.reason();
  ASSERT_EQ(reasons.size(), 4u);
  EXPECT_EQ(reasons["imu100"], "accel_mps2: not finite");
  EXPECT_EQ(reasons["gps2"], "latitude_deg: must be in [-90, 90], got 91");
  EXPECT_EQ(reasons["gps3"], "covariance_enu_m2: expected 0 or 9 values, got 8");
  EXPECT_EQ(reasons["gps4"], "sigma_vertical_m: must be > 0 (or 0 for the default), got -2");

  const v1::SessionStats stats = GetStats(stub_.get(), id);
  EXPECT_EQ(stats.imu_samples(), 101u);  // 100 + the one out of order
  EXPECT_EQ(stats.sensor_items_rejected(), 1u);
  EXPECT_EQ(stats.gps_fixes_in(), 4u);  // 2 + the stale one + the late one
  EXPECT_EQ(stats.gps_fixes_late(), 1u);
  EXPECT_NE(stats.last_input_error().find("older than the newest frame"), std::string::npos)
      << stats.last_input_error();
  EXPECT_FALSE(stats.has_gpsd());
  // The fake filter counts the fixes it was given: 2 on time + 1 late; each
  // rides on the next pose, as the filter saw it.
  EXPECT_EQ(push.poses().back().gps_used(), 3u);
  int seen = 0;
  for (const auto& p : push.poses()) {
    for (const auto& f : p.gps_fixes()) {
      ++seen;
      EXPECT_LE(f.t_ns(), p.t_ns());
      EXPECT_DOUBLE_EQ(f.sigma_horizontal_m(), 1.5);
      EXPECT_DOUBLE_EQ(f.sigma_vertical_m(), 10.0);  // not stated: the API's default
    }
  }
  EXPECT_EQ(seen, 3);
}

TEST_F(TypedInput, ANoFixReportIsAnOutageUntilTheNextFix) {
  Pusher push(stub_.get(), "");
  ASSERT_TRUE(push.ok());
  int poses = 0;
  auto frame = [&](int f) {
    EXPECT_TRUE(push.Write(Gray8Frame(kT0 + f * kFrameNs)));
    EXPECT_TRUE(push.WaitPoses(static_cast<size_t>(++poses)));
  };
  frame(1);
  ASSERT_TRUE(push.Write(Fix(kT0 + 15 * kFrameNs / 10, v1::GPS_FIX_NONE, std::nan(""))));
  frame(2);
  frame(3);
  ASSERT_TRUE(push.Write(Fix(kT0 + 35 * kFrameNs / 10)));
  frame(4);
  ASSERT_TRUE(push.Close().ok());
  const auto p = push.poses();
  ASSERT_EQ(p.size(), 4u);
  EXPECT_FALSE(p[0].gps_outage_active());
  EXPECT_TRUE(p[1].gps_outage_active());
  EXPECT_TRUE(p[2].gps_outage_active());
  EXPECT_FALSE(p[3].gps_outage_active());
  const v1::SessionStats stats = GetStats(stub_.get(), push.session().id());
  EXPECT_EQ(stats.gps_no_fix(), 1u);
  EXPECT_EQ(stats.gps_fixes_in(), 2u);
}

TEST_F(TypedInput, LeverArmDelayAndGpsdSourceAreCheckedBeforeOk) {
  auto start = [&](const v1::LiveSource& live) {
    v1::StartSessionRequest req;
    *req.mutable_live() = live;
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session out;
    return stub_->StartSession(&ctx, req, &out);
  };
  v1::LiveSource live = SmallCamera();
  live.add_gps_antenna_body_m(1.0);
  live.add_gps_antenna_body_m(0.5);
  grpc::Status s = start(live);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "live.gps_antenna_body_m: expected 0 or 3 values (x, y, z), got 2");
  live.add_gps_antenna_body_m(std::nan(""));
  s = start(live);
  EXPECT_EQ(s.error_message(), "live.gps_antenna_body_m[2]: must be finite and within 10 m of the IMU");
  live = SmallCamera();
  live.set_max_gps_delay_s(11);
  s = start(live);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "live.max_gps_delay_s: must be in [0, 10] (0 = 0.5 s), got 11");
  // Finite values whose R R^T overflows (inf - inf = NaN, determinant +inf):
  // not a rotation, though no comparison with NaN is true.
  live = SmallCamera();
  for (double v : {1e200, 1e200, 0.0, 0.0, -1e200, 1e200, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0}) live.add_t_cam0_imu(v);
  s = start(live);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message(), "live.T_cam0_imu: rotation part is not orthonormal");
  live = SmallCamera();
  live.mutable_gps_source()->mutable_gpsd()->set_port(70000);
  s = start(live);
  EXPECT_EQ(s.error_message(), "live.gps_source.gpsd.port: must be in [1, 65535], got 70000");
  live.mutable_gps_source()->mutable_gpsd()->set_port(0);
  live.mutable_gps_source()->mutable_gpsd()->set_host("bad host");
  s = start(live);
  EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("not a host name or address"), std::string::npos) << s.error_message();
  // A gpsd nobody runs: the session starts and reports the refused connection.
  live.mutable_gps_source()->mutable_gpsd()->set_host("127.0.0.1");
  live.mutable_gps_source()->mutable_gpsd()->set_port(1);
  v1::StartSessionRequest req;
  *req.mutable_live() = live;
  grpc::ClientContext ctx;
  SetDeadline(&ctx);
  v1::Session session;
  ASSERT_TRUE(stub_->StartSession(&ctx, req, &session).ok());
  EXPECT_EQ(session.source(), "live+gpsd:127.0.0.1:1");
  const v1::SessionStats stats = WaitStats(stub_.get(), session.id(), 10,
                                           [](const v1::SessionStats& s) { return !s.gpsd().last_error().empty(); });
  EXPECT_FALSE(stats.gpsd().connected());
  EXPECT_EQ(stats.gpsd().connects(), 0u);
  EXPECT_NE(stats.gpsd().last_error().find("gpsd at 127.0.0.1:1: cannot connect"), std::string::npos)
      << stats.gpsd().last_error();
}

}  // namespace
}  // namespace locaid::server::testing

namespace locaid::server::testing {
namespace {

// A camera_info of KITTI's 2011_09_26 raw cam0 or cam1 (R = R_rect_0x).
std::string KittiCameraInfo(bool right) {
  return std::string("image_width: 1392\nimage_height: 512\n") +
         "camera_matrix: {rows: 3, cols: 3, data: [984.2439, 0, 690, 0, 980.8141, 233.1966, 0, 0, 1]}\n"
         "distortion_model: plumb_bob\n"
         "distortion_coefficients: {rows: 1, cols: 5, data: [-0.3728755, 0.2037299, 0.002219027, 0.001383707, "
         "-0.07233722]}\n"
         "rectification_matrix: {rows: 3, cols: 3, data: [0.9999239, 0.00983776, -0.007445048, -0.009869795, "
         "0.9999421, -0.004278459, 0.007402527, 0.004351614, 0.9999631]}\n" +
         (right ? "projection_matrix: {rows: 3, cols: 4, data: [721.5377, 0, 609.5593, -387.5744, 0, 721.5377, "
                  "172.854, 0, 0, 0, 1, 0]}\n"
                : "projection_matrix: {rows: 3, cols: 4, data: [721.5377, 0, 609.5593, 0, 0, 721.5377, 172.854, 0, "
                  "0, 0, 1, 0]}\n");
}

// With cameras the server reads, the camera model comes from camera_info,
// and a given extrinsic (of the raw left camera, as a ROS tf) is rotated
// into the rectified frame by camera_info's R; the default rig is not.
TEST(LiveSourceCameras, ModelFromCameraInfoAndExtrinsicIntoTheRectifiedFrame) {
  v1::LiveSource l;
  l.mutable_cameras()->set_left_pipeline("videotestsrc");
  l.mutable_cameras()->set_right_pipeline("videotestsrc");
  l.mutable_cameras()->set_left_camera_info(KittiCameraInfo(false));
  l.mutable_cameras()->set_right_camera_info(KittiCameraInfo(true));
  const Eigen::Isometry3d rig = Eigen::Isometry3d(Eigen::Translation3d(0.1, 0.2, 0.3));
  LiveSourceSetup out;
  ASSERT_EQ(LiveSourceFromProto(l, rig, &out), "");
  ASSERT_TRUE(out.cameras.has_value());
  EXPECT_DOUBLE_EQ(out.camera.camera.fx, 721.5377);
  EXPECT_NEAR(out.camera.camera.baseline_m, 387.5744 / 721.5377, 1e-12);
  EXPECT_LT(out.camera.camera.width, 1392) << "cropped to what both cameras see";
  EXPECT_TRUE(out.camera.T_cam0_imu.isApprox(rig, 1e-12)) << "the default rig as it is";

  for (int i = 0; i < 12; ++i) l.add_t_cam0_imu(i % 5 == 0 ? 1.0 : 0.0);  // identity, raw camera frame
  ASSERT_EQ(LiveSourceFromProto(l, rig, &out), "");
  Eigen::Matrix3d R_rect;
  R_rect << 0.9999239, 0.00983776, -0.007445048, -0.009869795, 0.9999421, -0.004278459, 0.007402527, 0.004351614,
      0.9999631;
  EXPECT_TRUE(out.camera.T_cam0_imu.linear().isApprox(R_rect, 1e-6)) << out.camera.T_cam0_imu.linear();

  l.set_fx(700);
  EXPECT_EQ(LiveSourceFromProto(l, rig, &out),
            "live.cameras: leave live.fx .. height 0: the camera model comes from the camera_info files");
}

}  // namespace
}  // namespace locaid::server::testing
