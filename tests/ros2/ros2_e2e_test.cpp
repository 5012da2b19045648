// locaid-ros2 as a ROS 2 car sees it, against a Fast DDS peer (the DDS under
// ROS 2's default rmw), with the real locaid-server:
//  - a session's poses out: every published field against the gRPC stream of
//    the same session (stamps exactly, covariances, frame ids), /tf_static
//    for a late subscriber, the node in ros_discovery_info;
//  - a car's topics in: a live session fed over DDS, and bad input (a
//    message of another type on a topic, truncated CDR, an image of another
//    size than its CameraInfo, stamps running backwards, a publisher that
//    dies) counted and named while the session goes on.
#include "ros2_e2e_support.hpp"
#include "ros_samples.hpp"

#include "output/ros2_messages.hpp"
#include "ros2/dds.hpp"

#include <algorithm>
#include <atomic>
#include <fstream>
#include <map>

namespace locaid::ros2::testing {
namespace {

namespace sm = sensor_msgs::msg::dds_;

const char* Value(const diagnostic_msgs::msg::dds_::DiagnosticStatus_& s, const std::string& key) {
  for (const auto& kv : s.values())
    if (kv.key() == key) return kv.value().c_str();
  return nullptr;
}

TEST_F(Ros2Car, EveryPublishedFieldIsTheGrpcStreams) {
  auto odom = fast_->Subscribe<nav_msgs::msg::dds_::Odometry_PubSubType>("rt/locaid/odometry", {true, false, 100});
  auto fix = fast_->Subscribe<sm::NavSatFix_PubSubType>("rt/locaid/fix", {true, false, 100});
  auto gps = fast_->Subscribe<sm::NavSatFix_PubSubType>("rt/locaid/gps", {true, false, 100});
  auto tf = fast_->Subscribe<tf2_msgs::msg::dds_::TFMessage_PubSubType>("rt/tf", {true, false, 100});
  auto diag = fast_->Subscribe<diagnostic_msgs::msg::dds_::DiagnosticArray_PubSubType>("rt/diagnostics",
                                                                                         {true, false, 100});
  auto graph = fast_->Subscribe<rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_PubSubType>(
      "ros_discovery_info", {true, true, 1});
  StartRos2({"--diagnostics-period-s", "0", "--frame", "map=world"});
  ASSERT_TRUE(odom->WaitMatched(20)) << ros2_->log();
  ASSERT_TRUE(diag->WaitMatched(5)) << ros2_->log();

  v1::StartSessionRequest req;
  req.mutable_synthetic()->set_seed(3);
  req.mutable_synthetic()->set_frames(40);
  req.set_playback_rate(2);
  grpc::ClientContext ctx;
  st::SetDeadline(&ctx, 30);
  v1::Session session;
  ASSERT_TRUE(stub_->StartSession(&ctx, req, &session).ok());
  st::PoseCollector poses(server_->NewChannel(1), session.id(), /*from_start=*/true, 300);
  ASSERT_TRUE(poses.WaitDone(300)) << "the session never finished";
  const auto grpc_poses = poses.poses();
  ASSERT_EQ(grpc_poses.size(), 40u);
  ASSERT_TRUE(odom->WaitCount(grpc_poses.size(), 30)) << odom->count() << " of " << grpc_poses.size() << "\n"
                                                      << ros2_->log();
  ASSERT_TRUE(diag->WaitCount(grpc_poses.size(), 10));
  // /tf_static is transient local: a subscriber that comes after the session still gets the rig.
  auto tf_static = fast_->Subscribe<tf2_msgs::msg::dds_::TFMessage_PubSubType>("rt/tf_static", {true, true, 1});
  ASSERT_TRUE(tf_static->WaitCount(1, 10));

  std::map<int64_t, v1::PoseUpdate> by_stamp;
  size_t fixes_seen = 0, not_lost = 0;
  for (const auto& p : grpc_poses) {
    by_stamp[p.t_ns()] = p;
    fixes_seen += static_cast<size_t>(p.gps_fixes_size());
    not_lost += p.mode() != v1::MODE_LOST;
  }
  for (const auto& r : odom->samples()) {
    const auto& o = r.msg;
    const auto it = by_stamp.find(StampNs(o.header().stamp()));
    ASSERT_NE(it, by_stamp.end()) << "an Odometry stamp that is no pose's t_ns: " << StampNs(o.header().stamp());
    const v1::PoseUpdate& p = it->second;
    EXPECT_EQ(o.header().frame_id(), "world");
    EXPECT_EQ(o.child_frame_id(), "base_link");
    EXPECT_EQ(o.pose().pose().position().x(), p.position_enu_m().x());
    EXPECT_EQ(o.pose().pose().position().y(), p.position_enu_m().y());
    EXPECT_EQ(o.pose().pose().position().z(), p.position_enu_m().z());
    const Eigen::Quaterniond q = Eigen::Quaterniond(p.orientation_enu_body().w(), p.orientation_enu_body().x(),
                                                    p.orientation_enu_body().y(), p.orientation_enu_body().z())
                                     .normalized();
    EXPECT_NEAR(o.pose().pose().orientation().w(), q.w(), 1e-12);
    EXPECT_NEAR(o.pose().pose().orientation().z(), q.z(), 1e-12);
    // Covariance: the position block as the filter has it, the whole matrix
    // as output/ros2_messages.hpp turns the attitude into roll/pitch/yaw.
    ASSERT_EQ(p.covariance_size(), 36);
    output::Matrix6d P;
    for (int k = 0; k < 36; ++k) P(k / 6, k % 6) = p.covariance(k);
    const output::Matrix6d ros = output::RosPoseCovariance(P, q);
    for (int k = 0; k < 36; ++k) EXPECT_NEAR(o.pose().covariance()[static_cast<size_t>(k)], ros(k / 6, k % 6), 1e-12) << k;
    EXPECT_NEAR(o.pose().covariance()[0], P(0, 0), 1e-12);  // position as the filter has it
    EXPECT_EQ(o.twist().covariance()[0], output::kRos2UnknownVariance);
    const Eigen::Vector3d v_body =
        q.conjugate() * Eigen::Vector3d(p.velocity_enu_mps().x(), p.velocity_enu_mps().y(), p.velocity_enu_mps().z());
    EXPECT_NEAR(o.twist().twist().linear().x(), v_body.x(), 1e-9);
  }
  ASSERT_TRUE(fix->WaitCount(not_lost, 5));
  for (const auto& r : fix->samples()) {
    const v1::PoseUpdate& p = by_stamp.at(StampNs(r.msg.header().stamp()));
    EXPECT_NE(p.mode(), v1::MODE_LOST);
    EXPECT_EQ(r.msg.latitude(), p.latitude_deg());
    EXPECT_EQ(r.msg.longitude(), p.longitude_deg());
    EXPECT_EQ(r.msg.altitude(), p.altitude_m());
    EXPECT_EQ(r.msg.position_covariance_type(), 3);
  }
  ASSERT_TRUE(gps->WaitCount(fixes_seen, 5));
  EXPECT_EQ(gps->count(), fixes_seen);
  ASSERT_TRUE(tf->WaitCount(grpc_poses.size(), 5));
  for (const auto& r : tf->samples()) {
    ASSERT_EQ(r.msg.transforms().size(), 1u);
    const auto& t = r.msg.transforms()[0];
    EXPECT_EQ(t.header().frame_id(), "world");
    EXPECT_EQ(t.child_frame_id(), "base_link");
    EXPECT_EQ(t.transform().translation().x(), by_stamp.at(StampNs(t.header().stamp())).position_enu_m().x());
  }
  EXPECT_EQ(tf_static->samples()[0].msg.transforms()[0].child_frame_id(), "camera_left");
  for (const auto& r : diag->samples()) {
    ASSERT_FALSE(r.msg.status().empty());
    const auto& s = r.msg.status()[0];
    const v1::PoseUpdate& p = by_stamp.at(StampNs(r.msg.header().stamp()));
    EXPECT_EQ(s.hardware_id(), session.id());
    ASSERT_NE(Value(s, "sequence"), nullptr);
    EXPECT_EQ(std::stoull(Value(s, "sequence")), p.sequence());
    EXPECT_EQ(s.level(), p.mode() == v1::MODE_GPS_FUSED ? 0 : p.mode() == v1::MODE_LOST ? 2 : 1);
  }
  // The node in ROS 2's graph, its writers the ones the samples came from.
  ASSERT_TRUE(graph->WaitCount(1, 5));
  const auto nodes = graph->samples().back().msg.node_entities_info_seq();
  ASSERT_EQ(nodes.size(), 1u);
  EXPECT_EQ(nodes[0].node_name().to_string(), "locaid_ros2");
  const auto& writers = nodes[0].writer_gid_seq();
  EXPECT_TRUE(std::any_of(writers.begin(), writers.end(), [&](const auto& g) {
    return std::equal(g.data().begin(), g.data().end(), odom->samples()[0].publication.begin());
  }));
  EXPECT_EQ(ros2_->Stop(), 0) << ros2_->log();
  EXPECT_NE(ros2_->log().find("40 poses"), std::string::npos) << ros2_->log();
}

// A small car publishing on Fast DDS: 10 Hz stereo + CameraInfo, 100 Hz IMU,
// 10 Hz fixes, 20 Hz speed, /tf_static once; each fault on request.
class CarPublisher {
 public:
  struct Faults {
    std::atomic<bool> small_left_image{false}, imu_backwards{false}, speed_dies{false};
  };
  CarPublisher(FastPeer& fast, Faults& faults) : faults_(faults) {
    using namespace sensor_msgs::msg::dds_;
    left_ = fast.Advertise<Image_PubSubType>("rt/cam/left/image_raw");
    right_ = fast.Advertise<Image_PubSubType>("rt/cam/right/image_raw");
    left_info_ = fast.Advertise<CameraInfo_PubSubType>("rt/cam/left/camera_info");
    right_info_ = fast.Advertise<CameraInfo_PubSubType>("rt/cam/right/camera_info");
    imu_ = fast.Advertise<Imu_PubSubType>("rt/imu", {true, false, 100});
    fix_ = fast.Advertise<NavSatFix_PubSubType>("rt/fix");
    speed_ = fast.Advertise<geometry_msgs::msg::dds_::TwistStamped_PubSubType>("rt/speed");
    tf_ = fast.Advertise<tf2_msgs::msg::dds_::TFMessage_PubSubType>("rt/tf_static", {true, true, 1});
    auto tf = MakeTfStatic(kT0);
    tf_->Write(&tf);
    thread_ = std::thread([this, &fast] { Run(fast); });
  }
  ~CarPublisher() {
    stop_ = true;
    thread_.join();
  }
  int64_t ticks() const { return ticks_; }

