// A live session's input: frames, OXTS records, IMU samples and GPS fixes
// pushed by a client (values already validated by the caller; ordering is
// checked here), and fixes from a GPS receiver read on its own thread.
#pragma once

#include "core/stereo_camera.hpp"
#include "fusion/types.hpp"
#include "pipeline/frame_source.hpp"

#include <opencv2/core.hpp>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace locaid::pipeline {

// One item pushed by a client (values already validated, see the server's
// push_requests.cpp; ordering is checked here).
struct LiveItem {
  enum class Kind { kFrame, kOxts, kImu, kGps, kSpeed };
  Kind kind = Kind::kFrame;
  int64_t t_ns = 0;
  bool png = true;          // frames: PNG/encoded bytes, else raw GRAY8
  std::string left, right;  // frames
  // Frames from the server's own cameras: already rectified CV_8UC1 of the
  // camera size (the bytes above stay empty); both empty with no_images.
  cv::Mat left_image, right_image;
  bool no_images = false;   // a tick while the cameras are down: a pose without VO
  std::string oxts_line;    // OXTS: the 30 fields
  fusion::ImuSample imu;    // kImu
  fusion::GpsFix gps;       // kGps (gps.t_ns == t_ns)
  fusion::SpeedSample speed;  // kSpeed (speed.t_ns == t_ns)
  bool gps_no_fix = false;  // kGps: a no-fix report (position meaningless)
  int64_t arrival_steady_ns = 0;  // kGps read from gpsd: when it arrived; 0 for pushed items
};

struct LiveCameraSetup {
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  // A fix older than the newest frame by more than this is dropped (counted).
  double max_gps_delay_s = 0.5;
  // The filter is IMU-driven: 50 frames without an IMU sample are reported
  // (input_stats().last_error), since the session should have said no_imu.
  bool expects_imu = true;
};

// Something that feeds a live source from a thread of its own (the server's
// gpsd receiver). Owned by the source it feeds, so it stops before the
// source's state goes.
class InputFeeder {
 public:
  virtual ~InputFeeder() = default;  // stops feeding (joins its thread)
  // Its own figures (connection state), merged into input_stats(). Any thread.
  virtual void AddStats(LiveInputStats& stats) const = 0;
};

// Bounded queue between a PushSensorData stream and the session thread, with
// back-pressure: Push() returns false when full and calls `resume` once there
// is room again (the stream then reads its next message).
class LiveFrameSource : public FrameSource {
 public:
  static constexpr size_t kDefaultCapacity = 8;
  LiveFrameSource(LiveCameraSetup setup, size_t capacity = kDefaultCapacity);

  // Producer side (any thread).
  bool Push(LiveItem item, std::function<void()> resume);
  // A frame from a producer that must not wait (the server's cameras): false
  // when the queue is full, and the item is not taken (the caller drops it).
  bool TryPush(LiveItem item);
  // A fix from a receiver the server reads itself (gpsd): never blocks; at
  // most kMaxAsyncFixes wait, the oldest is dropped (counted late) beyond.
  static constexpr size_t kMaxAsyncFixes = 64;
  static constexpr int64_t kFramesBeforeNoImuNotice = 50;  // LiveCameraSetup::expects_imu
  void PushAsyncFix(LiveItem fix);
  void CloseInput();  // half-close: Next() returns kEnd once drained
  // Takes ownership of a feeder (the gpsd receiver: PushAsyncFix; the
  // cameras: TryPush). Before the first Next().
  void AttachFeeder(std::unique_ptr<InputFeeder> feeder) { feeders_.push_back(std::move(feeder)); }

  // Consumer side (session thread). Waits up to ~50 ms for input.
  SourceItem Next() override;
  void Cancel() override;
  void Wake() override;
  const StereoCamera& camera() const override { return setup_.camera; }
  Eigen::Isometry3d T_cam0_imu() const override { return setup_.T_cam0_imu; }
  LiveInputStats input_stats() const override;

 private:
  // Consumer side: typed items go to the pending lists (false: refused).
  void TakeImu(const LiveItem& item);
  void TakeGps(LiveItem item);
  void TakeSpeed(const LiveItem& item);
  void TakeOxts(const LiveItem& item);  // a bad record is counted, its error kept for the next item
  // The next pushed item, waiting up to 50 ms for one; nullopt when Next()
  // returns `out` instead (the end, idle, woken, or samples due between
  // frames).
  std::optional<LiveItem> Dequeue(SourceItem& out);
  // A frame: its samples, its images decoded or checked.
  SourceItem Frame(LiveItem item);
  // Moves the pending typed data up to t_ns into `out`.
  void Release(int64_t t_ns, SourceItem& out);
  bool HasReleasable() const;

  LiveCameraSetup setup_;
  const size_t capacity_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<LiveItem> queue_;
  std::optional<LiveItem> pending_;
  std::function<void()> resume_;
  bool closed_ = false, cancelled_ = false, woken_ = false;
  // Consumer state.
  SampleBatch truth_;  // pushed OXTS as truth samples, up to the next frame
  std::optional<int64_t> last_oxts_t_ns_;  // newest record accepted (ordering check)
  int bad_lines_ = 0;
  std::string last_error_;
  int64_t frames_ = 0, oxts_count_ = 0;
  int64_t last_frame_ns_ = INT64_MIN;
  // Typed input (consumer state): samples and fixes wait here until the
  // sensor time (newest frame / IMU sample) reaches them.
  std::deque<LiveItem> async_fixes_;  // mu_: from PushAsyncFix
  std::vector<fusion::ImuSample> imu_;
  std::vector<fusion::SpeedSample> speed_;
  std::deque<ArrivedFix> held_gps_;   // time order, at most kMaxAsyncFixes
  std::optional<bool> receiver_has_fix_;
  std::optional<int64_t> last_imu_ns_, last_gps_ns_, last_speed_ns_;
  int64_t sensor_time_ns_ = INT64_MIN;  // newest frame or IMU time seen
  mutable std::mutex stats_mu_;
  LiveInputStats stats_;
  std::vector<std::unique_ptr<InputFeeder>> feeders_;  // last member: destroyed (stopped) first
};

// Width and height a PNG declares in its IHDR chunk (bytes 16..23, big
// endian), read without decoding; nullopt when `bytes` has no PNG signature
// followed by a 13-byte IHDR chunk.
struct PngSize {
  uint32_t width = 0, height = 0;
};
std::optional<PngSize> ReadPngSize(const std::string& bytes);
// "" when the PNG header declares the camera size (or is not a PNG header:
// decoding reports that), else "left image: PNG declares WxH px, session
// camera is WxH px".
std::string PngSizeMismatch(const std::string& bytes, const StereoCamera& camera, const char* which);

// Decodes one pushed image into CV_8UC1 of the camera size; throws
// std::invalid_argument "left image: ..." on failure. A PNG's declared size
// is checked before decoding, so a small file declaring a huge image is
// never decoded.
cv::Mat DecodeLiveImage(const std::string& bytes, bool png, const StereoCamera& camera,
                        const char* which);

}  // namespace locaid::pipeline
