// Inputs of a session: stereo frames with the OXTS samples that arrived since
// the previous frame. DatasetFrameSource plays a KITTI dataset (real or
// synthetic) from disk; LiveFrameSource is fed by a PushSensorData stream.
// Both turn bad input into counted, skipped items instead of errors.
#pragma once

#include "core/stereo_camera.hpp"
#include "fusion/types.hpp"
#include "kitti/dataset.hpp"
#include "server/session_pipeline.hpp"
#include "kitti/types.hpp"

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
#include <Eigen/Geometry>

namespace locaid::server {

// A GPS fix of a live session, with the steady-clock time it reached the
// server (for the latency from arrival to use).
struct ArrivedFix {
  fusion::GpsFix fix;
  int64_t arrival_steady_ns = 0;  // 0: pushed (no arrival-to-use latency recorded)
};

struct SourceItem {
  // kSensors: typed IMU / GPS data between frames, to fuse now (live input).
  enum class Kind { kFrame, kSkipped, kCorrupt, kIdle, kEnd, kSensors };
  Kind kind = Kind::kIdle;
  int64_t index = -1;
  int64_t t_ns = 0;
  cv::Mat left, right;                         // kFrame: CV_8UC1, camera size
  std::vector<kitti::OxtsSample> oxts;         // t_prev_frame < t <= t_ns
  std::vector<fusion::ImuSample> imu;          // typed IMU, time order, t <= t_ns for frames
  std::vector<ArrivedFix> gps;                 // typed / gpsd fixes, time order, t <= sensor time
  std::optional<bool> receiver_has_fix;        // the receiver's newest no-fix / fix state
  std::optional<kitti::OxtsRecord> truth;      // dataset sources: OXTS at the frame time (interpolated)
  int oxts_bad_lines = 0;
  std::string error;                           // why skipped/corrupt, last bad OXTS line
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual SourceItem Next() = 0;
  virtual void Cancel() {}
  virtual void Wake() {}
  virtual int64_t total_frames() const { return 0; }
  virtual double duration_s() const { return 0; }  // sensor time span, 0 = unknown
  virtual const StereoCamera& camera() const = 0;
  virtual Eigen::Isometry3d T_cam0_imu() const = 0;
  // Counters of typed live input (any thread).
  virtual LiveInputStats input_stats() const { return {}; }
};

// Frames [first, last] of a dataset (last < 0: to the end). A frame whose
// time is not after the previous delivered frame's is kCorrupt (as for
// pushed frames).
class DatasetFrameSource : public FrameSource {
 public:
  DatasetFrameSource(std::unique_ptr<kitti::StereoDataset> dataset, int64_t first, int64_t last);
  SourceItem Next() override;
  int64_t total_frames() const override { return end_ - first_; }
  double duration_s() const override;
  const StereoCamera& camera() const override { return dataset_->camera(); }
  Eigen::Isometry3d T_cam0_imu() const override { return dataset_->T_cam0_imu(); }

 private:
  std::unique_ptr<kitti::StereoDataset> dataset_;
  int64_t first_, end_, next_;
  size_t next_oxts_ = 0;
  // OXTS records the reader skipped as unreadable (report() notes, when the
  // dataset was opened with skip_bad_oxts); reported with the first item.
  int skipped_oxts_ = 0;
  std::string skipped_oxts_error_;
  int64_t last_frame_ns_ = INT64_MIN;  // time of the last frame delivered
};

// One item pushed by a client (values already validated, see
// session_requests.cpp; ordering is checked here).
struct LiveItem {
  enum class Kind { kFrame, kOxts, kImu, kGps };
  Kind kind = Kind::kFrame;
  int64_t t_ns = 0;
  bool png = true;          // frames: PNG/encoded bytes, else raw GRAY8
  std::string left, right;  // frames
  std::string oxts_line;    // OXTS: the 30 fields
  fusion::ImuSample imu;    // kImu
  fusion::GpsFix gps;       // kGps (gps.t_ns == t_ns)
  bool gps_no_fix = false;  // kGps: a no-fix report (position meaningless)
  int64_t arrival_steady_ns = 0;  // kGps read from gpsd: when it arrived; 0 for pushed items
};

struct LiveCameraSetup {
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  // A fix older than the newest frame by more than this is dropped (counted).
  double max_gps_delay_s = 0.5;
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
  // A fix from a receiver the server reads itself (gpsd): never blocks; at
  // most kMaxAsyncFixes wait, the oldest is dropped (counted late) beyond.
  static constexpr size_t kMaxAsyncFixes = 64;
  void PushAsyncFix(LiveItem fix);
  void CloseInput();  // half-close: Next() returns kEnd once drained

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
  std::vector<kitti::OxtsSample> oxts_;
  std::optional<int64_t> last_oxts_t_ns_;  // newest record accepted (ordering check)
  int bad_lines_ = 0;
  std::string last_error_;
  int64_t frames_ = 0, oxts_count_ = 0;
  int64_t last_frame_ns_ = INT64_MIN;
  // Typed input (consumer state): samples and fixes wait here until the
  // sensor time (newest frame / IMU sample) reaches them.
  std::deque<LiveItem> async_fixes_;  // mu_: from PushAsyncFix
  std::vector<fusion::ImuSample> imu_;
  std::deque<ArrivedFix> held_gps_;   // time order, at most kMaxAsyncFixes
  std::optional<bool> receiver_has_fix_;
  std::optional<int64_t> last_imu_ns_, last_gps_ns_;
  int64_t sensor_time_ns_ = INT64_MIN;  // newest frame or IMU time seen
  mutable std::mutex stats_mu_;
  LiveInputStats stats_;
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

}  // namespace locaid::server