 private:
  void Run(FastPeer& fast) {
    constexpr int64_t kTick = 10'000'000;  // 10 ms
    const auto start = std::chrono::steady_clock::now();
    for (int64_t k = 0; !stop_; ++k) {
      std::this_thread::sleep_until(start + std::chrono::milliseconds(10 * k));
      const int64_t t = kT0 + k * kTick;
      auto imu = MakeImu(faults_.imu_backwards.exchange(false) ? t - 50 * kTick : t, 0.2);
      imu_->Write(&imu);
      if (k % 5 == 0 && speed_) {
        if (faults_.speed_dies) {
          fast.Unadvertise(speed_);  // the publisher is gone: its topic goes silent
        } else {
          auto s = MakeTwist(t, 0.0);
          speed_->Write(&s);
        }
      }
      if (k % 10 == 0) {
        auto fix = MakeFix(t, 49.0 + 1e-6 * static_cast<double>(k));
        fix_->Write(&fix);
        auto li = MakeCameraInfo(t, "camera_left", 0), ri = MakeCameraInfo(t, "camera_right", -kCamF * kBaseline);
        left_info_->Write(&li);
        right_info_->Write(&ri);
        const bool small = faults_.small_left_image.exchange(false);
        auto l = MakeImage(t, "camera_left", static_cast<uint64_t>(k), small ? kCamW - 16 : kCamW);
        auto r = MakeImage(t + 2'000'000, "camera_right", static_cast<uint64_t>(k));
        left_->Write(&l);
        right_->Write(&r);
      }
      ticks_ = k;
    }
  }

