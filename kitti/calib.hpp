// KITTI calibration files: raw-drive calib_cam_to_cam.txt, calib_velo_to_cam.txt,
// calib_imu_to_velo.txt (in the date folder), odometry calib.txt; readers,
// writers and the derived rectified stereo model and cam0<-imu extrinsic.
//
// Format: one "key: v1 v2 ..." per line. Errors are kitti::Error
// "FILE:LINE: key 'K_00': 8 numbers, expected 9" / "FILE: missing key 'P_rect_01'".
#pragma once

#include "core/stereo_camera.hpp"
#include "kitti/types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <filesystem>
#include <string>
#include <string_view>

namespace locaid::kitti {

// One camera of calib_cam_to_cam.txt (keys S_0x, K_0x, ... P_rect_0x).
struct CameraCalib {
  Eigen::Vector2d S = Eigen::Vector2d::Zero();       // unrectified image size (w, h) px
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();   // unrectified intrinsics
  Eigen::Matrix<double, 5, 1> D = Eigen::Matrix<double, 5, 1>::Zero();  // k1 k2 p1 p2 k3
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();   // rotation cam0 -> this cam (unrect.)
  Eigen::Vector3d T = Eigen::Vector3d::Zero();       // translation cam0 -> this cam, m
  Eigen::Vector2d S_rect = Eigen::Vector2d::Zero();  // rectified image size (w, h) px
  Eigen::Matrix3d R_rect = Eigen::Matrix3d::Identity();  // unrect. cam x -> rectified
  Eigen::Matrix<double, 3, 4> P_rect = Eigen::Matrix<double, 3, 4>::Zero();  // rect. projection
};

struct CamToCamCalib {
  std::string calib_time;  // free text, e.g. "09-Jan-2012 13:57:47"; optional on read
  double corner_dist = 0;  // optional on read
  std::array<CameraCalib, 4> cams;  // 00..03
};

// calib_velo_to_cam.txt (T_to_from = cam0<-velo) or calib_imu_to_velo.txt
// (velo<-imu): "R:" 9 numbers row-major, "T:" 3 numbers (m).
struct RigidCalib {
  std::string calib_time;  // optional on read
  Eigen::Isometry3d T_to_from = Eigen::Isometry3d::Identity();
};

// Odometry calib.txt: P0..P3 (rectified projections), Tr (cam0 <- velodyne).
struct OdometryCalib {
  std::array<Eigen::Matrix<double, 3, 4>, 4> P;
  Eigen::Isometry3d T_cam0_velo = Eigen::Isometry3d::Identity();
};

// The three raw calibration files of a date folder and what derives from them.
struct RawCalib {
  CamToCamCalib cam_to_cam;
  RigidCalib velo_to_cam;  // T_to_from = T_cam0_velo (unrectified cam0)
  RigidCalib imu_to_velo;  // T_to_from = T_velo_imu
  StereoCamera stereo;     // RectifiedStereo(cam_to_cam)
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();  // rectified cam0 <- imu
};

// Parsers of file contents; `where` (usually the path) prefixes errors.
CamToCamCalib ParseCamToCam(std::string_view text, const std::string& where);
RigidCalib ParseRigidCalib(std::string_view text, const std::string& where);
OdometryCalib ParseOdometryCalib(std::string_view text, const std::string& where);

// Readers (throw kitti::Error "PATH: cannot open" when unreadable).
CamToCamCalib ReadCamToCam(const std::filesystem::path& path);
RigidCalib ReadVeloToCam(const std::filesystem::path& path);  // T_to_from = T_cam0_velo
RigidCalib ReadImuToVelo(const std::filesystem::path& path);  // T_to_from = T_velo_imu
OdometryCalib ReadOdometryCalib(const std::filesystem::path& path);
// Reads calib_cam_to_cam.txt, calib_velo_to_cam.txt, calib_imu_to_velo.txt
// from `date_dir` and derives stereo and T_cam0_imu.
RawCalib ReadRawCalib(const std::filesystem::path& date_dir);

// Writers in the KITTI layout (17 significant digits: exact round trip).
// Throw kitti::Error when the file cannot be written.
void WriteCamToCam(const std::filesystem::path& path, const CamToCamCalib& calib);
void WriteVeloToCam(const std::filesystem::path& path, const RigidCalib& calib);
void WriteImuToVelo(const std::filesystem::path& path, const RigidCalib& calib);
void WriteOdometryCalib(const std::filesystem::path& path, const OdometryCalib& calib);

// Rectified stereo of cams 00/01: fx, fy, cx, cy from P_rect_00, baseline
// -P_rect_01(0,3) / P_rect_01(0,0), size S_rect_00.
StereoCamera RectifiedStereo(const CamToCamCalib& calib);
// Odometry: fx.. from P0, baseline -P1(0,3)/P1(0,0); size given by the caller.
StereoCamera OdometryStereo(const OdometryCalib& calib, int width, int height);

// KITTI devkit chain: rectified cam0 <- imu = T_rect0 * T_cam0_velo * T_velo_imu,
// T_rect0 = [R_rect_00 | 0]. The rotation of the result is projected onto SO(3)
// (nearest rotation; KITTI's 7-digit matrices are off by ~1e-7).
Eigen::Isometry3d ComputeT_cam0_imu(const CamToCamCalib& cam_to_cam,
                                    const Eigen::Isometry3d& T_cam0_velo,
                                    const Eigen::Isometry3d& T_velo_imu);

}  // namespace locaid::kitti
