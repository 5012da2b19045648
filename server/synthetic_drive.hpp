// Synthetic drives for sessions: rendered by the kitti synth library into the
// server's work directory, then opened like any KITTI raw drive.
#pragma once

#include "core/stereo_camera.hpp"
#include "kitti/dataset.hpp"

#include <Eigen/Geometry>

#include <atomic>
#include <filesystem>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

namespace locaid::server {

class SyntheticError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The camera and IMU extrinsic a synthetic drive will have.
struct SyntheticRig {
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
};

// Checks a session's synthetic request before it is accepted: options_yaml
// (keys, types, ranges, NaN) and the number of frames the drive will have
// (frames, or what length_m needs at the slowest speed) against max_frames.
// Throws SyntheticError naming the field. Returns the drive's rig.
SyntheticRig ValidateSyntheticRequest(uint64_t seed, size_t frames, const std::string& options_yaml,
                                      size_t max_frames);

// Renders a drive into `dir` (or reuses a complete one there) and opens it.
// Throws SyntheticError when the generator fails, and SyntheticCancelled
// (leaving no partial folder) as soon as *cancel is set (checked after every
// rendered frame). Different folders render in parallel.
class SyntheticCancelled : public SyntheticError {
 public:
  SyntheticCancelled() : SyntheticError("synthetic drive: rendering cancelled") {}
};
std::unique_ptr<kitti::StereoDataset> MakeSyntheticDrive(const std::filesystem::path& dir, uint64_t seed,
                                                         size_t frames, const std::string& options_yaml,
                                                         const std::atomic<bool>* cancel = nullptr);

// Where a server renders its sessions' drives: <work_dir>/synthetic (work_dir
// empty: $TMPDIR/locaid-server-<uid>/synthetic). A session's drive is
// <root>/<key>, rendered when it starts and deleted when its pipeline ends.
std::filesystem::path SyntheticRoot(const std::string& work_dir);
// Deletes what a previous server process left under the root (its drives
// were deleted with their sessions unless it was killed). Returns the count.
size_t RemoveStaleSyntheticDrives(const std::string& work_dir);

// cam0 (rectified) <- imu of the KITTI 2011_09_26 rig, from its calibration
// files (R_rect_00 * T_cam0_velo * T_velo_imu); default for live sessions.
Eigen::Isometry3d KittiRigTcam0Imu();

}  // namespace locaid::server
