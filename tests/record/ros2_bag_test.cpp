// Ros2Recording's ROS 2 bags judged by the field's own libraries: @mcap/core
// reads the MCAP, @foxglove/rosmsg parses the ros2msg schemas stored in it and
// @foxglove/rosmsg2-serialization decodes every CDR message
// (js/read_ros2_bag.mjs, pinned in js/package-lock.json). Then the decoded
// values are compared with the PoseUpdates written. The pieces (CDR bytes,
// schema texts, the covariance mapping) are checked on their own first.
// The node tests skip when node is missing (fail when CI is set: needs_tool.hpp).
#include "ros2_bag_reader.hpp"
#include "output/cdr_writer.hpp"
#include "output/ros2_recording.hpp"
#include "output/ros2_schemas.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <random>

namespace {

namespace fs = std::filesystem;
namespace ft = locaid::foxglove::testing;
namespace out = locaid::output;
namespace v1 = locaid::v1;
using nlohmann::json;

constexpr int64_t kStartNs = 1'715'940'000'123'456'789;  // 2024-05-17, like a synthetic drive
constexpr int64_t kStepNs = 100'000'000;
constexpr double kTight = 1e-12;

TEST(CdrWriter, AlignsPrimitivesAfterTheEncapsulationHeader) {
  out::CdrWriter w;
  w.Uint8(7);
  w.Float64(1.0);  // 7 bytes of padding: offset 1 -> 8
  w.String("ab");  // u32 length 3 (NUL included) at offset 16, then "ab\0"
  w.Uint16(0x0102);  // 1 byte of padding: offset 23 -> 24
  w.Int8(-1);
  const std::string expected("\x00\x01\x00\x00"
                             "\x07\x00\x00\x00\x00\x00\x00\x00"
                             "\x00\x00\x00\x00\x00\x00\xf0\x3f"
                             "\x03\x00\x00\x00"
                             "ab\x00"
                             "\x00"
                             "\x02\x01"
                             "\xff",
                             31);
  EXPECT_EQ(w.data(), expected);
}

TEST(Ros2Schemas, OdometryDefinitionIsTheMsgTextThenEachDependencyOnce) {
  const std::string full = out::Ros2FullDefinition("nav_msgs/msg/Odometry");
  const std::string& odometry = out::Ros2MsgText("nav_msgs/Odometry");
  ASSERT_EQ(full.substr(0, odometry.size()), odometry);
  const std::string delimiter = "\n" + std::string(80, '=') + "\nMSG: ";
  // Depth first, each package's dependencies in sorted order (rosbag2's order).
  const std::vector<std::string> expected = {
      "geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose",  "geometry_msgs/Point",
      "geometry_msgs/Quaternion",         "geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist",
      "geometry_msgs/Vector3",            "std_msgs/Header",     "builtin_interfaces/Time"};
  std::vector<std::string> found;
  for (size_t at = full.find(delimiter); at != std::string::npos; at = full.find(delimiter, at + 1)) {
    const size_t name = at + delimiter.size();
    found.push_back(full.substr(name, full.find('\n', name) - name));
  }
  EXPECT_EQ(found, expected);
  EXPECT_NE(full.find("float64[36] covariance"), std::string::npos);
  EXPECT_THROW(out::Ros2FullDefinition("sensor_msgs/msg/Image"), std::invalid_argument);
}

// Roll, pitch, yaw of R = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Vector3d Rpy(const Eigen::Matrix3d& R) {
  return {std::atan2(R(2, 1), R(2, 2)), std::asin(-R(2, 0)), std::atan2(R(1, 0), R(0, 0))};
}

