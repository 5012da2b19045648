#include "core/stereo_camera.hpp"
#include "error_of.hpp"
#include "kitti/calib.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;

constexpr double kExact = 0.0;  // writers print 17 significant digits

const std::string kVeloToCam =
    "calib_time: 15-Mar-2012 11:37:16\n"
    "R: 7.533745e-03 -9.999714e-01 -6.166020e-04 1.480249e-02 7.280733e-04 -9.998902e-01 "
    "9.998621e-01 7.523790e-03 1.480755e-02\n"
    "T: -4.069766e-03 -7.631618e-02 -2.717806e-01\n"
    "delta_f: 0.000000e+00 0.000000e+00\n"
    "delta_c: 0.000000e+00 0.000000e+00\n";

std::string ErrorOf(const std::function<void()>& f) { return locaid::test_support::ErrorOf<Error>(f); }

// A plausible cam_to_cam with distinct values per camera.
CamToCamCalib MakeCamToCam() {
  CamToCamCalib c;
  c.calib_time = "09-Jan-2012 13:57:47";
  c.corner_dist = 0.0995;
  for (int i = 0; i < 4; ++i) {
    CameraCalib& cam = c.cams[i];
    cam.S << 1392, 512;
    cam.K << 984.2439 + i, 0, 690, 0, 980.8141, 233.1966, 0, 0, 1;
    cam.D << -0.3728755, 0.2037299, 0.002219027, 0.001383707, -0.07233722 / (i + 1);
    cam.R = Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    cam.T << -0.537 * i, 0.0048, -0.0125;
    cam.S_rect << 1242, 375;
    cam.R_rect = Eigen::AngleAxisd(0.007 * (i + 1), Eigen::Vector3d(3, -1, 2).normalized())
                     .toRotationMatrix();
    cam.P_rect << 721.5377, 0, 609.5593, -387.5744 * i, 0, 721.5377, 172.854, 0, 0, 0, 1, 0;
  }
  return c;
}

TEST(IoCalib, ParsesVeloToCam) {
  const RigidCalib c = ParseRigidCalib(kVeloToCam, "v.txt");
  EXPECT_EQ(c.calib_time, "15-Mar-2012 11:37:16");
  EXPECT_DOUBLE_EQ(c.T_to_from.linear()(0, 1), -9.999714e-01);  // row-major
  EXPECT_DOUBLE_EQ(c.T_to_from.linear()(1, 0), 1.480249e-02);
  EXPECT_DOUBLE_EQ(c.T_to_from.translation().z(), -2.717806e-01);
}

TEST(IoCalib, RigidErrorsNameFileKeyAndReason) {
  std::string s = kVeloToCam;
  s.replace(s.find("T: -4.069766e-03 "), 17, "T: ");
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }),
            "v.txt:3: key 'T': 2 numbers, expected 3");
  s = kVeloToCam;
  s.replace(s.find("-7.631618e-02"), 13, "abc");
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }),
            "v.txt:3: key 'T': value 2 is not a number: 'abc'");
  s = kVeloToCam;
  s.replace(s.find("-7.631618e-02"), 13, "nan");
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }),
            "v.txt:3: key 'T': value 2 is NaN: 'nan'");
  s = kVeloToCam;
  s.replace(s.find("-7.631618e-02"), 13, "inf");
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }),
            "v.txt:3: key 'T': value 2 is infinite: 'inf'");
  s = kVeloToCam;
  s.erase(s.find("T:"), s.find("delta_f") - s.find("T:"));
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }), "v.txt: missing key 'T'");
  s = kVeloToCam;
  s.replace(s.find("7.533745e-03"), 12, "5.000000e-01");  // not orthonormal
  EXPECT_NE(ErrorOf([&] { ParseRigidCalib(s, "v.txt"); }).find("v.txt:2: key 'R': not a rotation"),
            std::string::npos);
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(kVeloToCam + "garbage line\n", "v.txt"); }),
            "v.txt:6: expected 'key: values', got 'garbage line'");
  EXPECT_EQ(ErrorOf([&] { ParseRigidCalib(kVeloToCam + "T: 1 2 3\n", "v.txt"); }),
            "v.txt:6: key 'T' repeated (first on line 3)");
}

