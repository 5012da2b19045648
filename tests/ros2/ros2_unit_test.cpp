// locaid-ros2's pieces without a network: ROS 2 names on DDS, QoS flags, the
// graph message (against Fast DDS's generated type), the choice of input
// topics and the rig, and the merge of a car's messages into a live
// session's items, bad messages included. The messages are made and
// serialized by Fast DDS's generated code (ros_samples.hpp).
#include "ros_samples.hpp"

#include "ros/cdr.hpp"
#include "ros2/dds.hpp"
#include "ros2/graph.hpp"
#include "ros2/input_assembler.hpp"
#include "ros2/input_setup.hpp"
#include "ros2/pose_publisher.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>

namespace locaid::ros2 {
namespace {

using namespace testing;
namespace sm = sensor_msgs::msg::dds_;

TEST(Ros2Names, RosTopicsAndTypesOnDds) {
  EXPECT_EQ(DdsTopicName("/locaid/odometry"), "rt/locaid/odometry");
  EXPECT_EQ(DdsTopicName("/tf"), "rt/tf");
  EXPECT_EQ(RosTopicName("rt/camera/left/image_raw"), "/camera/left/image_raw");
  EXPECT_EQ(RosTopicName("ros_discovery_info"), "");
  EXPECT_EQ(RosTopicName("rt"), "");
  for (const char* bad : {"tf", "/", "/a/", "/a//b", "/a b", "/a-b", ""}) {
    EXPECT_THROW(DdsTopicName(bad), std::invalid_argument) << bad;
  }
  EXPECT_EQ(DdsTypeName("nav_msgs/msg/Odometry"), "nav_msgs::msg::dds_::Odometry_");
  EXPECT_EQ(RosTypeName("sensor_msgs::msg::dds_::NavSatFix_"), "sensor_msgs/msg/NavSatFix");
  EXPECT_EQ(RosTypeName("DCPSParticipant"), "");
  EXPECT_EQ(RosTypeName("a::msg::dds_::B"), "");
  for (const char* bad : {"Odometry", "nav_msgs/Odometry", "/msg/X", "a/msg/", "a/b/msg/X", "a/msg/X/Y"}) {
    EXPECT_THROW(DdsTypeName(bad), std::invalid_argument) << bad;
  }
}

TEST(Ros2Names, QosFlagsAndDomain) {
  const Qos q = ParseQos("best_effort,transient_local,depth=3", Qos{});
  EXPECT_EQ(q.reliability, Reliability::kBestEffort);
  EXPECT_EQ(q.durability, Durability::kTransientLocal);
  EXPECT_EQ(q.depth, 3);
  EXPECT_EQ(DescribeQos(q), "best_effort, transient_local, depth 3");
  EXPECT_EQ(ParseQos("reliable", q).reliability, Reliability::kReliable);
  for (const char* bad : {"fast", "depth=0", "depth=x", "reliable,,volatile", "depth=100001"}) {
    EXPECT_THROW(ParseQos(bad, Qos{}), std::invalid_argument) << bad;
  }
  EXPECT_EQ(DomainId(7), 7u);
  EXPECT_THROW(DomainId(233), std::invalid_argument);
  ::setenv("ROS_DOMAIN_ID", "42", 1);
  EXPECT_EQ(DomainId(-1), 42u);
  ::setenv("ROS_DOMAIN_ID", "4x", 1);
  EXPECT_THROW(DomainId(-1), std::invalid_argument);
  ::unsetenv("ROS_DOMAIN_ID");
  EXPECT_EQ(DomainId(-1), 0u);
}

TEST(Ros2Names, PoseTopicFramesAndQosOptions) {
  PosePublisherOptions o;
  SetTopicOption(o, "odometry=/car/odom");
  SetTopicOption(o, "gps=");
  SetQosOption(o, "tf=best_effort,depth=1");
  SetFrameOption(o, "map=world");
  EXPECT_EQ(o.topics[static_cast<size_t>(PoseTopic::kOdometry)], "/car/odom");
  EXPECT_EQ(o.topics[static_cast<size_t>(PoseTopic::kGps)], "");
  EXPECT_EQ(o.qos[static_cast<size_t>(PoseTopic::kTf)].reliability, Reliability::kBestEffort);
  EXPECT_EQ(o.qos[static_cast<size_t>(PoseTopic::kTfStatic)].durability, Durability::kTransientLocal);
  EXPECT_EQ(o.frames.map, "world");
  EXPECT_THROW(SetTopicOption(o, "pose=/x"), std::invalid_argument);
  EXPECT_THROW(SetTopicOption(o, "odometry=odom"), std::invalid_argument);
  EXPECT_THROW(SetTopicOption(o, "odometry"), std::invalid_argument);
  EXPECT_THROW(SetFrameOption(o, "base=x"), std::invalid_argument);
  EXPECT_THROW(SetFrameOption(o, "body="), std::invalid_argument);
}

ParticipantEntities SomeEntities() {
  ParticipantEntities info;
  for (uint8_t i = 0; i < 16; ++i) info.gid[i] = i;
  NodeEntities n{"/car", "locaid_ros2", {}, {}};
  for (uint8_t k = 0; k < 3; ++k) {
    Guid g{};
    g.fill(static_cast<uint8_t>(0xA0 + k));
    (k == 0 ? n.readers : n.writers).push_back(g);
  }
  info.nodes.push_back(n);
  return info;
}

TEST(Ros2Graph, ParticipantEntitiesInfoAsFastDdsDecodesIt) {
  const ParticipantEntities info = SomeEntities();
  const std::string cdr = EncodeParticipantEntitiesInfo(info, RosDistro::kIronOrLater);
  eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<uint32_t>(cdr.size()));
  std::memcpy(payload.data, cdr.data(), cdr.size());
  payload.length = static_cast<uint32_t>(cdr.size());
  rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType type;
  rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_ msg;
  ASSERT_TRUE(type.deserialize(&payload, &msg));
  EXPECT_TRUE(std::equal(info.gid.begin(), info.gid.end(), msg.gid().data().begin()));
  ASSERT_EQ(msg.node_entities_info_seq().size(), 1u);
  const auto& n = msg.node_entities_info_seq()[0];
  EXPECT_EQ(n.node_namespace().to_string(), "/car");
  EXPECT_EQ(n.node_name().to_string(), "locaid_ros2");
  ASSERT_EQ(n.reader_gid_seq().size(), 1u);
  ASSERT_EQ(n.writer_gid_seq().size(), 2u);
  EXPECT_EQ(n.writer_gid_seq()[1].data()[15], 0xA2);
  // ... and ours reads Fast DDS's bytes back.
  const std::string theirs = Cdr<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType>(msg);
  const ParticipantEntities back = DecodeParticipantEntitiesInfo(theirs, RosDistro::kIronOrLater);
  EXPECT_EQ(back.gid, info.gid);
  EXPECT_EQ(back.nodes[0].writers, info.nodes[0].writers);
  EXPECT_EQ(back.nodes[0].readers, info.nodes[0].readers);
}

TEST(Ros2Graph, HumbleGidsAre24BytesAndTruncationThrows) {
  const ParticipantEntities info = SomeEntities();
  const std::string jazzy = EncodeParticipantEntitiesInfo(info, RosDistro::kIronOrLater);
  const std::string humble = EncodeParticipantEntitiesInfo(info, RosDistro::kHumble);
  EXPECT_EQ(humble.size(), jazzy.size() + 4 * 8);  // the participant's and three entities' gids, 8 bytes more each
  EXPECT_EQ(DecodeParticipantEntitiesInfo(humble, RosDistro::kHumble).nodes[0].writers, info.nodes[0].writers);
  EXPECT_EQ(ParseRosDistro("humble"), RosDistro::kHumble);
  EXPECT_EQ(ParseRosDistro("jazzy"), RosDistro::kIronOrLater);
  EXPECT_THROW(ParseRosDistro("galactic"), std::invalid_argument);
  for (size_t cut : {size_t{3}, size_t{10}, jazzy.size() - 1}) {
    EXPECT_THROW(DecodeParticipantEntitiesInfo(jazzy.substr(0, cut), RosDistro::kIronOrLater), ros::CdrError) << cut;
  }
  EXPECT_NO_THROW(CheckNodeName("/", "locaid_ros2"));
  EXPECT_NO_THROW(CheckNodeName("/car/front", "_x1"));
  for (const auto& [ns, name] : std::vector<std::pair<std::string, std::string>>{
           {"/", "1x"}, {"/", "a-b"}, {"car", "x"}, {"/car/", "x"}, {"//", "x"}, {"/", ""}}) {
    EXPECT_THROW(CheckNodeName(ns, name), std::invalid_argument) << ns << " " << name;
  }
}

// ------------------------------------------------------------ input setup --

struct CarMessages {
  std::string left_info = Cdr<sm::CameraInfo_PubSubType>(MakeCameraInfo(kT0, "camera_left", 0));
  std::string right_info = Cdr<sm::CameraInfo_PubSubType>(MakeCameraInfo(kT0, "camera_right", -kCamF * kBaseline));
  std::string imu = Cdr<sm::Imu_PubSubType>(MakeImu(kT0));
  std::string fix = Cdr<sm::NavSatFix_PubSubType>(MakeFix(kT0));
  std::string tf = Cdr<tf2_msgs::msg::dds_::TFMessage_PubSubType>(MakeTfStatic(kT0));
};

bag::BagTopics AllNamed() {
  bag::BagTopics t;
  t.left_image = "/cam/left/image_raw";
  t.left_info = "/cam/left/camera_info";
  t.right_image = "/cam/right/image_raw";
  t.right_info = "/cam/right/camera_info";
  t.imu = "/imu";
  t.gps = "/fix";
  t.speed = "/speed";
  return t;
}

InputRig SetUpInputs(InputSetup& setup, const bag::BagTopics& t) {
  const CarMessages m;
  std::string missing;
  EXPECT_FALSE(setup.TryFinish(0.1, &missing));
  EXPECT_NE(missing.find("CameraInfo"), std::string::npos) << missing;
  setup.AddMessage(t.left_info, m.left_info);
  setup.AddMessage(t.right_info, m.right_info);
  EXPECT_FALSE(setup.TryFinish(0.2, &missing));
  EXPECT_NE(missing.find(t.imu), std::string::npos) << missing;
  setup.AddMessage(t.imu, m.imu);
  EXPECT_FALSE(setup.TryFinish(0.3, &missing));
  EXPECT_NE(missing.find("/tf_static does not connect"), std::string::npos) << missing;
  setup.AddMessage("/tf_static", m.tf);
  setup.AddMessage(t.gps, m.fix);
  auto rig = setup.TryFinish(0.4, &missing);
  EXPECT_TRUE(rig) << missing;
  return rig ? *rig : InputRig{};
}

TEST(Ros2Inputs, NamedTopicsAndTheRigFromTheFirstMessages) {
  InputSetup setup(AllNamed(), {});
  const InputRig rig = SetUpInputs(setup, AllNamed());
  ASSERT_TRUE(rig.rectified);
  EXPECT_EQ(setup.topics().type_of(InputRole::kLeftImage), "sensor_msgs/msg/Image");
  EXPECT_EQ(setup.topics().topic_of(InputRole::kTfStatic), "/tf_static");
  EXPECT_TRUE(rig.has_imu);
  // The body's x (forward) is the camera's z; its lever arm 1.2 m ahead.
  EXPECT_TRUE((rig.T_cam0_imu.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE(rig.lever_arm_body_m.isApprox(Eigen::Vector3d(1.2, 0, 0), 1e-12));
  const v1::LiveSource live = rig.live();
  EXPECT_EQ(live.width(), kCamW);
  EXPECT_EQ(live.height(), kCamH);
  EXPECT_DOUBLE_EQ(live.fx(), kCamF);
  EXPECT_DOUBLE_EQ(live.baseline_m(), kBaseline);
  EXPECT_EQ(live.t_cam0_imu_size(), 12);
  EXPECT_FALSE(live.no_imu());
}

TEST(Ros2Inputs, PickedByTypeAsABagsTopicsAre) {
  InputSetup setup({}, {1.0, 10.0});
  // Left and right are told apart by P[3], not by the names.
  for (const std::string side : {"a", "b"}) {
    setup.AddPublication("/stereo/" + side + "/camera_info", "sensor_msgs/msg/CameraInfo");
    setup.AddPublication("/stereo/" + side + "/image_raw/compressed", "sensor_msgs/msg/CompressedImage");
  }
  setup.AddPublication("/imu/data", "sensor_msgs/msg/Imu");
  setup.AddPublication("/gps/fix", "sensor_msgs/msg/NavSatFix");
  std::string missing;
  EXPECT_FALSE(setup.TryFinish(0.5, &missing));
  EXPECT_NE(missing.find("looking for topics"), std::string::npos) << missing;
  EXPECT_EQ(setup.WantedTopics().size(), 2u);  // the camera_info topics, to tell left from right
  const CarMessages m;
  setup.AddMessage("/stereo/a/camera_info", m.right_info);
  setup.AddMessage("/stereo/b/camera_info", m.left_info);
  EXPECT_FALSE(setup.TryFinish(1.5, &missing));
  ASSERT_TRUE(setup.chosen()) << missing;
  EXPECT_EQ(setup.topics().topic_of(InputRole::kLeftImage), "/stereo/b/image_raw/compressed");
  EXPECT_EQ(setup.topics().type_of(InputRole::kLeftImage), "sensor_msgs/msg/CompressedImage");
  EXPECT_EQ(setup.topics().topic_of(InputRole::kRightInfo), "/stereo/a/camera_info");
  EXPECT_EQ(setup.topics().topic_of(InputRole::kImu), "/imu/data");
  EXPECT_EQ(setup.topics().topic_of(InputRole::kSpeed), "");
}

TEST(Ros2Inputs, WhatCannotBeSetUpSaysWhichKeyToSet) {
  {
    InputSetup setup({}, {0.5, 3.0});
    setup.AddPublication("/imu_a", "sensor_msgs/msg/Imu");
    setup.AddPublication("/imu_b", "sensor_msgs/msg/Imu");
    std::string missing;
    EXPECT_FALSE(setup.TryFinish(1.0, &missing));
    try {
      setup.TryFinish(3.0, &missing);
      ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("--inputs FILE"), std::string::npos) << e.what();
    }
  }
  {
    bag::BagTopics t = AllNamed();
    InputSetup setup(t, {0.5, 3.0});
    const CarMessages m;
    setup.AddMessage(t.left_info, m.left_info);
    setup.AddMessage(t.right_info, m.right_info);
    setup.AddMessage(t.imu, m.imu);  // no /tf_static
    std::string missing;
    try {
      setup.TryFinish(3.5, &missing);
      ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("imu: none"), std::string::npos) << e.what();
    }
  }
}

// -------------------------------------------------------------- assembler --

struct Feed {
  Feed() : setup(AllNamed(), {}), rig(SetUpInputs(setup, AllNamed())) {
    AssemblerOptions o;
    o.silent_after_s = 0.5;
    assembler = std::make_unique<InputAssembler>(setup.topics(), rig, o, [this](const std::string& l) {
      log.push_back(l);
    });
  }
  void Add(InputRole role, const std::string& cdr, double at_s) {
    assembler->Add(role, cdr, t0 + std::chrono::duration_cast<InputClock::duration>(std::chrono::duration<double>(at_s)),
                   out);
  }
  TopicStats Stats(InputRole role) {
    for (const auto& [r, s] : assembler->stats(InputClock::now()))
      if (r == role) return s;
    return {};
  }
  InputSetup setup;
  InputRig rig;
  std::unique_ptr<InputAssembler> assembler;
  std::vector<v1::PushRequest> out;
  std::vector<std::string> log;
  InputClock::time_point t0 = InputClock::now();
};

std::string ImageCdr(int64_t t, const std::string& frame, int width = kCamW) {
  return Cdr<sm::Image_PubSubType>(MakeImage(t, frame, 7, width));
}
std::string ImuCdr(int64_t t) { return Cdr<sm::Imu_PubSubType>(MakeImu(t, 0.1)); }

int64_t StampOf(const v1::PushRequest& r) {
  switch (r.item_case()) {
    case v1::PushRequest::kFrame: return r.frame().t_ns();
    case v1::PushRequest::kImu: return r.imu().t_ns();
    case v1::PushRequest::kGps: return r.gps().t_ns();
    case v1::PushRequest::kSpeed: return r.speed().t_ns();
    default: return 0;
  }
}

// Images arrive 35 ms after IMU samples of the same time, right after left:
// every item goes out once, in stamp order, frames as rectified GRAY8.
TEST(Ros2Inputs, MessagesGoOutInStampOrderAsRectifiedFrames) {
  Feed f;
  constexpr int64_t kMs = 1'000'000;
  for (int k = 0; k < 100; ++k) {  // 1 s: IMU at 100 Hz, frames at 10 Hz, fixes at 5 Hz, speed at 20 Hz
    const int64_t t = kT0 + k * 10 * kMs;
    const double at = k * 0.01;
    f.Add(InputRole::kImu, ImuCdr(t), at);
    if (k % 5 == 0) f.Add(InputRole::kSpeed, Cdr<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(MakeTwist(t, 3)), at);
    if (k % 20 == 0) f.Add(InputRole::kGps, Cdr<sm::NavSatFix_PubSubType>(MakeFix(t)), at + 0.05);
    if (k % 10 == 3) {  // the images of 30 ms ago: left, then right 2 ms off
      f.Add(InputRole::kLeftImage, ImageCdr(t - 30 * kMs, "camera_left"), at + 0.005);
      f.Add(InputRole::kRightImage, ImageCdr(t - 28 * kMs, "camera_right"), at + 0.006);
    }
  }
  f.assembler->Flush(f.out);
  std::map<v1::PushRequest::ItemCase, int> kinds;
  int64_t previous = INT64_MIN;
  for (const auto& r : f.out) {
    ++kinds[r.item_case()];
    if (r.item_case() != v1::PushRequest::kGps) {
      EXPECT_GE(StampOf(r), previous);
      previous = StampOf(r);
    }
    if (r.has_frame()) {
      EXPECT_EQ(r.frame().encoding(), v1::IMAGE_ENCODING_GRAY8);
      EXPECT_EQ(r.frame().left().size(), static_cast<size_t>(kCamW * kCamH));
      EXPECT_EQ((r.frame().t_ns() - kT0) % (100 * kMs), 0) << "a frame's time is its left image's";
    }
  }
  EXPECT_EQ(kinds[v1::PushRequest::kImu], 100);
  EXPECT_EQ(kinds[v1::PushRequest::kFrame], 10);
  EXPECT_EQ(kinds[v1::PushRequest::kGps], 5);
  EXPECT_EQ(kinds[v1::PushRequest::kSpeed], 20);
  EXPECT_EQ(f.Stats(InputRole::kImu).used, 100u);
  EXPECT_EQ(f.Stats(InputRole::kLeftImage).late, 0u);
  EXPECT_EQ(f.assembler->frames(), 10u);
}

// Messages of one stamp go out in the order a replay fuses them (IMU, fix,
// speed, then the frame), whichever DDS delivered first: a live session then
// makes the replay's track (tests/ros2/ros2_kitti_test.cpp).
TEST(Ros2Inputs, EqualStampsGoOutInTheReplaysOrder) {
  Feed f;
  constexpr int64_t kMs = 1'000'000;
  for (int k = 0; k < 4; ++k) {  // every topic at the same stamps, delivered frame first, IMU last
    const int64_t t = kT0 + k * 100 * kMs;
    const double at = k * 0.1;
    f.Add(InputRole::kLeftImage, ImageCdr(t, "camera_left"), at);
    f.Add(InputRole::kRightImage, ImageCdr(t, "camera_right"), at);
    f.Add(InputRole::kSpeed, Cdr<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(MakeTwist(t, 3)), at);
    f.Add(InputRole::kGps, Cdr<sm::NavSatFix_PubSubType>(MakeFix(t)), at);
    f.Add(InputRole::kImu, ImuCdr(t), at);
  }
  f.assembler->Flush(f.out);
  std::string order;
  for (const auto& r : f.out) {
    order += r.has_imu() ? 'i' : r.has_gps() ? 'g' : r.has_speed() ? 's' : r.has_frame() ? 'F' : '?';
  }
  EXPECT_EQ(order, "igsFigsFigsFigsF");
}

// Each bad message is counted against its topic with what was wrong, and
// the good ones around it still go out.
TEST(Ros2Inputs, BadMessagesAreCountedAndNamedNeverFatal) {
  Feed f;
  constexpr int64_t kMs = 1'000'000;
  const std::string imu = ImuCdr(kT0 + 10 * kMs);
  f.Add(InputRole::kImu, imu.substr(0, imu.size() - 9), 0.0);       // truncated CDR
  f.Add(InputRole::kImu, std::string("\x00\x02\x00\x00xxxxxxxx", 12), 0.0);  // not plain CDR
  f.Add(InputRole::kImu, imu, 0.01);
  f.Add(InputRole::kImu, ImuCdr(kT0 + 5 * kMs), 0.02);              // stamps backwards
  auto nan_imu = MakeImu(kT0 + 20 * kMs);
  nan_imu.linear_acceleration().y(std::nan(""));
  f.Add(InputRole::kImu, Cdr<sm::Imu_PubSubType>(nan_imu), 0.03);  // not finite
  f.Add(InputRole::kLeftImage, ImageCdr(kT0 + 30 * kMs, "camera_left", kCamW - 16), 0.04);  // not the camera_info's size
  f.Add(InputRole::kRightImage, ImageCdr(kT0 + 30 * kMs, "camera_right"), 0.04);
  f.Add(InputRole::kLeftImage, ImageCdr(kT0 + 130 * kMs, "camera_left"), 0.14);           // right one never comes
  f.Add(InputRole::kLeftImage, ImageCdr(kT0 + 230 * kMs, "camera_left"), 0.24);
  f.Add(InputRole::kRightImage, ImageCdr(kT0 + 230 * kMs, "camera_right"), 0.24);
  f.Add(InputRole::kGps, Cdr<sm::NavSatFix_PubSubType>(MakeFix(kT0 + 40 * kMs, 49, 8.4, -1)), 0.25);  // NO_FIX
  f.assembler->WrongType(InputRole::kSpeed, "sensor_msgs/msg/NavSatFix");
  f.assembler->Flush(f.out);

  const TopicStats imu_stats = f.Stats(InputRole::kImu);
  EXPECT_EQ(imu_stats.undecodable, 2u);
  EXPECT_EQ(imu_stats.late, 1u);
  EXPECT_EQ(imu_stats.bad, 1u);
  EXPECT_EQ(imu_stats.used, 1u);
  EXPECT_NE(imu_stats.last_error.find("not finite"), std::string::npos) << imu_stats.last_error;
  const TopicStats left = f.Stats(InputRole::kLeftImage);
  EXPECT_EQ(left.bad, 1u);
  EXPECT_NE(left.last_error.find("image size 80x64"), std::string::npos) << left.last_error;
  EXPECT_EQ(left.unpaired, 1u);
  EXPECT_EQ(f.Stats(InputRole::kSpeed).wrong_type, 1u);
  EXPECT_EQ(f.assembler->frames(), 1u);
  const auto fix = std::find_if(f.out.begin(), f.out.end(), [](const auto& r) { return r.has_gps(); });
  ASSERT_NE(fix, f.out.end());
  EXPECT_EQ(fix->gps().fix_type(), v1::GPS_FIX_NONE);
  // Every problem was logged, naming the topic.
  EXPECT_TRUE(std::any_of(f.log.begin(), f.log.end(), [](const std::string& l) {
    return l.rfind("/imu: CDR:", 0) == 0;
  })) << ::testing::PrintToString(f.log);
  const output::DiagnosticStatus health = f.assembler->Health(InputClock::now());
  EXPECT_GE(health.level, output::DiagnosticStatus::kWarn);
  const std::map<std::string, std::string> values(health.values.begin(), health.values.end());
  EXPECT_EQ(values.at("imu.undecodable"), "2");
  EXPECT_EQ(values.at("left_image.bad"), "1");
}

// A stream that stops no longer holds the others back; its health says so,
// and it is back when it speaks again.
TEST(Ros2Inputs, ASilentTopicIsReportedAndReleased) {
  Feed f;
  constexpr int64_t kMs = 1'000'000;
  f.Add(InputRole::kImu, ImuCdr(kT0), 0.0);
  f.Add(InputRole::kLeftImage, ImageCdr(kT0, "camera_left"), 0.0);
  f.Add(InputRole::kRightImage, ImageCdr(kT0, "camera_right"), 0.0);
  for (int k = 1; k <= 100; ++k) f.Add(InputRole::kImu, ImuCdr(kT0 + k * 10 * kMs), k * 0.01);  // cameras stop
  const auto at = f.t0 + std::chrono::milliseconds(1000);
  f.assembler->Tick(at, f.out);
  EXPECT_TRUE(f.Stats(InputRole::kLeftImage).silent);
  EXPECT_EQ(f.assembler->Health(at).level, output::DiagnosticStatus::kError);
  EXPECT_GE(std::count_if(f.out.begin(), f.out.end(), [](const auto& r) { return r.has_imu(); }), 95);
  EXPECT_TRUE(std::any_of(f.log.begin(), f.log.end(), [](const std::string& l) {
    return l.find("/cam/left/image_raw: silent") != std::string::npos;
  })) << ::testing::PrintToString(f.log);
  f.Add(InputRole::kLeftImage, ImageCdr(kT0 + 1010 * kMs, "camera_left"), 1.01);
  EXPECT_FALSE(f.Stats(InputRole::kLeftImage).silent);
}

}  // namespace
}  // namespace locaid::ros2
