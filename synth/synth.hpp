// Synthetic KITTI raw *sync* drives rendered by locaid's own software renderer.
//
// GenerateDrive(config, out_dir) writes the date folder `out_dir`:
//   calib_cam_to_cam.txt, calib_velo_to_cam.txt, calib_imu_to_velo.txt
//   <date>_drive_<NNNN>_sync/
//     image_00/data/%010d.png, image_00/timestamps.txt   (left, 8-bit gray, rectified)
//     image_01/data/%010d.png, image_01/timestamps.txt   (right)
//     oxts/data/%010d.txt, oxts/timestamps.txt, oxts/dataformat.txt
//     ground_truth_cam0.txt  (KITTI 3x4 row-major T_world_cam0, world = cam0 at frame 0)
//     ground_truth_cam0.tum  (t tx ty tz qx qy qz qw; t = s since the first image)
// Cam0 is the *rectified* left camera: T_cam0_imu = R_rect_00 * T_cam0_velo * T_velo_imu,
// exactly as KITTI defines the odometry ground truth. OXTS records follow the
// RT3003 conventions (see oxts/dataformat.txt; accelerations are specific
// force, +g on z at rest). Same config (incl. seed) -> byte-identical files.
// Calib files, timestamps, OXTS records and KITTI / TUM poses are formatted
// by kitti/'s writers (one formatter per file type in the code base); only
// oxts/dataformat.txt, a fixed text, is synth's own.
#pragma once

#include "core/stereo_camera.hpp"
#include "kitti/calib.hpp"
#include "kitti/types.hpp"
#include "synth/motion.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

namespace locaid::synth {

struct SynthConfig {
  uint64_t seed = 1;
  int frames = 600;           // number of stereo frames (used when length_m <= 0)
  double length_m = 0;        // > 0: drive this distance instead (frames derived)
  int width = 1242, height = 375;  // image size; intrinsics scale with it
  double frame_rate_hz = 10;
  std::string date = "2024_05_17";  // date folder name / timestamp date (YYYY_MM_DD)
  int drive_number = 1;
  double origin_lat_deg = 49.0110, origin_lon_deg = 8.4165, origin_alt_m = 115.0;  // Karlsruhe
  double noise_sigma_dn = 1.2;       // sensor noise
  double oxts_time_offset_max_s = 0.004;  // |t_oxts - t_image| <= this (sync data are not exact)
  double frame_jitter_max_s = 0.0015;     // image timestamp jitter around 1/rate
  // Route shape: the planned speed stays within [speed_min, speed_max] (m/s;
  // the minimum wins over the curve limit), and curve radii are drawn
  // log-uniformly from [radius_min, radius_max] (m). The defaults are
  // RouteConfig's, a town and country-road drive (5-20 m/s, 35-220 m); e.g.
  // 20-30 m/s with 300-1500 m radii is a motorway.
  double speed_min_mps = RouteConfig{}.v_min_mps, speed_max_mps = RouteConfig{}.v_max_mps;
  double curve_radius_min_m = RouteConfig{}.min_radius_m, curve_radius_max_m = RouteConfig{}.max_radius_m;
  // Anisotropic texture filtering (Renderer::anisotropic): the road stays
  // sharp sideways into the distance. Off by default, so images rendered by
  // earlier versions keep their bytes.
  bool anisotropic_filtering = false;
  int png_compression = -1;          // -1: fast (SUB filter, zlib level 1, RLE); 0..9: zlib level, adaptive filters
  // Route mode (route_poses set): drive a real route, a KITTI odometry
  // ground-truth poses file (poses/NN.txt), from pose route_start_frame on
  // and on the clock of route_times (sequences/NN/times.txt; empty: 10 Hz).
  // Image 0 is at that pose's time; frames / length_m say how much at most is
  // rendered (frames 0: up to the last pose), the poses' end ends it sooner.
  // The ground truth is the smooth trajectory fitted to the poses
  // (synth/route_file.hpp); the speed and curve ranges do not apply.
  std::filesystem::path route_poses, route_times;
  int route_start_frame = 0;
};

struct SynthSummary {
  std::filesystem::path date_dir, drive_dir;
  int frames = 0;
  double duration_s = 0, distance_m = 0;
  double min_speed_mps = 0, max_speed_mps = 0;
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();  // rectified cam0 <- imu
  size_t static_polygons = 0;
  // Route mode: the poses the drive spans (first = route_start_frame, last:
  // the last one at or before the last image) and whether the poses ended
  // before the frames or length asked for.
  int route_first_pose = -1, route_last_pose = -1;
  bool route_cut = false;
};

// Throws kitti::Error for bad configs ("synth: frames must be >= 2 (got 1)",
// checked before anything is written), bad route files ("synth: route
// poses: P:17: 11 numbers, expected 12 ...", read before anything is
// written; synth/route_file.hpp) and unwritable folders ("synth: cannot
// create folder '/x': Permission denied").
// Throws kitti::Error naming the field and its range when `config` cannot be
// rendered (GenerateDrive checks it first; callers can check before).
void ValidateSynthConfig(const SynthConfig& config);
// `progress(frame, total)` runs after each rendered frame and, with frame 0,
// after each set-up step (route, textures, world; about half a second of
// CPU together), so a callback that throws stops the render within one step
// or frame; the exception propagates and what was written so far stays.
SynthSummary GenerateDrive(const SynthConfig& config, const std::filesystem::path& out_dir,
                           const std::function<void(int frame, int total)>& progress = {});

// Calibration of the synthetic rig as written to the files (values with the
// 7 significant digits of the real files): the three calibration files, the
// stereo model and rectified cam0 <- imu derived from them.
struct SynthCalib {
  StereoCamera stereo;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  kitti::CamToCamCalib cam_to_cam;
  kitti::RigidCalib velo_to_cam, imu_to_velo;
};
SynthCalib MakeSynthCalib(int width, int height);

}  // namespace locaid::synth