Eigen::Matrix3d FromRpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// The analytic Jacobian against central differences of the angles under the
// filter's perturbation R = Exp(dtheta) R_hat, over orientations a car and a
// drone take (and the edge cases: identity, yaw +-pi, pitch near +-90 deg).
TEST(Ros2Covariance, RpyJacobianMatchesNumericDifferences) {
  const std::vector<Eigen::Vector3d> cases = {{0, 0, 0},        {0, 0, M_PI - 1e-3}, {0, 0, -M_PI / 2},
                                              {0.1, -0.2, 2.5}, {-0.4, 0.3, -1.2},   {0.05, 1.4, 0.7},
                                              {2.0, -1.0, 3.0}};
  constexpr double kStep = 1e-6, kTolerance = 1e-6;
  for (const auto& rpy : cases) {
    const Eigen::Matrix3d R = FromRpy(rpy.x(), rpy.y(), rpy.z());
    const Eigen::Matrix3d J = out::RpyFromEnuAttitudeJacobian(R);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d d = Eigen::Vector3d::Unit(k) * kStep;
      const Eigen::Matrix3d plus = Eigen::AngleAxisd(d.norm(), d.normalized()).toRotationMatrix() * R;
      const Eigen::Matrix3d minus = Eigen::AngleAxisd(d.norm(), -d.normalized()).toRotationMatrix() * R;
      Eigen::Vector3d diff = Rpy(plus) - Rpy(minus);
      for (int i = 0; i < 3; ++i) diff[i] = std::remainder(diff[i], 2 * M_PI);
      EXPECT_LT((diff / (2 * kStep) - J.col(k)).norm(), kTolerance) << "rpy " << rpy.transpose() << " column " << k;
    }
  }
}

// A car heading north (yaw +90 deg): rotation about the map's x axis (roll)
// is the filter's attitude error about North, pitch is minus the error about
// East, yaw the error about Up; position stays E, N, U.
TEST(Ros2Covariance, HeadingNorthMapsTheAttitudeErrorIntoRosOrder) {
  out::Matrix6d P = out::Matrix6d::Zero();
  P.diagonal() << 1.0, 2.0, 3.0, 0.01, 0.02, 0.03;
  P(0, 3) = P(3, 0) = 0.004;  // E with attitude about E
  P(1, 4) = P(4, 1) = 0.005;  // N with attitude about N
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const out::Matrix6d ros = out::RosPoseCovariance(P, q);
  EXPECT_NEAR(ros(0, 0), 1.0, kTight);
  EXPECT_NEAR(ros(2, 2), 3.0, kTight);
  EXPECT_NEAR(ros(3, 3), 0.02, kTight);   // roll = about North
  EXPECT_NEAR(ros(4, 4), 0.01, kTight);   // pitch = -(about East)
  EXPECT_NEAR(ros(5, 5), 0.03, kTight);   // yaw = about Up
  EXPECT_NEAR(ros(0, 4), -0.004, kTight);  // x with pitch
  EXPECT_NEAR(ros(1, 3), 0.005, kTight);   // y with roll
  EXPECT_NEAR(ros(0, 3), 0.0, kTight);
  EXPECT_EQ(ros, ros.transpose());
}

TEST(Ros2Covariance, NearestSymmetricPsdRemovesNegativeEigenvalues) {
  out::Matrix6d m = out::Matrix6d::Identity();
  m(0, 1) = 4.0;  // symmetrised: [[1, 2], [2, 1]], eigenvalues 3 and -1
  m(1, 0) = 0.0;
  m(5, 5) = -1e-9;  // rounding below zero
  const out::Matrix6d psd = out::NearestSymmetricPsd(m);
  EXPECT_EQ(psd, psd.transpose());
  EXPECT_GE(Eigen::SelfAdjointEigenSolver<out::Matrix6d>(psd).eigenvalues().minCoeff(), -kTight);
  const out::Matrix6d spd = out::Matrix6d::Identity() * 2;
  EXPECT_EQ(out::NearestSymmetricPsd(spd), spd);  // a covariance that is fine stays as it is
}

