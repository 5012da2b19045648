// A stereo dataset on disk, whatever its KITTI layout: raw *_sync, raw
// *_extract (rectified on load) or an odometry sequence. VO, replay and the
// server read frames through this interface only.
#pragma once

#include "core/pair_runner.hpp"
#include "core/stereo_camera.hpp"
#include "kitti/types.hpp"

#include <opencv2/core.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <Eigen/Geometry>

namespace locaid::kitti {

struct StereoImages {
  cv::Mat left, right;  // rectified, CV_8UC1, camera().width x camera().height
};

// What a reader found missing or odd; callers decide to skip or interpolate.
struct DatasetReport {
  std::vector<int> missing_left, missing_right;  // frame indices without that image
  int oxts_records = 0;                          // records present
  int oxts_expected = 0;                         // records the index range implies
  bool oxts_timestamps_estimated = false;        // no oxts/timestamps.txt
  // Why each unreadable OXTS record was left out (only with skip_bad_oxts);
  // each is also in `notes`.
  std::vector<std::string> oxts_skipped;
  std::vector<std::string> notes;                // human-readable, one per finding
};

class StereoDataset {
 public:
  virtual ~StereoDataset() = default;

  virtual std::string kind() const = 0;  // "raw_sync", "raw_extract", "odometry"
  virtual const StereoCamera& camera() const = 0;  // rectified model
  virtual size_t size() const = 0;                 // number of frame indices
  virtual int64_t time_ns(size_t i) const = 0;     // image_00 time of frame i
  // Seconds of frame i in the TUM convention (raw: since image_00 line 0;
  // odometry: times.txt).
  virtual double tum_time_s(size_t i) const = 0;
  virtual bool has_stereo(size_t i) const = 0;     // both images present
  // Loads and (for extract drives) rectifies frame i, the left and the right
  // image through `run` (at once, when it has a second thread). Throws
  // kitti::Error naming the file when an image is missing or cannot be
  // decoded (the left image's error first).
  virtual StereoImages Load(size_t i, const PairRunner& run = PairRunner::Sequential()) const = 0;
  // OXTS records sorted by time; empty for odometry sequences.
  virtual const std::vector<OxtsSample>& oxts() const = 0;
  // cam0 <- imu extrinsic (raw drives; identity-free odometry sequences use Tr).
  virtual Eigen::Isometry3d T_cam0_imu() const = 0;
  // Ground-truth pose of cam0 in the dataset's world frame at frame i, when known
  // (odometry poses/NN.txt; raw drives: OXTS interpolated to the image time).
  virtual std::optional<Eigen::Isometry3d> ground_truth(size_t i) const = 0;
  virtual const DatasetReport& report() const = 0;
};

// Detects the layout of `path` (a raw drive folder or an odometry sequence
// folder) and opens it. Throws kitti::Error with the offending file.
std::unique_ptr<StereoDataset> OpenDataset(const std::filesystem::path& path);

// `path` made absolute and lexically normal, without a trailing separator, so
// that parent_path() is the parent folder ("drive/" and "drive" both work).
std::filesystem::path NormalizeDir(const std::filesystem::path& path);

// Same, with options for raw drives (kitti/raw_drive.hpp; ignored for odometry).
struct RawDriveOptions;
std::unique_ptr<StereoDataset> OpenDataset(const std::filesystem::path& path,
                                           const RawDriveOptions& options);

}  // namespace locaid::kitti