  Faults& faults_;
  std::unique_ptr<FastWriter> left_, right_, left_info_, right_info_, imu_, fix_, speed_, tf_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> ticks_{0};
  std::thread thread_;
};

TEST_F(Ros2Car, ACarsTopicsFeedALiveSessionAndBadInputIsCountedAndNamed) {
  auto odom = fast_->Subscribe<nav_msgs::msg::dds_::Odometry_PubSubType>("rt/locaid/odometry", {true, false, 100});
  auto diag = fast_->Subscribe<diagnostic_msgs::msg::dds_::DiagnosticArray_PubSubType>("rt/diagnostics",
                                                                                         {true, false, 100});
  const fs::path inputs = dir_ / "car.yaml";
  std::ofstream(inputs) << "left_image: /cam/left/image_raw\nleft_info: /cam/left/camera_info\n"
                        << "right_image: /cam/right/image_raw\nright_info: /cam/right/camera_info\n"
                        << "imu: /imu\ngps: /fix\nspeed: /speed\n";
  CarPublisher::Faults faults;
  CarPublisher car(*fast_, faults);
  StartRos2({"--inputs", inputs.string(), "--silent-after-s", "1", "--diagnostics-period-s", "0.3"});
  ASSERT_TRUE(ros2_->WaitForLog("started (live, fed from DDS)", 30)) << ros2_->log();
  const std::string id = WaitSession(10);
  ASSERT_FALSE(id.empty());
  ASSERT_TRUE(odom->WaitCount(10, 30)) << ros2_->log();

  // The faults, each on its topic, while the car goes on.
  ParticipantOptions cyclone;
  cyclone.domain_id = loopback_->domain;
  Participant raw(cyclone);
  auto raw_imu = raw.CreateWriter("/imu", "sensor_msgs/msg/Imu", SensorDataQos());
  FastPeer other(loopback_->domain, loopback_->fastdds);  // one topic per name and participant
  auto wrong = other.Advertise<sm::NavSatFix_PubSubType>("rt/speed");  // another type on the speed topic
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (raw_imu->matched() < 1 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::string imu_cdr = Cdr<sm::Imu_PubSubType>(MakeImu(kT0));
  faults.small_left_image = true;
  faults.imu_backwards = true;
  faults.speed_dies = true;
  const size_t odometry_at_faults = odom->count();

  // Counted and named, the session going on.
  json stats;
  const auto counted = [&] {
    stats = ros2_->Stats();
    if (!stats.is_object() || !stats.contains("inputs")) return false;
    const json& in = stats["inputs"];
    return in["imu"]["undecodable"].get<int>() >= 1 && in["imu"]["late"].get<int>() >= 1 &&
           in["speed"]["wrong_type"].get<int>() >= 1 && in["speed"]["silences"].get<int>() >= 1 &&
           in["left_image"]["bad"].get<int>() >= 1;
  };
  const auto stats_until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!counted() && std::chrono::steady_clock::now() < stats_until) {
    // Truncated CDR, sent until it arrived: a best-effort reader misses what
    // comes before it matched this writer.
    raw_imu->Write(imu_cdr.substr(0, imu_cdr.size() - 20));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(counted()) << stats.dump(2) << "\n" << ros2_->log();
  EXPECT_NE(stats["inputs"]["imu"]["last_error"].get<std::string>().find("CDR:"), std::string::npos);
  EXPECT_NE(stats["inputs"]["left_image"]["last_error"].get<std::string>().find("80x64"), std::string::npos)
      << stats["inputs"]["left_image"]["last_error"];
  EXPECT_TRUE(odom->WaitCount(odometry_at_faults + 10, 20)) << "poses stopped after the faults";
  // The health on /diagnostics names the silent topic.
  EXPECT_TRUE(diag->WaitFor(
      [](const auto& samples) {
        for (const auto& r : samples)
          for (const auto& s : r.msg.status())
            if (s.name() == "locaid-ros2 inputs" && s.level() >= 1 && s.message().find("/speed silent") != std::string::npos)
              return true;
        return false;
      },
      10));
  const std::string log = ros2_->log();
  for (const char* named : {"/imu: CDR:", "is not after the previous message's", "/speed: silent",
                            "/speed: a publisher offers sensor_msgs/msg/NavSatFix",
                            "/cam/left/image_raw: image at"}) {
    EXPECT_NE(log.find(named), std::string::npos) << named << "\n" << log;
  }
  // The session saw frames, IMU, fixes; locaid-ros2 ends it with SIGTERM.
  const v1::SessionStats server_stats = st::GetStats(stub_.get(), id);
  EXPECT_GT(server_stats.frames_processed(), 10u);
  EXPECT_GT(server_stats.imu_samples(), 100u);
  EXPECT_GT(server_stats.gps_fixes_in(), 5u);
  EXPECT_EQ(ros2_->Stop(), 0) << ros2_->log();
  EXPECT_EQ(st::GetSession(stub_.get(), id).state(), v1::SESSION_STATE_FINISHED);
}

}  // namespace
}  // namespace locaid::ros2::testing
