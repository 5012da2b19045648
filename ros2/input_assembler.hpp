// A car's ROS 2 messages, as they arrive over DDS, turned into what a live
// session takes (PushRequest imu / gps / speed / frame), in header.stamp
// order, with every bad message counted against its topic and named.
//
//  - Time is each message's header.stamp. Messages are merged in stamp
//    order: one is sent once every stream (left, right, IMU, speed) has
//    passed its stamp, or once it is `reorder_window_s` older than the
//    newest message (a stream that stalls delays the others by at most the
//    window); messages of equal stamps go out as a replay fuses them (IMU,
//    fix, speed, frame). A message older than what was already sent, or not after the
//    previous one of its topic, is dropped and counted late. Fixes hold the
//    others back for at most `gps_hold_s` (a receiver at 1 Hz would hold
//    everything a second); a fix later than that goes out at once and the
//    session fuses it as a late fix (against where the antenna was).
//  - Left and right images whose stamps are within `stereo_tolerance_s` are
//    a pair (its time: the left stamp; pipeline/stereo_pairer.hpp, as for
//    bags and the server's cameras); an image without a partner is counted
//    unpaired. A pair is decoded (Image or CompressedImage to gray,
//    ros/images.hpp) and rectified from its CameraInfo when it is sent:
//    GRAY8 frames of the rectified camera. An image that does not decode or
//    whose size is not its CameraInfo's is counted bad, the frame dropped.
//  - Imu: linear_acceleration, angular_velocity (body = the IMU's frame);
//    NavSatFix: a fix (status above NO_FIX, position in range) with its
//    stated covariance, else the defaults, or a no-fix report (an outage);
//    TwistStamped: twist.linear.x, the forward speed. Non-finite values are
//    counted bad.
//  - A topic without a message for `silent_after_s` is silent: it no longer
//    holds the others back and its health says so until it speaks again.
//
// Not thread-safe: one thread feeds it (the caller serializes Health()).
#pragma once

#include "locaid/v1/localization.pb.h"
#include "output/ros2_messages.hpp"
#include "pipeline/stereo_pairer.hpp"
#include "ros2/input_setup.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <queue>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::ros2 {

using InputClock = std::chrono::steady_clock;

struct AssemblerOptions {
  double stereo_tolerance_s = 0.010;
  double reorder_window_s = 0.3;
  double silent_after_s = 2.0;
  // How long the merge waits for a fix that may still come (at most the
  // reorder window). Measured on the KITTI excerpt: fixes fused as late
  // fixes (0 here) end a 10 s outage 0.92 m off, sent in order 0.67 m, as
  // the replay.
  double gps_hold_s = 0.2;
  // For fixes whose covariance type is UNKNOWN (or zero), as for bags.
  double gps_sigma_h_m = 3.0, gps_sigma_v_m = 5.0;
};

struct TopicStats {
  std::string topic, type;
  uint64_t received = 0, used = 0;
  uint64_t undecodable = 0;  // CDR that does not decode as the type
  uint64_t late = 0;         // stamp not after the previous one, or older than what was sent
  uint64_t bad = 0;          // decodes, but unusable: image size or encoding, non-finite values
  uint64_t unpaired = 0;     // images without a stereo partner
  uint64_t wrong_type = 0;   // publications of another type on the topic (DDS never matches them)
  uint64_t silences = 0;     // times it went silent
  bool silent = false;
  double since_last_s = -1;  // wall seconds since its last message (-1: none yet)
  std::string last_error;
};

class InputAssembler {
 public:
  using Out = std::vector<v1::PushRequest>;
  // `log` gets one line per new kind of problem on a topic and when a topic
  // goes silent or speaks again (may be empty).
  InputAssembler(InputTopics topics, InputRig rig, AssemblerOptions options,
                 std::function<void(const std::string&)> log = {});

  // One message on `role` (its CDR), arriving at `now`; what is due is
  // appended to `out` in stamp order.
  void Add(InputRole role, std::string_view cdr, InputClock::time_point now, Out& out);
  // Silences, and what the window lets go without a new message.
  void Tick(InputClock::time_point now, Out& out);
  // Everything held, in order (the end of the input).
  void Flush(Out& out);
  // A publication of `offered_type` on the topic of `role` (never matched).
  void WrongType(InputRole role, const std::string& offered_type);

  std::vector<std::pair<InputRole, TopicStats>> stats(InputClock::time_point now) const;
  // "locaid-ros2 inputs": OK while every topic speaks and nothing new went
  // wrong since the last call; WARN for a silent sensor or new errors;
  // ERROR while a camera is silent (no frames, no poses). Values: per role
  // <key>.topic, .received, .used, .undecodable, .late, .bad, .unpaired,
  // .wrong_type, .silent, .last_error.
  output::DiagnosticStatus Health(InputClock::time_point now);
  // CPU seconds this thread spent decoding and rectifying images.
  double image_cpu_s() const { return image_cpu_s_; }
  uint64_t frames() const { return frames_; }

 private:
  struct Held {
    int64_t stamp_ns = 0;
    uint64_t order = 0;
    InputRole role = InputRole::kImu;  // typed items
    v1::PushRequest request;     // typed items, ready
    std::string left, right;     // frames: the image messages
    bool frame = false;
    // At equal stamps the order a replay fuses them in (pipeline::Localizer:
    // IMU, fix, speed, then the frame), whatever order DDS delivered them in.
    int rank() const {
      if (frame) return 3;
      return role == InputRole::kImu ? 0 : role == InputRole::kGps ? 1 : 2;
    }
    bool operator>(const Held& o) const {
      if (stamp_ns != o.stamp_ns) return stamp_ns > o.stamp_ns;
      if (rank() != o.rank()) return rank() > o.rank();
      return order > o.order;
    }
  };
  struct Image {
    int64_t stamp_ns = 0;
    std::string cdr;
  };

  void Problem(InputRole role, uint64_t TopicStats::*counter, const std::string& why);
  void AddImage(InputRole side, int64_t stamp_ns, std::string_view cdr);
  void Hold(int64_t stamp_ns, Held held);
  void Release(InputClock::time_point now, Out& out, bool all);
  void Send(Held held, Out& out);
  bool IsStream(InputRole role) const;
  TopicStats& S(InputRole role) { return stats_[static_cast<size_t>(role)]; }

  InputTopics topics_;
  InputRig rig_;
  AssemblerOptions options_;
  std::function<void(const std::string&)> log_;
  std::array<TopicStats, kInputRoleCount> stats_;
  std::array<std::optional<InputClock::time_point>, kInputRoleCount> last_arrival_;
  std::array<int64_t, kInputRoleCount> last_stamp_;
  std::array<int64_t, kInputRoleCount> newest_;
  std::array<uint64_t, kInputRoleCount> problems_logged_{};
  InputClock::time_point started_;
  static constexpr size_t kMaxWaitingImages = 16;  // per side, while the other side has none
  std::priority_queue<Held, std::vector<Held>, std::greater<>> held_;
  pipeline::StereoPairer<Image> pairer_;
  uint64_t order_ = 0;
  int64_t newest_ns_ = INT64_MIN, released_ns_ = INT64_MIN;
  uint64_t frames_ = 0;
  double image_cpu_s_ = 0;
  uint64_t errors_at_health_ = 0;
};

}  // namespace locaid::ros2
