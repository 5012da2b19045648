#include "ros2/input_assembler.hpp"

#include "ros/cdr.hpp"
#include "ros/images.hpp"
#include "ros/sensor_setup.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace locaid::ros2 {
namespace {

size_t Index(InputRole r) { return static_cast<size_t>(r); }

// The roles whose stamps hold the merge back (fixes never do).
constexpr InputRole kStreams[] = {InputRole::kLeftImage, InputRole::kRightImage, InputRole::kImu, InputRole::kSpeed};
// The roles whose silence is reported.
constexpr InputRole kWatched[] = {InputRole::kLeftImage, InputRole::kRightImage, InputRole::kImu, InputRole::kGps,
                                  InputRole::kSpeed};

std::string Seconds(int64_t ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", static_cast<double>(ns) * 1e-9);
  return text;
}

std::string Fixed(double v, int decimals) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", decimals, v);
  return text;
}

double ThreadCpuS() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

bool Finite(const Eigen::Vector3d& v) { return v.allFinite(); }

void SetVector(v1::Vector3* out, const Eigen::Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

// A NavSatFix as the session's GpsFix: a no-fix report, or the fix with its
// stated covariance (the diagonal as sigmas when the matrix is not positive
// definite), else the defaults for an unknown covariance.
v1::PushRequest GpsRequest(const ros::NavSatFix& nav, const AssemblerOptions& o) {
  v1::PushRequest req;
  v1::GpsFix* g = req.mutable_gps();
  g->set_t_ns(nav.header.stamp_ns);
  if (!ros::HasPosition(nav)) {
    g->set_fix_type(v1::GPS_FIX_NONE);
    return req;
  }
  g->set_fix_type(nav.status > 0 ? v1::GPS_FIX_DGPS : v1::GPS_FIX_3D);  // SBAS / GBAS: augmented
  g->set_latitude_deg(nav.latitude);
  g->set_longitude_deg(nav.longitude);
  g->set_altitude_m(nav.altitude);
  const auto cov = ros::StatedCovariance(nav);
  if (cov && Eigen::LLT<Eigen::Matrix3d>(*cov).info() == Eigen::Success) {
    for (int i = 0; i < 9; ++i) g->add_covariance_enu_m2((*cov)(i / 3, i % 3));
  } else if (cov) {
    g->set_sigma_horizontal_m(std::sqrt(0.5 * ((*cov)(0, 0) + (*cov)(1, 1))));
    g->set_sigma_vertical_m(std::sqrt((*cov)(2, 2)));
  } else {
    g->set_sigma_horizontal_m(o.gps_sigma_h_m);
    g->set_sigma_vertical_m(o.gps_sigma_v_m);
  }
  return req;
}

cv::Mat Gray(const std::string& type, std::string_view cdr) {
  return type == ros::kCompressedImage ? ros::ToGray(ros::DecodeCompressedImage(cdr))
                                       : ros::ToGray(ros::DecodeImage(cdr));
}

std::string Bytes(const cv::Mat& image) {
  const cv::Mat m = image.isContinuous() ? image : image.clone();
  return std::string(reinterpret_cast<const char*>(m.data), m.total());
}

}  // namespace

InputAssembler::InputAssembler(InputTopics topics, InputRig rig, AssemblerOptions options,
                               std::function<void(const std::string&)> log)
    : topics_(std::move(topics)),
      rig_(std::move(rig)),
      options_(options),
      log_(std::move(log)),
      pairer_(static_cast<int64_t>(options_.stereo_tolerance_s * 1e9), kMaxWaitingImages) {
  last_stamp_.fill(INT64_MIN);
  newest_.fill(INT64_MIN);
  for (size_t i = 0; i < kInputRoleCount; ++i) {
    stats_[i].topic = topics_.topic[i];
    stats_[i].type = topics_.type[i];
  }
  started_ = InputClock::now();
}

bool InputAssembler::IsStream(InputRole role) const { return !topics_.topic_of(role).empty(); }