TEST(IoCalib, CamToCamRoundTripAndErrors) {
  const test_support::ScopedTempDir dir("io_calib");
  const CamToCamCalib c = MakeCamToCam();
  WriteCamToCam(dir / "calib_cam_to_cam.txt", c);
  const CamToCamCalib back = ReadCamToCam(dir / "calib_cam_to_cam.txt");
  EXPECT_EQ(back.calib_time, c.calib_time);
  EXPECT_EQ(back.corner_dist, c.corner_dist);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ((back.cams[i].K - c.cams[i].K).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ((back.cams[i].D - c.cams[i].D).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ((back.cams[i].R - c.cams[i].R).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ((back.cams[i].T - c.cams[i].T).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ((back.cams[i].R_rect - c.cams[i].R_rect).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ((back.cams[i].P_rect - c.cams[i].P_rect).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ(back.cams[i].S, c.cams[i].S);
    EXPECT_EQ(back.cams[i].S_rect, c.cams[i].S_rect);
  }
  // Drop P_rect_02 from the written file: missing key named with the file.
  std::ifstream in(dir / "calib_cam_to_cam.txt");
  std::string text, line;
  while (std::getline(in, line))
    if (line.rfind("P_rect_02:", 0) != 0) text += line + "\n";
  EXPECT_EQ(ErrorOf([&] { ParseCamToCam(text, "c2c.txt"); }), "c2c.txt: missing key 'P_rect_02'");
  // Wrong count: D_00 with 4 values.
  std::string t2 = "D_00: 1 2 3 4\n";
  EXPECT_EQ(ErrorOf([&] { ParseCamToCam("S_00: 1392 512\nK_00: 1 0 0 0 1 0 0 0 1\n" + t2, "c"); }),
            "c:3: key 'D_00': 4 numbers, expected 5");
  EXPECT_NE(ErrorOf([&] { ReadCamToCam(dir / "absent.txt"); }).find("absent.txt: cannot open"),
            std::string::npos);
}

TEST(IoCalib, RealCamToCamValues) {
  const fs::path p = fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/calib_cam_to_cam.txt";
  if (!fs::exists(p)) GTEST_SKIP() << "real calibration absent: " << p;
  const CamToCamCalib c = ReadCamToCam(p);
  EXPECT_DOUBLE_EQ(c.cams[0].K(0, 0), 9.842439e+02);
  EXPECT_DOUBLE_EQ(c.cams[1].D(4), -5.314062e-02);
  EXPECT_DOUBLE_EQ(c.cams[3].P_rect(2, 3), 2.729905e-03);
  EXPECT_EQ(c.cams[2].S_rect, Eigen::Vector2d(1242, 375));
  const StereoCamera s = RectifiedStereo(c);
  EXPECT_DOUBLE_EQ(s.fx, 7.215377e+02);
  EXPECT_DOUBLE_EQ(s.cx, 6.095593e+02);
  EXPECT_DOUBLE_EQ(s.baseline_m, 3.875744e+02 / 7.215377e+02);
  EXPECT_EQ(s.width, 1242);
  EXPECT_EQ(s.height, 375);
}

TEST(IoCalib, RigidWritersRoundTrip) {
  const test_support::ScopedTempDir dir("io_calib");
  RigidCalib v;
  v.calib_time = "t";
  v.T_to_from.linear() = Eigen::AngleAxisd(1.3, Eigen::Vector3d(0.2, -0.5, 1).normalized())
                             .toRotationMatrix();
  v.T_to_from.translation() << -0.004069766, -0.07631618, -0.2717806;
  WriteVeloToCam(dir / "calib_velo_to_cam.txt", v);
  WriteImuToVelo(dir / "calib_imu_to_velo.txt", v);
  for (const RigidCalib& back :
       {ReadVeloToCam(dir / "calib_velo_to_cam.txt"), ReadImuToVelo(dir / "calib_imu_to_velo.txt")}) {
    EXPECT_EQ((back.T_to_from.matrix() - v.T_to_from.matrix()).cwiseAbs().maxCoeff(), kExact);
    EXPECT_EQ(back.calib_time, "t");
  }
}

TEST(IoCalib, DerivedCam0ImuFollowsDevkitChain) {
  CamToCamCalib c = MakeCamToCam();
  Eigen::Isometry3d T_cam0_velo = Eigen::Isometry3d::Identity();
  T_cam0_velo.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // velo x fwd,y left,z up -> cam
  T_cam0_velo.translation() << 0.01, -0.08, -0.27;
  Eigen::Isometry3d T_velo_imu = Eigen::Isometry3d::Identity();
  T_velo_imu.translation() << -0.81, 0.32, -0.80;
  const Eigen::Isometry3d T = ComputeT_cam0_imu(c, T_cam0_velo, T_velo_imu);
  // A point 10 m ahead of the IMU, checked against the devkit formula
  // R_rect_00 * (R_cv * (p + t_vi) + t_cv).
  const Eigen::Vector3d p_imu(10, 0, 0);
  const Eigen::Vector3d expect =
      c.cams[0].R_rect * (T_cam0_velo.linear() * (p_imu + T_velo_imu.translation()) +
                          T_cam0_velo.translation());
  constexpr double kTol = 1e-12;  // the test rotations are exact: projection changes nothing
  EXPECT_LT((T * p_imu - expect).norm(), kTol);
  EXPECT_GT((T * p_imu).z(), 8.0);  // ahead of the IMU = in front of the camera
  EXPECT_LT((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), kTol);
}

TEST(IoCalib, OdometryCalibRoundTripAndStereo) {
  const test_support::ScopedTempDir dir("io_calib");
  OdometryCalib c;
  for (int i = 0; i < 4; ++i)
    c.P[i] << 718.856, 0, 607.1928, -386.1448 * i, 0, 718.856, 185.2157, 0, 0, 0, 1, 0;
  c.T_cam0_velo.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  c.T_cam0_velo.translation() << -0.0119, -0.054, -0.292;
  WriteOdometryCalib(dir / "calib.txt", c);
  const OdometryCalib back = ReadOdometryCalib(dir / "calib.txt");
  for (int i = 0; i < 4; ++i) EXPECT_EQ(back.P[i], c.P[i]);
  EXPECT_EQ(back.T_cam0_velo.matrix(), c.T_cam0_velo.matrix());
  const StereoCamera s = OdometryStereo(back, 1241, 376);
  EXPECT_DOUBLE_EQ(s.baseline_m, 386.1448 / 718.856);
  EXPECT_EQ(s.width, 1241);
  EXPECT_EQ(ErrorOf([] { ParseOdometryCalib("P0: 1 2 3\n", "calib.txt"); }),
            "calib.txt:1: key 'P0': 3 numbers, expected 12");
}

}  // namespace
}  // namespace locaid::kitti
