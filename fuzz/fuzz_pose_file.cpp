// libFuzzer target: KITTI and TUM pose files (kitti/pose_io.hpp).
// Contract: ReadPoses / ReadKittiPoses / ReadTumPoses return or throw
// kitti::Error; returned poses are finite, TUM rotations orthonormal, KITTI
// rotations within the configured tolerance; ReadPoses agrees with the
// format-specific reader; WriteKittiPoses / WriteTumPoses read back exactly.
#include "fuzz/fuzz_support.hpp"
#include "kitti/pose_io.hpp"

#include <cmath>

namespace {

namespace kitti = locaid::kitti;

constexpr double kTumOrthoTolerance = 1e-9;

std::filesystem::path ScratchFile(const std::string& name) {
  static const locaid::fuzz::ScratchDir dir;
  return dir / name;
}

void CheckKitti(const std::vector<Eigen::Isometry3d>& poses, const kitti::PoseReadConfig& config) {
  for (const Eigen::Isometry3d& T : poses) {
    LOCAID_FUZZ_CHECK(T.matrix().allFinite(), "non-finite KITTI pose accepted");
    const Eigen::Matrix3d R = T.matrix().topLeftCorner<3, 3>();
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    LOCAID_FUZZ_CHECK(err <= config.rotation_tolerance, "non-rotation accepted");
  }
  const auto path = ScratchFile("kitti.txt");
  try {
    kitti::WriteKittiPoses(path, poses);
    const std::vector<Eigen::Isometry3d> back = kitti::ReadKittiPoses(path, config);
    LOCAID_FUZZ_CHECK(back.size() == poses.size(), "pose count changed on round trip");
    for (size_t i = 0; i < back.size(); ++i)
      LOCAID_FUZZ_CHECK(back[i].matrix() == poses[i].matrix(), "KITTI pose changed on round trip");
  } catch (const kitti::Error& e) {
    locaid::fuzz::Fail(std::string("written KITTI poses do not read back: ") + e.what());
  }
}

void CheckTum(const std::vector<kitti::StampedPose>& poses) {
  for (const kitti::StampedPose& p : poses) {
    LOCAID_FUZZ_CHECK(std::isfinite(p.t_s) && p.T_world_cam.matrix().allFinite(),
                      "non-finite TUM pose accepted");
    const Eigen::Matrix3d R = p.T_world_cam.linear();
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    LOCAID_FUZZ_CHECK(err <= kTumOrthoTolerance, "TUM rotation not orthonormal");
  }
  const auto path = ScratchFile("tum.txt");
  try {
    kitti::WriteTumPoses(path, poses);
    const std::vector<kitti::StampedPose> back = kitti::ReadTumPoses(path);
    LOCAID_FUZZ_CHECK(back.size() == poses.size(), "pose count changed on round trip");
    for (size_t i = 0; i < back.size(); ++i) {
      LOCAID_FUZZ_CHECK(back[i].t_s == poses[i].t_s, "TUM time changed on round trip");
      LOCAID_FUZZ_CHECK(back[i].T_world_cam.translation() == poses[i].T_world_cam.translation(),
                        "TUM translation changed on round trip");
    }
  } catch (const kitti::Error& e) {
    locaid::fuzz::Fail(std::string("written TUM poses do not read back: ") + e.what());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static locaid::fuzz::MemFile file;
  const std::filesystem::path& path = file.Write(locaid::fuzz::AsText(data, size));
  const kitti::PoseReadConfig config;
  kitti::PoseFile detected;
  bool detected_ok = false;
  try {
    detected = kitti::ReadPoses(path, config);
    detected_ok = true;
  } catch (const kitti::Error&) {
  }
  try {
    const std::vector<Eigen::Isometry3d> poses = kitti::ReadKittiPoses(path, config);
    if (detected_ok && detected.format == kitti::PoseFormat::kKitti) {
      LOCAID_FUZZ_CHECK(detected.poses.size() == poses.size(), "ReadPoses disagrees (KITTI)");
    }
    CheckKitti(poses, config);
  } catch (const kitti::Error&) {
    LOCAID_FUZZ_CHECK(!(detected_ok && detected.format == kitti::PoseFormat::kKitti),
                      "ReadPoses accepted what ReadKittiPoses rejects");
  }
  try {
    const std::vector<kitti::StampedPose> poses = kitti::ReadTumPoses(path);
    if (detected_ok && detected.format == kitti::PoseFormat::kTum) {
      LOCAID_FUZZ_CHECK(detected.poses.size() == poses.size(), "ReadPoses disagrees (TUM)");
    }
    CheckTum(poses);
  } catch (const kitti::Error&) {
    LOCAID_FUZZ_CHECK(!(detected_ok && detected.format == kitti::PoseFormat::kTum),
                      "ReadPoses accepted what ReadTumPoses rejects");
  }
  return 0;
}