void InputAssembler::Problem(InputRole role, uint64_t TopicStats::*counter, const std::string& why) {
  TopicStats& s = S(role);
  ++(s.*counter);
  s.last_error = why;
  const uint64_t n = ++problems_logged_[Index(role)];
  if (log_ && (n <= 3 || n % 100 == 0)) {
    log_(s.topic + ": " + why + (n > 3 ? " (" + std::to_string(n) + " problems on this topic so far)" : ""));
  }
}

void InputAssembler::Add(InputRole role, std::string_view cdr, InputClock::time_point now, Out& out) {
  TopicStats& s = S(role);
  ++s.received;
  if (s.silent) {
    s.silent = false;
    if (log_) log_(s.topic + ": messages again");
  }
  last_arrival_[Index(role)] = now;
  int64_t stamp = 0;
  Held held;
  try {
    switch (role) {
      case InputRole::kLeftImage:
      case InputRole::kRightImage:
        stamp = ros::DecodeHeader(cdr).stamp_ns;
        break;
      case InputRole::kImu: {
        const auto imu = ros::DecodeImu(cdr);
        stamp = imu.header.stamp_ns;
        if (!Finite(imu.linear_acceleration) || !Finite(imu.angular_velocity)) {
          Problem(role, &TopicStats::bad, "IMU sample at " + Seconds(stamp) + " s is not finite: dropped");
          return;
        }
        v1::ImuSample* i = held.request.mutable_imu();
        i->set_t_ns(stamp);
        SetVector(i->mutable_accel_mps2(), imu.linear_acceleration);
        SetVector(i->mutable_gyro_radps(), imu.angular_velocity);
        break;
      }
      case InputRole::kGps: {
        const auto nav = ros::DecodeNavSatFix(cdr);
        stamp = nav.header.stamp_ns;
        held.request = GpsRequest(nav, options_);
        break;
      }
      case InputRole::kSpeed: {
        const auto twist = ros::DecodeTwistStamped(cdr);
        stamp = twist.header.stamp_ns;
        if (!std::isfinite(twist.linear.x())) {
          Problem(role, &TopicStats::bad, "speed at " + Seconds(stamp) + " s is not finite: dropped");
          return;
        }
        held.request.mutable_speed()->set_t_ns(stamp);
        held.request.mutable_speed()->set_speed_mps(twist.linear.x());
        break;
      }
      case InputRole::kLeftInfo:
      case InputRole::kRightInfo:
        (void)ros::DecodeCameraInfo(cdr);  // the session's camera is the first one's; later ones are counted
        ++s.used;
        return;
      case InputRole::kTfStatic:
        (void)ros::DecodeTfMessage(cdr);
        ++s.used;
        return;
      case InputRole::kCount:
        return;
    }
  } catch (const ros::CdrError& e) {
    Problem(role, &TopicStats::undecodable, e.what());
    return;
  }
  if (stamp <= last_stamp_[Index(role)]) {
    Problem(role, &TopicStats::late,
            "stamp " + Seconds(stamp) + " s is not after the previous message's (" +
                Seconds(last_stamp_[Index(role)]) + " s): dropped");
    return;
  }
  last_stamp_[Index(role)] = stamp;
  if (role == InputRole::kGps && stamp < released_ns_) {
    out.push_back(std::move(held.request));  // the session judges a late fix
    ++s.used;
    return;
  }
  if (stamp < released_ns_) {
    Problem(role, &TopicStats::late,
            "stamp " + Seconds(stamp) + " s is older than data already sent (" + Seconds(released_ns_) +
                " s): dropped (a larger --reorder-window-ms keeps it)");
    return;
  }
  newest_[Index(role)] = std::max(newest_[Index(role)], stamp);
  newest_ns_ = std::max(newest_ns_, stamp);
  if (role == InputRole::kLeftImage || role == InputRole::kRightImage) {
    AddImage(role, stamp, cdr);
  } else {
    held.role = role;
    Hold(stamp, std::move(held));
  }
  Release(now, out, false);
}

void InputAssembler::Hold(int64_t stamp_ns, Held held) {
  held.stamp_ns = stamp_ns;
  held.order = order_++;
  held_.push(std::move(held));
}

