// BagFrameSource: a ROS 2 bag (bag/ros_bag.hpp) as a source of stereo frames
// and typed measurements, for locaid-replay --bag and a session's bag source.
//
// Topics are named by the options or picked by type from a preview of the
// bag's first seconds (bag/bag_topics.hpp). Time is every message's
// header.stamp, never the log time: messages are merged in stamp order
// within `reorder_window_s` (a message later than that is counted and
// dropped). Left and right images pair when their stamps are within
// `stereo_tolerance_s`; an image without a partner is a skipped frame.
// Raw images are rectified from their CameraInfo (ros/camera_model.hpp) and
// cropped to the region without border both cameras share; the
// camera-IMU extrinsic and the GPS antenna lever arm come from /tf_static.
//
// The IMU's frame is the body frame (x forward, y left, z up, REP-103); with
// no IMU topic the body is the rectified left camera turned to x forward.
// Measured IMU, fixes and speed go out as measured (a scenario adds outages
// only); a NavSatFix with status NO_FIX or a NaN position is no fix.
//
// Bounds: the reorder buffer holds at most `max_buffered_messages` messages
// (older ones are released early beyond that).
#pragma once

#include "bag/bag_topics.hpp"
#include "bag/ros_bag.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/stereo_pairer.hpp"
#include "ros/camera_model.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <queue>
#include <string>
#include <vector>

namespace locaid::pipeline {

struct BagSourceOptions {
  bag::BagTopics topics;             // empty entries: picked by type
  // Left/right stamps further apart are no pair. Hardware-triggered stereo
  // with software time stamps is a few ms apart (KITTI: up to 6.8 ms); 10 ms
  // still pairs unambiguously up to 50 Hz.
  double stereo_tolerance_s = 0.010;
  double reorder_window_s = 0.5;      // stamp-order merge window
  double preview_s = 5;               // log time scanned to pick topics
  size_t max_buffered_messages = 20000;
  // Used for fixes whose covariance type is UNKNOWN (or zero).
  double gps_sigma_h_m = 3.0, gps_sigma_v_m = 5.0;
};

// What the source counted, for a user (locaid-replay prints it).
struct BagSourceStats {
  uint64_t frames = 0, unpaired_images = 0, bad_images = 0;
  uint64_t imu = 0, fixes = 0, no_fix = 0, speed = 0;
  uint64_t late = 0;       // older than the reorder window or than the last of their topic
  uint64_t undecodable = 0;  // sensor messages whose CDR did not decode
};

class BagFrameSource : public FrameSource {
 public:
  // Throws std::runtime_error (bag::McapError) with what is wrong: the bag,
  // the topics, the camera_info or the transforms.
  BagFrameSource(const std::filesystem::path& bag, BagSourceOptions options);

  SourceItem Next() override;
  const StereoCamera& camera() const override { return camera_; }
  Eigen::Isometry3d T_cam0_imu() const override { return T_cam0_imu_; }
  int64_t total_frames() const override { return frames_hint_; }
  double duration_s() const override { return duration_hint_s_; }

  const bag::BagTopics& topics() const { return topics_; }
  // Whether it has an IMU topic: without one the filter runs its odometry
  // model (as locaid-replay --no-imu), never the IMU model starved of IMU.
  bool has_imu() const { return !topics_.imu.empty(); }
  // The GPS antenna in the body frame (from /tf_static; zero when not given).
  const Eigen::Vector3d& gps_lever_arm_body_m() const { return lever_arm_; }
  const BagSourceStats& stats() const { return stats_; }
  // Notes about the setup (extrinsic source, lever arm) and the bag (cut files).
  std::vector<std::string> notes() const;
  uint64_t bytes_total() const { return bag_->total_bytes(); }
  uint64_t bytes_done() const { return bag_->bytes_done(); }

 private:
  enum class Role { kLeft, kRight, kImu, kGps, kSpeed };
  struct Pending {
    int64_t stamp_ns = 0;
    uint64_t order = 0;  // arrival order: ties keep file order
    Role role = Role::kImu;
    std::string type, data, where;
    bool operator>(const Pending& o) const {
      return stamp_ns != o.stamp_ns ? stamp_ns > o.stamp_ns : order > o.order;
    }
  };

  // Reads the bag into the reorder buffer until its oldest message is out of
  // the window; false when nothing is left.
  bool Fill();
  void Handle(Pending p);
  void AddSample(const Pending& p);
  // A skipped frame for an image without a partner.
  void Unpaired(const Pending& image, const std::string& why);
  SourceItem MakeFrame(Pending left, Pending right);
  cv::Mat Decode(const Pending& image, const ros::Rectifier& rectifier) const;

  BagSourceOptions options_;
  std::unique_ptr<bag::RosBag> bag_;
  bag::BagTopics topics_;
  StereoCamera camera_;
  std::optional<ros::RectifiedStereo> rectified_;  // both rectifiers, cropped to what both cameras see
  Eigen::Isometry3d T_cam0_imu_ = Eigen::Isometry3d::Identity();
  Eigen::Vector3d lever_arm_ = Eigen::Vector3d::Zero();
  std::vector<std::string> setup_notes_;
  int64_t frames_hint_ = 0;
  double duration_hint_s_ = 0;

  std::priority_queue<Pending, std::vector<Pending>, std::greater<>> buffer_;
  uint64_t order_ = 0;
  int64_t newest_stamp_ns_ = INT64_MIN, released_stamp_ns_ = INT64_MIN;
  bool bag_done_ = false;
  // Left and right images by stamp; one waits per side (messages come in
  // stamp order: a second of its side means the first has no partner).
  StereoPairer<Pending> pairer_;
  SampleBatch samples_;
  int64_t last_imu_ns_ = INT64_MIN, last_gps_ns_ = INT64_MIN, last_speed_ns_ = INT64_MIN;
  int64_t last_frame_ns_ = INT64_MIN;
  int64_t next_index_ = 0;
  std::deque<SourceItem> ready_;
  std::string pending_error_;  // the last dropped message's reason, reported with the next item
  BagSourceStats stats_;
};

}  // namespace locaid::pipeline