// The i-th sample pose: LOST first (not initialised: no fix), then fused,
// heading north at 10 m/s with one fix a pose, every third refused.
v1::PoseUpdate SamplePose(int i) {
  v1::PoseUpdate p;
  p.set_session_id("sample");
  p.set_sequence(static_cast<uint64_t>(i));
  p.set_t_ns(kStartNs + i * kStepNs);
  p.set_mode(i == 0 ? v1::MODE_LOST : i % 3 == 0 ? v1::MODE_GPS_DEGRADED : v1::MODE_GPS_FUSED);
  p.mutable_position_enu_m()->set_x(0.5 * i);
  p.mutable_position_enu_m()->set_y(1.0 * i);
  p.mutable_position_enu_m()->set_z(0.1);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  p.mutable_orientation_enu_body()->set_w(q.w());
  p.mutable_orientation_enu_body()->set_z(q.z());
  p.mutable_velocity_enu_mps()->set_y(10.0);
  p.set_latitude_deg(49.0 + 1e-5 * i);
  p.set_longitude_deg(8.4);
  p.set_altitude_m(110.0);
  out::Matrix6d P = out::Matrix6d::Zero();
  P.diagonal() << 1.0 + i, 2.0, 3.0, 0.01, 0.02, 0.03;
  P(0, 1) = P(1, 0) = 0.5;
  P(0, 3) = P(3, 0) = 0.004;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) p.add_covariance(P(r, c));
  if (i > 0) {
    auto* f = p.add_gps_fixes();
    f->set_t_ns(kStartNs + i * kStepNs - 20'000'000);
    f->set_latitude_deg(49.0 + 1e-5 * i);
    f->set_longitude_deg(8.4);
    f->set_altitude_m(111.0);
    f->set_sigma_horizontal_m(1.5);
    f->set_sigma_vertical_m(3.0);
    f->set_used(i % 3 != 0);
    f->set_nis(i % 3 != 0 ? 1.0 : 40.0);
    f->set_gate(13.8);
  }
  return p;
}

using Ros2BagReadTest = out::testing::Ros2BagReaderTest;