void InputAssembler::AddImage(InputRole side, int64_t stamp_ns, std::string_view cdr) {
  const auto role_of = [](pipeline::StereoSide s) {
    return s == pipeline::StereoSide::kLeft ? InputRole::kLeftImage : InputRole::kRightImage;
  };
  const auto unpaired = [&](pipeline::StereoSide s, const Image& image) {
    Problem(role_of(s), &TopicStats::unpaired,
            "image at " + Seconds(image.stamp_ns) + " s has no stereo partner within " +
                Fixed(options_.stereo_tolerance_s * 1e3, 1) + " ms: dropped");
  };
  const pipeline::StereoSide s = side == InputRole::kLeftImage ? pipeline::StereoSide::kLeft
                                                                : pipeline::StereoSide::kRight;
  if (auto dropped = pairer_.Add(s, stamp_ns, Image{stamp_ns, std::string(cdr)})) unpaired(s, *dropped);
  pairer_.Pair(
      [&](Image left, Image right) {
        Held frame;
        frame.frame = true;
        frame.left = std::move(left.cdr);
        frame.right = std::move(right.cdr);
        Hold(left.stamp_ns, std::move(frame));  // a frame's time is its left image's
      },
      unpaired);
}

void InputAssembler::Tick(InputClock::time_point now, Out& out) { Release(now, out, false); }

void InputAssembler::Flush(Out& out) { Release(InputClock::now(), out, true); }

void InputAssembler::Release(InputClock::time_point now, Out& out, bool all) {
  for (const InputRole r : kWatched) {
    if (!IsStream(r)) continue;
    TopicStats& s = S(r);
    const auto since = now - last_arrival_[Index(r)].value_or(started_);
    if (!s.silent && since > std::chrono::duration<double>(options_.silent_after_s)) {
      s.silent = true;
      ++s.silences;
      if (log_) {
        log_(s.topic + ": " + (s.received ? "silent" : "no message") + " for " +
             Fixed(std::chrono::duration<double>(since).count(), 1) + " s");
      }
    }
  }
  // What a stream yet to come can still bring is after its newest stamp;
  // a frame's time is its left image's, so a left image still waiting for
  // its partner holds the merge back too.
  int64_t limit = INT64_MAX;
  bool holding = false;
  for (const InputRole r : kStreams) {
    if (!IsStream(r) || S(r).silent || r == InputRole::kRightImage) continue;
    limit = std::min(limit, newest_[Index(r)]);
    holding = true;
  }
  const auto waiting_left = pairer_.OldestWaiting(pipeline::StereoSide::kLeft);
  if (waiting_left && !S(InputRole::kLeftImage).silent) limit = std::min(limit, *waiting_left - 1);
  if (!holding) limit = newest_ns_;
  const auto window_ns = static_cast<int64_t>(options_.reorder_window_s * 1e9);
  if (newest_ns_ != INT64_MIN) limit = std::max(limit, newest_ns_ - window_ns);
  // A fix that may still come holds the others back for gps_hold_s at most:
  // sent in order, it is fused where it belongs, not as a late fix.
  const auto gps_hold_ns = static_cast<int64_t>(std::min(options_.gps_hold_s, options_.reorder_window_s) * 1e9);
  if (IsStream(InputRole::kGps) && !S(InputRole::kGps).silent && gps_hold_ns > 0 && newest_ns_ != INT64_MIN)
    limit = std::min(limit, std::max(newest_[Index(InputRole::kGps)], newest_ns_ - gps_hold_ns));
  if (all) limit = INT64_MAX;
  while (!held_.empty() && held_.top().stamp_ns <= limit) {
    Held h = held_.top();
    held_.pop();
    released_ns_ = std::max(released_ns_, h.stamp_ns);
    Send(std::move(h), out);
  }
}

