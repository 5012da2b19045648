#include "pipeline/bag_frame_source.hpp"

#include "ros/cdr.hpp"
#include "ros/images.hpp"
#include "ros/sensor_setup.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace locaid::pipeline {
namespace {

std::string Seconds(int64_t ns) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6f", static_cast<double>(ns) * 1e-9);
  return buf;
}

std::string Millis(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g ms", s * 1e3);
  return buf;
}

bool Finite(const Eigen::Vector3d& v) { return v.allFinite(); }

}  // namespace

BagFrameSource::BagFrameSource(const std::filesystem::path& path, BagSourceOptions options)
    : options_(std::move(options)), pairer_(static_cast<int64_t>(options_.stereo_tolerance_s * 1e9), 1) {
  if (!(options_.stereo_tolerance_s >= 0) || !(options_.reorder_window_s >= 0) || options_.max_buffered_messages < 2)
    throw std::invalid_argument("bag source: tolerances must be >= 0 and the buffer at least 2 messages");
  {
    bag::RosBag preview(path);
    const bag::BagInventory inv =
        bag::ScanBag(preview, static_cast<uint64_t>(options_.preview_s * 1e9));
    topics_ = bag::ChooseTopics(inv, options_.topics);
    const auto info = [&](const std::string& topic) -> const ros::CameraInfo& {
      const auto it = inv.topics.find(topic);
      if (it == inv.topics.end() || !it->second.camera_info) {
        throw std::runtime_error(path.string() + ": no camera_info message on " + topic + " in the first " +
                                 std::to_string(options_.preview_s) + " s of the bag");
      }
      return *it->second.camera_info;
    };
    const ros::CameraInfo& left = info(topics_.left_info);
    const ros::CameraInfo& right = info(topics_.right_info);
    try {
      rectified_.emplace(ros::MakeRectifiedStereo(left, right));
      camera_ = rectified_->camera;
      setup_notes_.push_back(rectified_->note);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(path.string() + ": " + topics_.left_info + " / " + topics_.right_info + ": " +
                               e.what());
    }

    const std::string& cam_frame = left.header.frame_id;
    if (!topics_.imu.empty()) {
      const std::string imu_frame = inv.topics.count(topics_.imu) ? inv.topics.at(topics_.imu).frame_id : "";
      if (imu_frame.empty()) {
        throw std::runtime_error(path.string() + ": no message on " + topics_.imu + " in the first " +
                                 std::to_string(options_.preview_s) + " s: cannot tell the IMU's frame");
      }
      const auto T_cam0_imu = ros::CameraImuExtrinsic(left, inv.static_transforms, imu_frame);
      if (!T_cam0_imu) {
        throw std::runtime_error(path.string() + ": /tf_static does not connect the IMU frame '" + imu_frame +
                                 "' and the left camera frame '" + cam_frame +
                                 "' (the camera-IMU extrinsic); record /tf_static or run without the IMU "
                                 "(imu: none in --bag-topics FILE)");
      }
      T_cam0_imu_ = *T_cam0_imu;
      setup_notes_.push_back("camera-IMU extrinsic from /tf_static: " + imu_frame + " -> " + cam_frame);
    } else {
      T_cam0_imu_ = ros::CameraBodyWithoutImu();
      setup_notes_.push_back("no IMU topic: the body frame is the rectified left camera turned x forward");
    }
    if (!topics_.gps.empty() && inv.topics.count(topics_.gps)) {
      const std::string gps_frame = inv.topics.at(topics_.gps).frame_id;
      if (const auto lever_arm = ros::GpsLeverArm(left, inv.static_transforms, T_cam0_imu_, gps_frame)) {
        lever_arm_ = *lever_arm;
      } else {
        setup_notes_.push_back("no /tf_static transform to the GPS frame '" + gps_frame +
                               "': antenna lever arm taken as zero");
      }
    }
    if (inv.complete && inv.topics.count(topics_.left_image)) {
      const auto& s = inv.topics.at(topics_.left_image);
      frames_hint_ = static_cast<int64_t>(s.count);
      duration_hint_s_ = static_cast<double>(s.last_stamp_ns - s.first_stamp_ns) * 1e-9;
    }
  }
  bag_ = std::make_unique<bag::RosBag>(path);
}

std::vector<std::string> BagFrameSource::notes() const {
  std::vector<std::string> out = setup_notes_;
  for (auto& n : bag_->notes()) out.push_back(std::move(n));
  return out;
}

