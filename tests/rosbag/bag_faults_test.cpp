// What a real recording gets wrong, in a bag written message by message
// here (record::McapWriter, output::CdrWriter): a fix with status FIX but a
// NaN position, NO_FIX, an IMU sample whose stamp goes back, a cut CDR
// message, an image whose size disagrees with its camera_info, a channel
// without a schema, log times out of stamp order; and an antenna lever arm
// in /tf_static. The source skips and
// counts each; nothing stops the run. (Bags from the official libraries:
// bag_source_test.cpp.)
#include "output/cdr_writer.hpp"
#include "pipeline/bag_frame_source.hpp"
#include "pipeline/cli_support.hpp"
#include "record/mcap_writer.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cmath>
#include <limits>
#include <map>
#include <string>

namespace locaid {
namespace {

using output::CdrWriter;
using test_support::ScopedTempDir;

constexpr int kW = 64, kH = 48;
constexpr int64_t kT0 = 1'700'000'000'000'000'000;

void Header(CdrWriter& w, int64_t t_ns, const std::string& frame) {
  w.Int32(static_cast<int32_t>(t_ns / 1'000'000'000));
  w.Uint32(static_cast<uint32_t>(t_ns % 1'000'000'000));
  w.String(frame);
}

std::string CameraInfo(int64_t t, const std::string& frame, double tx) {
  CdrWriter w;
  Header(w, t, frame);
  w.Uint32(kH);
  w.Uint32(kW);
  w.String("plumb_bob");
  w.SequenceLength(5);
  for (int i = 0; i < 5; ++i) w.Float64(0);
  for (double v : {50.0, 0.0, 32.0, 0.0, 50.0, 24.0, 0.0, 0.0, 1.0}) w.Float64(v);
  for (double v : {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}) w.Float64(v);
  for (double v : {50.0, 0.0, 32.0, tx, 0.0, 50.0, 24.0, 0.0, 0.0, 0.0, 1.0, 0.0}) w.Float64(v);
  for (int i = 0; i < 6; ++i) w.Uint32(0);
  w.Bool(false);
  return w.data();
}

std::string Image(int64_t t, const std::string& frame, int width) {
  CdrWriter w;
  Header(w, t, frame);
  w.Uint32(kH);
  w.Uint32(static_cast<uint32_t>(width));
  w.String("mono8");
  w.Uint8(0);
  w.Uint32(static_cast<uint32_t>(width));
  w.SequenceLength(static_cast<size_t>(width * kH));
  cv::Mat noise(kH, width, CV_8UC1);
  cv::randu(noise, 0, 255);
  for (int i = 0; i < width * kH; ++i) w.Uint8(noise.data[i]);
  return w.data();
}

std::string Imu(int64_t t) {
  CdrWriter w;
  Header(w, t, "imu");
  for (double v : {0.0, 0.0, 0.0, 1.0}) w.Float64(v);
  w.Float64(-1);
  for (int i = 0; i < 8; ++i) w.Float64(0);
  for (int block = 0; block < 2; ++block) {
    for (double v : {0.0, 0.0, block == 0 ? 0.0 : 9.81}) w.Float64(v);
    for (int i = 0; i < 9; ++i) w.Float64(0);
  }
  return w.data();
}

std::string Fix(int64_t t, int8_t status, double lat) {
  CdrWriter w;
  Header(w, t, "gps");
  w.Int8(status);
  w.Uint16(1);
  for (double v : {lat, 8.3, 110.0}) w.Float64(v);
  for (int i = 0; i < 9; ++i) w.Float64(i % 4 == 0 ? 4.0 : 0.0);
  w.Uint8(2);
  return w.data();
}

std::string TfStatic(int64_t t) {
  CdrWriter w;
  w.SequenceLength(2);
  Header(w, t, "imu");
  w.String("cam_l");
  for (double v : {0.0, 0.0, 0.0}) w.Float64(v);
  // The optical frame (z forward, x right) in a body frame x forward, y left.
  for (double v : {-0.5, 0.5, -0.5, 0.5}) w.Float64(v);
  Header(w, t, "imu");
  w.String("gps");  // the antenna: 1.2 m ahead, 0.3 m left, 0.9 m up
  for (double v : {1.2, 0.3, 0.9}) w.Float64(v);
  for (double v : {0.0, 0.0, 0.0, 1.0}) w.Float64(v);
  return w.data();
}

TEST(BagFaults, EachFaultIsSkippedAndCountedAndTheRunGoesOn) {
  ScopedTempDir dir("bag_faults");
  const auto path = dir.path() / "faults.mcap";
  {
    record::McapOptions options;
    options.profile = "ros2";
    record::McapWriter mcap(path, options);
    std::map<std::string, uint16_t> ch;
    const auto channel = [&](const std::string& topic, const std::string& type) {
      ch[topic] = mcap.AddChannel(mcap.AddSchema(type, "ros2msg", "# test"), topic, "cdr");
    };
    channel("/l/image_raw", "sensor_msgs/msg/Image");
    channel("/r/image_raw", "sensor_msgs/msg/Image");
    channel("/l/camera_info", "sensor_msgs/msg/CameraInfo");
    channel("/r/camera_info", "sensor_msgs/msg/CameraInfo");
    channel("/imu", "sensor_msgs/msg/Imu");
    channel("/fix", "sensor_msgs/msg/NavSatFix");
    channel("/tf_static", "tf2_msgs/msg/TFMessage");
    const uint16_t no_schema = mcap.AddChannel(0, "/raw_bytes", "cdr");
    const auto put = [&](const std::string& topic, int64_t stamp, const std::string& data, int64_t delay_ms = 20) {
      mcap.Write(ch.at(topic), static_cast<uint64_t>(stamp + delay_ms * 1'000'000),
                 static_cast<uint64_t>(stamp + delay_ms * 1'000'000), data);
    };
    put("/tf_static", kT0, TfStatic(kT0), 0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int k = 0; k < 30; ++k) {
      const int64_t t = kT0 + int64_t{k} * 100'000'000;
      // Images log later than the IMU of the same time: log order != stamp order.
      put("/l/camera_info", t, CameraInfo(t, "cam_l", 0), 60);
      put("/r/camera_info", t, CameraInfo(t, "cam_r", -50 * 0.5), 60);
      put("/l/image_raw", t, Image(t, "cam_l", k == 12 ? kW / 2 : kW), 60);  // frame 12: wrong size
      put("/r/image_raw", t + 1'000'000, Image(t + 1'000'000, "cam_r", kW), 65);
      for (int i = 0; i < 10; ++i) {
        const int64_t ti = t + int64_t{i} * 10'000'000;
        std::string imu = Imu(ti);
        if (k == 5 && i == 3) imu.resize(imu.size() / 2);  // cut CDR
        put("/imu", ti, imu, 5);
      }
      if (k == 8) put("/imu", t - 500'000'000, Imu(t - 500'000'000), 5);  // stamp goes back 0.5 s
      // Fixes: NaN with status FIX at k = 10, NO_FIX at k = 11, else good.
      put("/fix", t, Fix(t, k == 11 ? -1 : 0, k == 10 ? nan : 49.0 + k * 1e-6), 30);
      mcap.Write(no_schema, static_cast<uint64_t>(t), static_cast<uint64_t>(t), "\x00\x01\x00\x00");
    }
    mcap.Close();
  }

  pipeline::BagFrameSource source(path, {});
  EXPECT_EQ(source.topics().imu, "/imu");
  EXPECT_NEAR(source.camera().baseline_m, 0.5, 1e-12);
  // The lever arm from /tf_static, in the body (IMU) frame, through the camera.
  EXPECT_TRUE(source.gps_lever_arm_body_m().isApprox(Eigen::Vector3d(1.2, 0.3, 0.9), 1e-9))
      << source.gps_lever_arm_body_m().transpose();
  int frames = 0, corrupt = 0;
  std::string errors;
  for (;;) {
    const auto item = source.Next();
    if (item.kind == pipeline::SourceItem::Kind::kEnd) break;
    frames += item.kind == pipeline::SourceItem::Kind::kFrame;
    corrupt += item.kind == pipeline::SourceItem::Kind::kCorrupt;
    if (!item.error.empty()) errors += item.error + "\n";
    for (const auto& f : item.samples.gps) EXPECT_TRUE(std::isfinite(f.fix.lat_deg));  // never a NaN fix
  }
  const auto& s = source.stats();
  EXPECT_EQ(frames, 29);
  EXPECT_EQ(corrupt, 1);
  EXPECT_EQ(s.bad_images, 1u);
  EXPECT_EQ(s.undecodable, 1u);
  EXPECT_EQ(s.late, 1u);
  EXPECT_EQ(s.no_fix, 2u);
  EXPECT_EQ(s.fixes, 28u);
  EXPECT_EQ(s.imu, 299u);
  EXPECT_NE(errors.find("faults.mcap: topic /l/image_raw, message"), std::string::npos) << errors;
  EXPECT_NE(errors.find("disagrees with its camera_info"), std::string::npos) << errors;
  EXPECT_NE(errors.find("topic /imu"), std::string::npos) << errors;
  bool noted = false;
  for (const auto& n : source.notes()) noted = noted || n.find("/raw_bytes") != std::string::npos;
  EXPECT_TRUE(noted) << "the channel without a schema is named in the notes";

  // The program as a user runs it: the run completes and says what it dropped.
  const auto r = test::RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-replay --bag " + path.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("1 bad images"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("2 no fix"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace locaid