void InputAssembler::Send(Held h, Out& out) {
  if (!h.frame) {
    ++S(h.role).used;
    out.push_back(std::move(h.request));
    return;
  }
  const double cpu0 = ThreadCpuS();
  cv::Mat rectified[2];
  const InputRole sides[2] = {InputRole::kLeftImage, InputRole::kRightImage};
  const ros::Rectifier* rectifiers[2] = {&rig_.rectified->left, &rig_.rectified->right};
  const std::string* images[2] = {&h.left, &h.right};
  bool ok = true;
  for (int i = 0; i < 2 && ok; ++i) {
    try {
      rectified[i] = rectifiers[i]->Rectify(Gray(topics_.type_of(sides[i]), *images[i]));
    } catch (const ros::CdrError& e) {
      Problem(sides[i], &TopicStats::undecodable, e.what());
      ok = false;
    } catch (const std::exception& e) {
      Problem(sides[i], &TopicStats::bad, "image at " + Seconds(h.stamp_ns) + " s: " + e.what() + ": frame dropped");
      ok = false;
    }
  }
  image_cpu_s_ += ThreadCpuS() - cpu0;
  if (!ok) return;
  v1::PushRequest req;
  v1::StereoFrame* f = req.mutable_frame();
  f->set_t_ns(h.stamp_ns);
  f->set_encoding(v1::IMAGE_ENCODING_GRAY8);
  f->set_left(Bytes(rectified[0]));
  f->set_right(Bytes(rectified[1]));
  out.push_back(std::move(req));
  ++S(InputRole::kLeftImage).used;
  ++S(InputRole::kRightImage).used;
  ++frames_;
}

void InputAssembler::WrongType(InputRole role, const std::string& offered_type) {
  Problem(role, &TopicStats::wrong_type,
          "a publisher offers " + offered_type + ", expected " + topics_.type_of(role) +
              ": DDS does not match it, its messages never arrive");
}

std::vector<std::pair<InputRole, TopicStats>> InputAssembler::stats(InputClock::time_point now) const {
  std::vector<std::pair<InputRole, TopicStats>> out;
  for (size_t i = 0; i < kInputRoleCount; ++i) {
    if (topics_.topic[i].empty()) continue;
    TopicStats s = stats_[i];
    if (last_arrival_[i]) s.since_last_s = std::chrono::duration<double>(now - *last_arrival_[i]).count();
    out.emplace_back(static_cast<InputRole>(i), std::move(s));
  }
  return out;
}

output::DiagnosticStatus InputAssembler::Health(InputClock::time_point now) {
  output::DiagnosticStatus h;
  h.name = "locaid-ros2 inputs";
  uint64_t errors = 0;
  std::string problems;
  bool camera_silent = false, silent = false;
  for (const auto& [role, s] : stats(now)) {
    const std::string key = InputRoleKey(role);
    errors += s.undecodable + s.late + s.bad + s.unpaired + s.wrong_type;
    h.values.insert(h.values.end(), {{key + ".topic", s.topic},
                                     {key + ".received", std::to_string(s.received)},
                                     {key + ".used", std::to_string(s.used)},
                                     {key + ".undecodable", std::to_string(s.undecodable)},
                                     {key + ".late", std::to_string(s.late)},
                                     {key + ".bad", std::to_string(s.bad)},
                                     {key + ".unpaired", std::to_string(s.unpaired)},
                                     {key + ".wrong_type", std::to_string(s.wrong_type)},
                                     {key + ".silent", s.silent ? "true" : "false"}});
    if (!s.last_error.empty()) h.values.emplace_back(key + ".last_error", s.last_error);
    if (s.silent) {
      silent = true;
      camera_silent = camera_silent || role == InputRole::kLeftImage || role == InputRole::kRightImage;
      problems += (problems.empty() ? "" : "; ") + s.topic + " silent" +
                  (s.since_last_s >= 0 ? " for " + Fixed(s.since_last_s, 1) + " s" : " (no message yet)");
    }
  }
  const bool new_errors = errors > errors_at_health_;
  if (new_errors) {
    problems += (problems.empty() ? "" : "; ") + std::to_string(errors - errors_at_health_) + " bad message(s)";
  }
  errors_at_health_ = errors;
  h.level = camera_silent                ? output::DiagnosticStatus::kError
            : silent || new_errors       ? output::DiagnosticStatus::kWarn
                                         : output::DiagnosticStatus::kOk;
  h.message = problems.empty() ? "inputs live" : problems;
  h.values.emplace_back("frames_sent", std::to_string(frames_));
  return h;
}

}  // namespace locaid::ros2
