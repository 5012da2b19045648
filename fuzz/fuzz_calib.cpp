// libFuzzer target: KITTI calibration files (kitti/calib.hpp).
// Built three times, LOCAID_FUZZ_CALIB_KIND selecting the parser:
//   1 calib_cam_to_cam.txt, 2 calib_velo_to_cam.txt / calib_imu_to_velo.txt,
//   3 odometry calib.txt.
// Contract: Parse* returns or throws kitti::Error; what it returns is finite,
// its derived stereo model / extrinsic can be computed without undefined
// behaviour, and Write* -> Read* reproduces it exactly (no kitti::Error there).
#include "core/stereo_camera.hpp"
#include "fuzz/fuzz_support.hpp"
#include "kitti/calib.hpp"

#include <cmath>

#ifndef LOCAID_FUZZ_CALIB_KIND
#error "define LOCAID_FUZZ_CALIB_KIND (1 cam_to_cam, 2 rigid, 3 odometry)"
#endif

namespace {

namespace kitti = locaid::kitti;

template <typename M>
void CheckFinite(const M& m, const std::string& what) {
  LOCAID_FUZZ_CHECK(m.allFinite(), what + " has a non-finite entry");
}

#if LOCAID_FUZZ_CALIB_KIND != 2
void CheckStereo(const locaid::StereoCamera& cam) {
  LOCAID_FUZZ_CHECK(std::isfinite(cam.fx) && std::isfinite(cam.fy) && std::isfinite(cam.cx) &&
                        std::isfinite(cam.cy) && std::isfinite(cam.baseline_m),
                    "stereo model not finite");
}
#endif

std::filesystem::path ScratchFile(const std::string& name) {
  static const locaid::fuzz::ScratchDir dir;
  return dir / name;
}

#if LOCAID_FUZZ_CALIB_KIND == 1
void Check(const kitti::CamToCamCalib& c) {
  for (const auto& cam : c.cams) {
    CheckFinite(cam.K, "K");
    CheckFinite(cam.P_rect, "P_rect");
    LOCAID_FUZZ_CHECK(cam.S_rect(0) >= 1 && cam.S_rect(1) >= 1, "S_rect not positive");
  }
  const locaid::StereoCamera stereo = kitti::RectifiedStereo(c);
  CheckStereo(stereo);
  LOCAID_FUZZ_CHECK(stereo.width >= 1 && stereo.height >= 1, "rectified size not positive");
  CheckFinite(kitti::ComputeT_cam0_imu(c, Eigen::Isometry3d::Identity(),
                                       Eigen::Isometry3d::Identity()).matrix(),
              "T_cam0_imu");
  const auto path = ScratchFile("calib_cam_to_cam.txt");
  kitti::WriteCamToCam(path, c);
  const kitti::CamToCamCalib back = kitti::ReadCamToCam(path);
  for (int i = 0; i < 4; ++i) {
    LOCAID_FUZZ_CHECK(back.cams[i].P_rect == c.cams[i].P_rect, "P_rect changed on round trip");
    LOCAID_FUZZ_CHECK(back.cams[i].K == c.cams[i].K, "K changed on round trip");
    LOCAID_FUZZ_CHECK(back.cams[i].S_rect == c.cams[i].S_rect, "S_rect changed on round trip");
  }
}
void Run(std::string_view text) {
  kitti::CamToCamCalib c;
  try {
    c = kitti::ParseCamToCam(text, "fuzz");
  } catch (const kitti::Error&) {
    return;
  }
  Check(c);
}
#elif LOCAID_FUZZ_CALIB_KIND == 2
void Check(const kitti::RigidCalib& c) {
  CheckFinite(c.T_to_from.matrix(), "T_to_from");
  CheckFinite(kitti::ComputeT_cam0_imu(kitti::CamToCamCalib{}, c.T_to_from, c.T_to_from).matrix(),
              "T_cam0_imu");
  const auto path = ScratchFile("calib_imu_to_velo.txt");
  kitti::WriteImuToVelo(path, c);
  const kitti::RigidCalib back = kitti::ReadImuToVelo(path);
  LOCAID_FUZZ_CHECK(back.T_to_from.matrix() == c.T_to_from.matrix(),
                    "rigid transform changed on round trip");
}
void Run(std::string_view text) {
  kitti::RigidCalib c;
  try {
    c = kitti::ParseRigidCalib(text, "fuzz");
  } catch (const kitti::Error&) {
    return;
  }
  Check(c);
}
#elif LOCAID_FUZZ_CALIB_KIND == 3
void Check(const kitti::OdometryCalib& c) {
  for (const auto& P : c.P) CheckFinite(P, "P");
  CheckFinite(c.T_cam0_velo.matrix(), "Tr");
  CheckStereo(kitti::OdometryStereo(c, 1241, 376));
  const auto path = ScratchFile("calib.txt");
  kitti::WriteOdometryCalib(path, c);
  const kitti::OdometryCalib back = kitti::ReadOdometryCalib(path);
  for (int i = 0; i < 4; ++i) LOCAID_FUZZ_CHECK(back.P[i] == c.P[i], "P changed on round trip");
  LOCAID_FUZZ_CHECK(back.T_cam0_velo.matrix() == c.T_cam0_velo.matrix(),
                    "Tr changed on round trip");
}
void Run(std::string_view text) {
  kitti::OdometryCalib c;
  try {
    c = kitti::ParseOdometryCalib(text, "fuzz");
  } catch (const kitti::Error&) {
    return;
  }
  Check(c);
}
#endif

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    Run(locaid::fuzz::AsText(data, size));
  } catch (const locaid::kitti::Error& e) {
    locaid::fuzz::Fail(std::string("accepted input fails after parsing: ") + e.what());
  }
  return 0;
}