TEST_F(Ros2BagReadTest, EveryMessageDecodesToWhatWasWritten) {
  constexpr int kPoses = 30;
  const fs::path file = dir_ / "sample.mcap";
  out::Ros2RecordingOptions options;
  options.T_body_cam0 = out::KittiRigTBodyCam0();
  {
    out::Ros2Recording bag(file, options);
    for (int i = 0; i < kPoses; ++i) bag.Add(SamplePose(i));
    bag.Close();
    EXPECT_EQ(bag.poses(), static_cast<uint64_t>(kPoses));
  }
  const ft::NodeRun run = out::testing::ReadRos2Bag(file, true);
  ASSERT_EQ(run.exit_code, 0) << run.text;
  const json& topics = run.out["topics"];
  EXPECT_EQ(run.out["profile"], "ros2");
  EXPECT_EQ(topics["/locaid/odometry"]["count"], kPoses);
  EXPECT_EQ(topics["/tf"]["count"], kPoses);
  EXPECT_EQ(topics["/locaid/status"]["count"], kPoses);
  EXPECT_EQ(topics["/locaid/fix"]["count"], kPoses - 1);  // none while LOST
  EXPECT_EQ(topics["/locaid/gps"]["count"], kPoses - 1);
  EXPECT_EQ(topics["/tf_static"]["count"], 1);
  EXPECT_EQ(topics["/locaid/odometry"]["type"], "nav_msgs/msg/Odometry");
  EXPECT_EQ(topics["/locaid/status"]["type"], "diagnostic_msgs/msg/DiagnosticArray");
  EXPECT_NE(topics["/tf_static"]["qos"].get<std::string>().find("durability: 1"), std::string::npos);

  const json& odometry = topics["/locaid/odometry"]["messages"];
  ASSERT_EQ(odometry.size(), static_cast<size_t>(kPoses));
  for (int i = 0; i < kPoses; ++i) {
    const v1::PoseUpdate p = SamplePose(i);
    const json& m = odometry[static_cast<size_t>(i)];
    EXPECT_EQ(m["header"]["stamp"]["sec"].get<int64_t>() * 1'000'000'000 + m["header"]["stamp"]["nanosec"].get<int64_t>(),
              p.t_ns());
    EXPECT_EQ(m["pose"]["pose"]["position"]["x"].get<double>(), p.position_enu_m().x());
    EXPECT_EQ(m["pose"]["pose"]["position"]["y"].get<double>(), p.position_enu_m().y());
    EXPECT_NEAR(m["pose"]["pose"]["orientation"]["z"].get<double>(), std::sqrt(0.5), kTight);
    // Heading north: 10 m/s north is 10 m/s forward in base_link.
    EXPECT_NEAR(m["twist"]["twist"]["linear"]["x"].get<double>(), 10.0, 1e-9);
    EXPECT_NEAR(m["twist"]["twist"]["linear"]["y"].get<double>(), 0.0, 1e-9);
    const auto c = m["pose"]["covariance"].get<std::vector<double>>();
    ASSERT_EQ(c.size(), 36u);
    EXPECT_NEAR(c[0], 1.0 + i, kTight);  // x x
    EXPECT_NEAR(c[1], 0.5, kTight);      // x y
    EXPECT_NEAR(c[3 * 6 + 3], 0.02, kTight);  // roll = attitude about North
    EXPECT_NEAR(c[4 * 6 + 4], 0.01, kTight);  // pitch = -(attitude about East)
    EXPECT_NEAR(c[0 * 6 + 4], -0.004, kTight);
    EXPECT_NEAR(c[4 * 6 + 0], -0.004, kTight);
    EXPECT_EQ(m["twist"]["covariance"][0].get<double>(), out::kRos2UnknownVariance);
  }
  const json& fix = topics["/locaid/fix"]["first"];
  EXPECT_EQ(fix["latitude"].get<double>(), SamplePose(1).latitude_deg());
  EXPECT_EQ(fix["position_covariance"][0].get<double>(), 2.0);  // E E of pose 1
  EXPECT_EQ(fix["position_covariance_type"], 3);
  const json& gps = topics["/locaid/gps"]["messages"];
  EXPECT_EQ(gps[0]["header"]["frame_id"], "gps");
  EXPECT_EQ(gps[0]["position_covariance"][8].get<double>(), 9.0);
  // What the gate did is in the status of the pose that saw the fix.
  const json& status = topics["/locaid/status"]["messages"];
  auto value = [](const json& array, const std::string& key) {
    for (const auto& kv : array["status"][0]["values"])
      if (kv["key"] == key) return kv["value"].get<std::string>();
    return std::string("<missing>");
  };
  EXPECT_EQ(status[0]["status"][0]["level"], 2);  // LOST: ERROR
  EXPECT_EQ(status[0]["status"][0]["message"], "LOST");
  EXPECT_EQ(status[1]["status"][0]["level"], 0);  // GPS_FUSED: OK
  EXPECT_EQ(value(status[1], "gps_last_fix_gate"), "fused");
  EXPECT_EQ(status[3]["status"][0]["level"], 1);  // GPS_DEGRADED: WARN
  EXPECT_EQ(value(status[3], "gps_last_fix_gate"), "refused");
  EXPECT_EQ(value(status[3], "gps_last_fix_nis"), "40");
  EXPECT_EQ(run.out["tf_parents"], json({{"base_link", "map"}, {"camera_left", "base_link"}}));
}

// The reader is not a rubber stamp: a bag without the camera transform fails it.
TEST_F(Ros2BagReadTest, ReaderRefusesABagWithoutTheCameraChain) {
  const fs::path file = dir_ / "no_camera.mcap";
  {
    out::Ros2Recording bag(file);  // no T_body_cam0: /tf_static stays empty
    bag.Add(SamplePose(1));
  }
  const ft::NodeRun run = out::testing::ReadRos2Bag(file);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.text.find("no transform base_link -> camera_left"), std::string::npos) << run.text;
}

}  // namespace
