// Inputs of a session: stereo frames with the OXTS samples that arrived since
// the previous frame. DatasetFrameSource plays a KITTI dataset (real or
// synthetic) from disk; LiveFrameSource is fed by a PushSensorData stream.
// Both turn bad input into counted, skipped items instead of errors.
#pragma once

#include "kitti/dataset.hpp"
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

namespace locaid::server {

struct SourceItem {
  enum class Kind { kFrame, kSkipped, kCorrupt, kIdle, kEnd };
  Kind kind = Kind::kIdle;
  int64_t index = -1;
  int64_t t_ns = 0;
  cv::Mat left, right;                         // kFrame: CV_8UC1, camera size
  std::vector<kitti::OxtsSample> oxts;         // t_prev_frame < t <= t_ns
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
  virtual const kitti::StereoCamera& camera() const = 0;
  virtual Eigen::Isometry3d T_cam0_imu() const = 0;
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
  const kitti::StereoCamera& camera() const override { return dataset_->camera(); }
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

// One item pushed by a client.
struct LiveItem {
  enum class Kind { kFrame, kOxts };
  Kind kind = Kind::kFrame;
  int64_t t_ns = 0;
  bool png = true;          // frames: PNG/encoded bytes, else raw GRAY8
  std::string left, right;  // frames
  std::string oxts_line;    // OXTS: the 30 fields
};

struct LiveCameraSetup {
  kitti::StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
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
  void CloseInput();  // half-close: Next() returns kEnd once drained

  // Consumer side (session thread). Waits up to ~50 ms for input.
  SourceItem Next() override;
  void Cancel() override;
  void Wake() override;
  const kitti::StereoCamera& camera() const override { return setup_.camera; }
  Eigen::Isometry3d T_cam0_imu() const override { return setup_.T_cam0_imu; }

 private:
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
std::string PngSizeMismatch(const std::string& bytes, const kitti::StereoCamera& camera, const char* which);

// Decodes one pushed image into CV_8UC1 of the camera size; throws
// std::invalid_argument "left image: ..." on failure. A PNG's declared size
// is checked before decoding, so a small file declaring a huge image is
// never decoded.
cv::Mat DecodeLiveImage(const std::string& bytes, bool png, const kitti::StereoCamera& camera,
                        const char* which);

}  // namespace locaid::server
