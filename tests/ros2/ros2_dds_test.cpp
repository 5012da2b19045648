// Two DDS vendors in one process, on loopback: locaid's Cyclone DDS node
// (ros2/) and a Fast DDS participant with the types fastddsgen made from the
// ROS 2 IDL. What locaid publishes, Fast DDS's generated code decodes to the
// same values; what Fast DDS publishes, locaid's decoders read; a
// publication of another type on an input topic is seen by discovery and
// never matched.
#include "ros_samples.hpp"
#include "temp_dir.hpp"

#include "output/ros2_messages.hpp"
#include "ros/images.hpp"
#include "ros/messages.hpp"

#include <opencv2/imgcodecs.hpp>
#include "ros2/graph.hpp"
#include "ros2/pose_publisher.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace locaid::ros2 {
namespace {

using namespace testing;
using test_support::ScopedTempDir;
namespace sm = sensor_msgs::msg::dds_;

v1::PoseUpdate SomePose(uint64_t sequence) {
  v1::PoseUpdate p;
  p.set_session_id("s0123456789ab");
  p.set_sequence(sequence);
  p.set_t_ns(kT0 + static_cast<int64_t>(sequence) * 100'000'000 + 7);
  p.mutable_position_enu_m()->set_x(10.0 + static_cast<double>(sequence));
  p.mutable_position_enu_m()->set_y(-3.25);
  p.mutable_position_enu_m()->set_z(0.5);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  p.mutable_orientation_enu_body()->set_w(q.w());
  p.mutable_orientation_enu_body()->set_z(q.z());
  p.mutable_velocity_enu_mps()->set_x(5);
  for (int i = 0; i < 36; ++i) p.add_covariance(i % 7 == 0 ? 0.01 * (1 + i / 7) : 0.0);
  p.set_latitude_deg(49.01);
  p.set_longitude_deg(8.41);
  p.set_altitude_m(112);
  p.set_mode(v1::MODE_GPS_FUSED);
  auto* fix = p.add_gps_fixes();
  fix->set_t_ns(p.t_ns() - 30'000'000);
  fix->set_latitude_deg(49.0101);
  fix->set_sigma_horizontal_m(1.5);
  fix->set_sigma_vertical_m(3);
  fix->set_used(true);
  return p;
}

class TwoVendors : public ::testing::Test {
 protected:
  TwoVendors() : dir_("ros2_dds"), loopback_(dir_.path()), fast_(loopback_.domain, loopback_.fastdds) {
    NodeOptions o;
    o.participant.domain_id = loopback_.domain;
    o.name = "locaid_test";
    node_ = std::make_unique<Node>(o);
  }
  ScopedTempDir dir_;
  DdsLoopback loopback_;
  FastPeer fast_;
  std::unique_ptr<Node> node_;
};

TEST_F(TwoVendors, PosesFromCycloneAsFastDdsDecodesThem) {
  auto odom = fast_.Subscribe<nav_msgs::msg::dds_::Odometry_PubSubType>("rt/locaid/odometry");
  auto fix = fast_.Subscribe<sm::NavSatFix_PubSubType>("rt/locaid/fix");
  auto gps = fast_.Subscribe<sm::NavSatFix_PubSubType>("rt/locaid/gps");
  auto tf = fast_.Subscribe<tf2_msgs::msg::dds_::TFMessage_PubSubType>("rt/tf");
  auto diag = fast_.Subscribe<diagnostic_msgs::msg::dds_::DiagnosticArray_PubSubType>("rt/diagnostics");
  auto graph = fast_.Subscribe<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType>(
      "ros_discovery_info", {true, true, 1});
  PosePublisherOptions o;
  o.T_body_cam0 = Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.2, 1.5));
  o.diagnostics_period_s = 0;
  PosePublisher publisher(*node_, o);
  // Discovery before publishing (volatile topics keep nothing for late
  // readers), both ways: a writer sends only to readers it has matched.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  for (const PoseTopic t : {PoseTopic::kOdometry, PoseTopic::kFix, PoseTopic::kGps, PoseTopic::kTf,
                            PoseTopic::kDiagnostics}) {
    while (publisher.matched(t) < 1 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ASSERT_EQ(publisher.matched(t), 1) << PoseTopicKey(t);
  }
  ASSERT_TRUE(odom->WaitMatched(10) && fix->WaitMatched(10) && gps->WaitMatched(10) && tf->WaitMatched(10) &&
              diag->WaitMatched(10));
  for (uint64_t s = 0; s < 5; ++s) publisher.Publish(SomePose(s));
  ASSERT_TRUE(odom->WaitCount(5, 10));
  ASSERT_TRUE(diag->WaitCount(5, 10));
  // A late subscriber still gets the rig (transient local).
  auto tf_static = fast_.Subscribe<tf2_msgs::msg::dds_::TFMessage_PubSubType>("rt/tf_static", {true, true, 1});
  ASSERT_TRUE(tf_static->WaitCount(1, 10));

  const auto odoms = odom->samples();
  for (size_t i = 0; i < odoms.size(); ++i) {
    const v1::PoseUpdate p = SomePose(i);
    const auto& o = odoms[i].msg;
    EXPECT_EQ(StampNs(o.header().stamp()), p.t_ns());
    EXPECT_EQ(o.header().frame_id(), "map");
    EXPECT_EQ(o.child_frame_id(), "base_link");
    EXPECT_EQ(o.pose().pose().position().x(), p.position_enu_m().x());
    EXPECT_NEAR(o.pose().pose().orientation().z(), p.orientation_enu_body().z(), 1e-15);
    EXPECT_EQ(o.pose().covariance()[0], 0.01);  // position block as the filter has it
    EXPECT_EQ(o.twist().covariance()[35], output::kRos2UnknownVariance);
    EXPECT_NEAR(o.twist().twist().linear().x(), 5 * std::cos(0.3), 1e-12);  // the ENU velocity in body axes
  }
  ASSERT_TRUE(fix->WaitCount(5, 5));
  EXPECT_EQ(fix->samples()[0].msg.latitude(), 49.01);
  EXPECT_EQ(fix->samples()[0].msg.position_covariance_type(), 3);
  ASSERT_TRUE(gps->WaitCount(5, 5));
  EXPECT_EQ(StampNs(gps->samples()[0].msg.header().stamp()), SomePose(0).t_ns() - 30'000'000);
  EXPECT_EQ(gps->samples()[0].msg.position_covariance()[8], 9.0);
  ASSERT_TRUE(tf->WaitCount(5, 5));
  EXPECT_EQ(tf->samples()[4].msg.transforms()[0].transform().translation().x(), 14.0);
  EXPECT_EQ(tf_static->samples()[0].msg.transforms()[0].child_frame_id(), "camera_left");
  EXPECT_EQ(tf_static->samples()[0].msg.transforms()[0].transform().translation().z(), 1.5);
  const auto diags = diag->samples();
  const auto& status = diags[3].msg.status()[0];
  EXPECT_EQ(status.name(), "locaid");
  EXPECT_EQ(status.level(), 0);
  EXPECT_EQ(status.hardware_id(), "s0123456789ab");
  const auto seq = std::find_if(status.values().begin(), status.values().end(),
                                [](const auto& kv) { return kv.key() == "sequence"; });
  ASSERT_NE(seq, status.values().end());
  EXPECT_EQ(seq->value(), "3");

  // The graph: the node and its writers, by the GUIDs the samples came from.
  ASSERT_TRUE(graph->WaitFor(
      [](const auto& s) {
        return !s.empty() && !s.back().msg.node_entities_info_seq().empty() &&
               s.back().msg.node_entities_info_seq()[0].writer_gid_seq().size() == 6;
      },
      10));
  const auto info = graph->samples().back().msg;
  EXPECT_EQ(info.node_entities_info_seq()[0].node_name().to_string(), "locaid_test");
  const auto& writers = info.node_entities_info_seq()[0].writer_gid_seq();
  for (const auto& sample : {odoms[0].publication, diag->samples()[0].publication}) {
    EXPECT_TRUE(std::any_of(writers.begin(), writers.end(), [&](const auto& g) {
      return std::equal(sample.begin(), sample.end(), g.data().begin());
    })) << "a writer the samples came from is not announced";
  }
  EXPECT_TRUE(std::equal(info.gid().data().begin(), info.gid().data().begin() + 12, odoms[0].publication.begin()))
      << "the participant's gid is the GUID prefix of its writers";
}

