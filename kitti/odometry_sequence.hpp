// KITTI odometry sequence (sequences/NN/: calib.txt, times.txt, image_0/,
// image_1/ with %06d.png) as a StereoDataset; ground truth from
// sequences/NN/../../poses/NN.txt when that file exists.
#pragma once

#include "core/stereo_camera.hpp"
#include "kitti/calib.hpp"
#include "kitti/dataset.hpp"

#include <filesystem>

namespace locaid::kitti {

class OdometrySequence final : public StereoDataset {
 public:
  // Throws kitti::Error naming the file (calib.txt, times.txt, poses/NN.txt).
  // Missing image folders are not an error: they are reported (every frame in
  // missing_left/right, a note) and Load() throws naming the file.
  explicit OdometrySequence(const std::filesystem::path& sequence_dir);

  std::string kind() const override { return "odometry"; }
  // Rectified model from P0/P1; width/height from the first left image, 0 when
  // the sequence has no images.
  const StereoCamera& camera() const override { return camera_; }
  size_t size() const override { return times_s_.size(); }
  int64_t time_ns(size_t i) const override;     // llround(times.txt * 1e9)
  double tum_time_s(size_t i) const override { return times_s_.at(i); }
  bool has_stereo(size_t i) const override;
  StereoImages Load(size_t i, const PairRunner& run = PairRunner::Sequential()) const override;
  const std::vector<OxtsSample>& oxts() const override { return oxts_; }  // always empty
  // KITTI odometry publishes no IMU extrinsic. This returns Tr = T_cam0_velo
  // from calib.txt (NOT cam0<-imu): the only rig transform the format carries.
  Eigen::Isometry3d T_cam0_imu() const override { return calib_.T_cam0_velo; }
  // poses/NN.txt line i (world = cam0 at frame 0), std::nullopt without it.
  std::optional<Eigen::Isometry3d> ground_truth(size_t i) const override;
  const DatasetReport& report() const override { return report_; }

  const OdometryCalib& calib() const { return calib_; }
  bool has_ground_truth() const { return !poses_.empty(); }
  std::filesystem::path left_path(size_t i) const;
  std::filesystem::path right_path(size_t i) const;

 private:
  std::filesystem::path dir_;
  OdometryCalib calib_;
  StereoCamera camera_;
  std::vector<double> times_s_;
  std::vector<char> has_left_, has_right_;
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<OxtsSample> oxts_;
  DatasetReport report_;
};

}  // namespace locaid::kitti
