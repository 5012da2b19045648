// What the frame loop (frame_loop.hpp) reads: stereo frames with the samples
// that arrived since the previous frame. DatasetFrameSource plays a KITTI
// dataset (real or synthetic) from disk, its OXTS as truth samples
// (oxts_adapter.hpp); LiveFrameSource (live_frame_source.hpp) is fed by a
// client pushing frames and samples.
// Both turn bad input into counted, skipped items instead of errors.
#pragma once

#include "core/pair_runner.hpp"

#include "core/stereo_camera.hpp"
#include "fusion/types.hpp"
#include "kitti/dataset.hpp"
#include "kitti/types.hpp"
#include "pipeline/samples.hpp"

#include <opencv2/core.hpp>

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace locaid::pipeline {

// Counters of a live source's typed input and GPS receiver (all zero for
// file sources).
struct LiveInputStats {
  uint64_t imu_samples = 0, gps_fixes_in = 0, gps_fixes_late = 0, gps_no_fix = 0, speed_samples = 0;
  uint64_t sensor_rejected = 0;  // typed items refused (out of order); last_error says why
  std::string last_error;
  bool has_gpsd = false, gpsd_connected = false;
  uint64_t gpsd_connects = 0, gpsd_losses = 0;
  std::string gpsd_error;
  double fix_latency_median_ms = 0, fix_latency_max_ms = 0;
  // The server's own cameras (LiveSource.cameras).
  bool has_camera = false, camera_running = false;
  uint64_t camera_pairs = 0, camera_unpaired = 0, camera_dropped_late = 0, camera_restarts = 0;
  std::string camera_error;
};

struct SourceItem {
  // kSamples: samples (IMU / GPS / speed) between frames, to fuse now (live input).
  enum class Kind { kFrame, kSkipped, kCorrupt, kIdle, kEnd, kSamples };
  Kind kind = Kind::kIdle;
  int64_t index = -1;
  int64_t t_ns = 0;
  cv::Mat left, right;                         // kFrame: CV_8UC1, camera size
  bool no_images = false;                      // kFrame: a tick while the live cameras are down (no images)
  // Samples since the previous item (t <= t_ns for frames).
  SampleBatch samples;
  std::optional<fusion::TruthSample> truth;  // recorded drives: the truth at the frame time
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
  // Who decodes a frame's two images (core/pair_runner.hpp); the stepping
  // thread alone by default. Set before the first Next(); not owned, must
  // outlive the source's use.
  void set_pair_runner(const PairRunner* runner) { runner_ = runner ? runner : &PairRunner::Sequential(); }

 protected:
  const PairRunner& pair_runner() const { return *runner_; }

 private:
  const PairRunner* runner_ = &PairRunner::Sequential();
};

// Frames [first, last] of a dataset (last < 0: to the end), each with the
// OXTS samples after the previous frame up to its time as truth samples
// (samples before the first frame are not fed). A frame whose time is not after the previous
// delivered frame's is kCorrupt (as for pushed frames); a frame without both
// images is kSkipped and its OXTS samples go with the next frame.
class DatasetFrameSource : public FrameSource {
 public:
  // load_images false: frames come without pixels (a caller that has the VO
  // results already, e.g. locaid-replay --vo-cache).
  DatasetFrameSource(std::unique_ptr<kitti::StereoDataset> dataset, int64_t first, int64_t last,
                     bool load_images = true);
  SourceItem Next() override;
  int64_t total_frames() const override { return end_ - first_; }
  double duration_s() const override;
  const StereoCamera& camera() const override { return dataset_->camera(); }
  Eigen::Isometry3d T_cam0_imu() const override { return dataset_->T_cam0_imu(); }
  const kitti::StereoDataset& dataset() const { return *dataset_; }

 private:
  std::unique_ptr<kitti::StereoDataset> dataset_;
  int64_t first_, end_, next_;
  bool load_images_;
  size_t next_oxts_ = 0;
  // OXTS records the reader skipped as unreadable (report() notes, when the
  // dataset was opened with skip_bad_oxts); reported with the first item.
  int skipped_oxts_ = 0;
  std::string skipped_oxts_error_;
  int64_t last_frame_ns_ = INT64_MIN;  // time of the last frame delivered
};

}  // namespace locaid::pipeline