bool BagFrameSource::Fill() {
  const auto window_ns = static_cast<int64_t>(options_.reorder_window_s * 1e9);
  bag::BagMessage m;
  while (!bag_done_ && buffer_.size() < options_.max_buffered_messages &&
         (buffer_.empty() || buffer_.top().stamp_ns > newest_stamp_ns_ - window_ns)) {
    if (!bag_->Next(m)) {
      bag_done_ = true;
      break;
    }
    Role role;
    if (m.topic == topics_.left_image) {
      role = Role::kLeft;
    } else if (m.topic == topics_.right_image) {
      role = Role::kRight;
    } else if (!topics_.imu.empty() && m.topic == topics_.imu) {
      role = Role::kImu;
    } else if (!topics_.gps.empty() && m.topic == topics_.gps) {
      role = Role::kGps;
    } else if (!topics_.speed.empty() && m.topic == topics_.speed) {
      role = Role::kSpeed;
    } else {
      continue;
    }
    Pending p;
    try {
      p.stamp_ns = ros::DecodeHeader(m.data).stamp_ns;
    } catch (const ros::CdrError& e) {
      ++stats_.undecodable;
      pending_error_ = m.Where() + ": " + e.what();
      continue;
    }
    if (p.stamp_ns < released_stamp_ns_) {
      ++stats_.late;
      pending_error_ = m.Where() + ": stamp " + Seconds(p.stamp_ns) + " s is older than messages already used (" +
                       Seconds(released_stamp_ns_) + " s): dropped (a larger reorder window keeps it)";
      continue;
    }
    p.order = order_++;
    p.role = role;
    p.type = std::string(m.type);
    p.data = std::string(m.data);
    p.where = m.Where();
    newest_stamp_ns_ = std::max(newest_stamp_ns_, p.stamp_ns);
    buffer_.push(std::move(p));
  }
  return !buffer_.empty();
}

SourceItem BagFrameSource::Next() {
  while (ready_.empty()) {
    if (!Fill()) {
      // The end: images without a partner, then the last samples.
      pairer_.Drain([this](StereoSide, const Pending& image) {
        Unpaired(image, "the bag ends before its stereo partner");
      });
      if (!samples_.empty()) {
        SourceItem s;
        s.kind = SourceItem::Kind::kSamples;
        s.t_ns = newest_stamp_ns_;
        s.samples = std::exchange(samples_, {});
        ready_.push_back(std::move(s));
      }
      SourceItem end;
      end.kind = SourceItem::Kind::kEnd;
      ready_.push_back(std::move(end));
      break;
    }
    Pending p = buffer_.top();
    buffer_.pop();
    released_stamp_ns_ = std::max(released_stamp_ns_, p.stamp_ns);
    Handle(std::move(p));
  }
  SourceItem item = std::move(ready_.front());
  ready_.pop_front();
  if (item.kind != SourceItem::Kind::kEnd && item.error.empty() && !pending_error_.empty())
    item.error = std::exchange(pending_error_, {});
  if (item.kind == SourceItem::Kind::kEnd) {
    ready_.push_back(item);  // Next() after the end keeps saying so
  }
  return item;
}

void BagFrameSource::Handle(Pending p) {
  if (p.role != Role::kLeft && p.role != Role::kRight) {
    AddSample(p);
    return;
  }
  const StereoSide side = p.role == Role::kLeft ? StereoSide::kLeft : StereoSide::kRight;
  const int64_t stamp_ns = p.stamp_ns;
  if (const std::optional<Pending> before = pairer_.Add(side, stamp_ns, std::move(p))) {
    // the previous image of this side never found a partner
    Unpaired(*before, std::string("no ") + (side == StereoSide::kLeft ? "right" : "left") + " image within " +
                          Millis(options_.stereo_tolerance_s));
  }
  pairer_.Pair([this](Pending left, Pending right) { ready_.push_back(MakeFrame(std::move(left), std::move(right))); },
               [this](StereoSide, const Pending& older) {
                 // The older one has no partner any more (messages come in stamp order).
                 Unpaired(older, "no stereo partner within " + Millis(options_.stereo_tolerance_s));
               });
}