TEST_F(TwoVendors, InputsFromFastDdsAsLocaidDecodesThem) {
  Participant& p = node_->participant();
  p.WatchPublications();
  const std::vector<std::tuple<std::string, std::string>> topics = {
      {"/cam/image_raw", "sensor_msgs/msg/Image"},         {"/cam/camera_info", "sensor_msgs/msg/CameraInfo"},
      {"/cam/image_raw/compressed", "sensor_msgs/msg/CompressedImage"},
      {"/imu", "sensor_msgs/msg/Imu"},                     {"/fix", "sensor_msgs/msg/NavSatFix"},
      {"/speed", "geometry_msgs/msg/TwistStamped"},        {"/tf_static", "tf2_msgs/msg/TFMessage"}};
  std::map<std::string, std::unique_ptr<Reader>> readers;
  std::map<std::string, std::unique_ptr<FastWriter>> writers;
  for (const auto& [topic, type] : topics) {
    const bool tf = topic == "/tf_static";
    readers[topic] = node_->CreateSubscription(topic, type, tf ? Qos{Reliability::kReliable, Durability::kTransientLocal, 10}
                                                               : SensorDataQos(10));
    writers[topic] = fast_.AdvertiseRos(type, DdsTopicName(topic), {true, tf, 10});
  }
  // A NavSatFix on the IMU's topic (another participant): another type, never matched.
  FastPeer other(loopback_.domain, loopback_.fastdds);
  auto wrong = other.Advertise<sm::NavSatFix_PubSubType>("rt/imu");
  for (auto& [topic, w] : writers) ASSERT_TRUE(w->WaitMatched(1, 10)) << topic;
  auto image = MakeImage(kT0, "camera_left", 3);
  sm::CompressedImage_ png;  // a 2x1 gray PNG
  png.header(RosHeader(kT0, "camera_left"));
  png.format("mono8; png compressed");
  {
    std::vector<uint8_t> bytes;
    cv::imencode(".png", cv::Mat(1, 2, CV_8UC1, cv::Scalar(200)), bytes);
    png.data(bytes);
  }
  auto info = MakeCameraInfo(kT0, "camera_left", 0);
  auto imu = MakeImu(kT0 + 1, 0.25, -0.5);
  auto nav = MakeFix(kT0 + 2);
  auto twist = MakeTwist(kT0 + 3, 7.5);
  auto tf = MakeTfStatic(kT0 + 4);
  auto wrong_fix = MakeFix(kT0 + 5);
  // Best-effort readers may miss what comes before they matched the writer:
  // each message is sent again until it arrived.
  const auto send = [&] {
    writers["/cam/image_raw"]->Write(&image);
    writers["/cam/image_raw/compressed"]->Write(&png);
    writers["/cam/camera_info"]->Write(&info);
    writers["/imu"]->Write(&imu);
    writers["/fix"]->Write(&nav);
    writers["/speed"]->Write(&twist);
    wrong->Write(&wrong_fix);
  };
  ASSERT_TRUE(writers["/tf_static"]->Write(&tf));
  std::map<std::string, std::vector<Sample>> got;
  bool wrong_seen = false;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  auto next_send = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < until) {
    if (std::chrono::steady_clock::now() >= next_send) {
      send();
      next_send += std::chrono::milliseconds(200);
    }
    p.Wait(std::chrono::milliseconds(50));
    for (const Publication& pub : p.TakePublications())
      wrong_seen = wrong_seen || (pub.topic == "rt/imu" && RosTypeName(pub.type) == "sensor_msgs/msg/NavSatFix");
    for (auto& [topic, r] : readers) r->Take(got[topic]);
    if (wrong_seen && std::all_of(topics.begin(), topics.end(), [&](const auto& t) { return !got[std::get<0>(t)].empty(); }))
      break;
  }
  EXPECT_TRUE(wrong_seen);
  for (const auto& [topic, type] : topics) ASSERT_FALSE(got[topic].empty()) << topic;
  // Only the Imu publisher's messages came on /imu, never the NavSatFix one's.
  for (const Sample& s : got["/imu"]) EXPECT_EQ(ros::DecodeImu(s.data).header.frame_id, "imu_link");

  const ros::Image im = ros::DecodeImage(got["/cam/image_raw"][0].data);
  EXPECT_EQ(im.header.stamp_ns, kT0);
  EXPECT_EQ(im.header.frame_id, "camera_left");
  EXPECT_EQ(im.width, static_cast<uint32_t>(kCamW));
  EXPECT_EQ(im.encoding, "mono8");
  ASSERT_EQ(im.data.size(), image.data().size());
  EXPECT_EQ(std::memcmp(im.data.data(), image.data().data(), im.data.size()), 0);
  const cv::Mat gray = ros::ToGray(ros::DecodeCompressedImage(got["/cam/image_raw/compressed"][0].data));
  EXPECT_EQ(gray.cols, 2);
  EXPECT_EQ(gray.at<uint8_t>(0, 1), 200);
  const ros::CameraInfo ci = ros::DecodeCameraInfo(got["/cam/camera_info"][0].data);
  EXPECT_EQ(ci.p[0], kCamF);
  EXPECT_EQ(ci.d.size(), 5u);
  EXPECT_EQ(ci.distortion_model, "plumb_bob");
  const ros::Imu i = ros::DecodeImu(got["/imu"][0].data);
  EXPECT_EQ(i.header.stamp_ns, kT0 + 1);
  EXPECT_EQ(i.linear_acceleration, Eigen::Vector3d(0.25, 0, 9.81));
  EXPECT_EQ(i.angular_velocity.z(), -0.5);
  const ros::NavSatFix f = ros::DecodeNavSatFix(got["/fix"][0].data);
  EXPECT_EQ(f.latitude, 49.0);
  EXPECT_EQ(f.position_covariance[8], 9.0);
  EXPECT_EQ(f.position_covariance_type, 2);
  EXPECT_EQ(ros::DecodeTwistStamped(got["/speed"][0].data).linear.x(), 7.5);
  const auto transforms = ros::DecodeTfMessage(got["/tf_static"][0].data);
  ASSERT_EQ(transforms.size(), 2u);
  EXPECT_EQ(transforms[1].child_frame_id, "gps_link");
  EXPECT_EQ(transforms[1].T_parent_child.translation().x(), 1.2);
}

}  // namespace
}  // namespace locaid::ros2
