// KITTI raw drive (<date>/<date>_drive_NNNN_{sync,extract}/) as a StereoDataset.
//
// Layout read: image_00/, image_01/ (timestamps.txt, data/%010d.png), oxts/
// (data/%010d.txt, optional timestamps.txt); calibration files in the parent
// date folder. *_extract images are raw and rectified on Load (maps built once);
// *_sync images are already rectified.
#pragma once

#include "core/stereo_camera.hpp"
#include "kitti/calib.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts_pose.hpp"

#include <opencv2/core.hpp>

#include <filesystem>

namespace locaid::kitti {

enum class RawLayout { kAuto, kSync, kExtract };

struct RawDriveOptions {
  // kAuto: "_sync"/"_extract" suffix of the folder name, else the size of the
  // first left image (S_00 -> extract, S_rect_00 -> sync).
  RawLayout layout = RawLayout::kAuto;
  // false: a bad OXTS file throws kitti::Error (file and reason).
  // true: it is skipped and named in report().notes.
  bool skip_bad_oxts = false;
  // Without oxts/timestamps.txt, extract drives place record i at
  // t(image_00 frame 0) + offset + i * period (fitted on 2011_09_26, see
  // data/kitti/README.md); sync drives use the image_00 time of frame i.
  int64_t extract_oxts_offset_ns = 100'000'000;
  int64_t extract_oxts_period_ns = 10'000'000;
  // Ground truth is std::nullopt when the OXTS records around a frame are
  // further apart than this.
  double max_gt_gap_s = 0.5;
};

class RawDrive final : public StereoDataset {
 public:
  // Throws kitti::Error naming the offending file (missing calibration,
  // image_00/timestamps.txt, bad OXTS unless skip_bad_oxts, ...).
  explicit RawDrive(const std::filesystem::path& drive_dir, const RawDriveOptions& options = {});

  std::string kind() const override { return extract_ ? "raw_extract" : "raw_sync"; }
  const StereoCamera& camera() const override { return calib_.stereo; }
  size_t size() const override { return t_ns_.size(); }
  int64_t time_ns(size_t i) const override;
  double tum_time_s(size_t i) const override;
  bool has_stereo(size_t i) const override;
  StereoImages Load(size_t i, const PairRunner& run = PairRunner::Sequential()) const override;
  const std::vector<OxtsSample>& oxts() const override { return oxts_; }
  // Rectified cam0 <- imu (R_rect_00 * T_cam0_velo * T_velo_imu).
  Eigen::Isometry3d T_cam0_imu() const override { return calib_.T_cam0_imu; }
  // T_world_cam0; world = cam0 at gt().anchor_frame (frame 0 when the OXTS
  // span covers it). std::nullopt outside the OXTS span or over a > max_gt_gap_s gap.
  std::optional<Eigen::Isometry3d> ground_truth(size_t i) const override;
  const DatasetReport& report() const override { return report_; }

  bool is_extract() const { return extract_; }
  const RawCalib& calib() const { return calib_; }
  // ENU origin, T_enu_world, T_enu_imu per OXTS sample.
  const OxtsGroundTruth& gt() const { return gt_; }
  std::filesystem::path left_path(size_t i) const;
  std::filesystem::path right_path(size_t i) const;
  // The rectified image of camera `cam` (0 left, 1 right) from its raw image
  // (extract drives, with the maps built once); a sync drive's image as it is.
  cv::Mat Rectify(int cam, const cv::Mat& raw) const;

 private:
  void ReadOxts(const RawDriveOptions& options);
  cv::Mat LoadOne(const std::filesystem::path& path, int cam, bool missing, size_t i,
                  const char* side) const;

  std::filesystem::path dir_;
  RawCalib calib_;
  bool extract_ = false;
  std::vector<int64_t> t_ns_;
  std::vector<char> has_left_, has_right_;
  cv::Mat map1_[2], map2_[2];  // extract only: rectification maps of cam 0/1
  std::vector<OxtsSample> oxts_;
  OxtsGroundTruth gt_;
  DatasetReport report_;
};

}  // namespace locaid::kitti