void BagFrameSource::Unpaired(const Pending& image, const std::string& why) {
  SourceItem s;
  s.kind = SourceItem::Kind::kSkipped;
  s.index = next_index_++;
  s.t_ns = image.stamp_ns;
  s.error = image.where + ": " + why;
  ++stats_.unpaired_images;
  ready_.push_back(std::move(s));
}

cv::Mat BagFrameSource::Decode(const Pending& image, const ros::Rectifier& rectifier) const {
  const cv::Mat raw = image.type == ros::kImage ? ros::ToGray(ros::DecodeImage(image.data))
                                                : ros::ToGray(ros::DecodeCompressedImage(image.data));
  return rectifier.Rectify(raw);
}

SourceItem BagFrameSource::MakeFrame(Pending left, Pending right) {
  SourceItem item;
  item.index = next_index_++;
  item.t_ns = left.stamp_ns;
  samples_.MoveUpTo(item.t_ns, item.samples);
  if (item.t_ns <= last_frame_ns_) {
    item.kind = SourceItem::Kind::kCorrupt;
    item.error = left.where + ": frame time " + Seconds(item.t_ns) + " s is not after the previous frame's";
    return item;
  }
  try {
    pair_runner().Run([&] { item.left = Decode(left, rectified_->left); },
                      [&] {
                        try {
                          item.right = Decode(right, rectified_->right);
                        } catch (const std::exception& e) {
                          throw std::runtime_error(right.where + ": " + e.what());
                        }
                      });
  } catch (const std::exception& e) {
    item.kind = SourceItem::Kind::kCorrupt;
    item.error = std::string(item.left.empty() ? left.where + ": " : "") + e.what();
    item.left.release();
    item.right.release();
    ++stats_.bad_images;
    return item;
  }
  item.kind = SourceItem::Kind::kFrame;
  last_frame_ns_ = item.t_ns;
  ++stats_.frames;
  return item;
}

void BagFrameSource::AddSample(const Pending& p) {
  // A reading older than its topic's last one, or not finite, is dropped and
  // counted; otherwise `last` moves on to it.
  const auto in_order = [&](int64_t stamp_ns, int64_t& last, bool finite, const char* what) {
    if (stamp_ns > last && finite) {
      last = stamp_ns;
      return true;
    }
    ++stats_.late;
    pending_error_ = p.where + ": " + what + " not after the previous one or not finite: dropped";
    return false;
  };
  try {
    if (p.role == Role::kImu) {
      const auto imu = ros::DecodeImu(p.data);
      if (!in_order(imu.header.stamp_ns, last_imu_ns_,
                    Finite(imu.linear_acceleration) && Finite(imu.angular_velocity), "IMU sample"))
        return;
      fusion::ImuSample s;
      s.t_ns = imu.header.stamp_ns;
      s.accel_mps2 = imu.linear_acceleration;
      s.gyro_radps = imu.angular_velocity;
      samples_.imu.push_back(s);
      ++stats_.imu;
    } else if (p.role == Role::kGps) {
      const auto nav = ros::DecodeNavSatFix(p.data);
      if (!in_order(nav.header.stamp_ns, last_gps_ns_, true, "fix")) return;
      if (!ros::HasPosition(nav)) {
        samples_.receiver_has_fix = false;
        ++stats_.no_fix;
        return;
      }
      ArrivedFix a;
      a.fix.t_ns = nav.header.stamp_ns;
      a.fix.lat_deg = nav.latitude;
      a.fix.lon_deg = nav.longitude;
      a.fix.alt_m = nav.altitude;
      a.fix.sigma_h_m = options_.gps_sigma_h_m;
      a.fix.sigma_v_m = options_.gps_sigma_v_m;
      if (const auto cov = ros::StatedCovariance(nav)) a.fix.cov_enu_m2 = *cov;
      samples_.gps.push_back(a);
      samples_.receiver_has_fix = true;
      ++stats_.fixes;
    } else {
      const auto twist = ros::DecodeTwistStamped(p.data);
      if (!in_order(twist.header.stamp_ns, last_speed_ns_, std::isfinite(twist.linear.x()), "speed reading")) return;
      fusion::SpeedSample s;
      s.t_ns = twist.header.stamp_ns;
      s.speed_mps = twist.linear.x();
      samples_.speed.push_back(s);
      ++stats_.speed;
    }
  } catch (const ros::CdrError& e) {
    ++stats_.undecodable;
    pending_error_ = p.where + ": " + e.what();
  }
}

}  // namespace locaid::pipeline
