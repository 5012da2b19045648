#include "ros/sensor_setup.hpp"

#include "ros/camera_model.hpp"
#include "ros/tf_tree.hpp"

#include <algorithm>
#include <cmath>

namespace locaid::ros {
namespace {

// The left camera's optical frame into its rectified frame.
Eigen::Isometry3d RectifiedFromCamera(const CameraInfo& left) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = RectificationRotation(left);
  return T;
}

}  // namespace

std::optional<Eigen::Isometry3d> CameraImuExtrinsic(const CameraInfo& left,
                                                    const std::vector<TransformStamped>& static_transforms,
                                                    const std::string& imu_frame) {
  const auto T_imu_cam = FindTransform(static_transforms, imu_frame, left.header.frame_id);
  if (!T_imu_cam) return std::nullopt;
  return RectifiedFromCamera(left) * T_imu_cam->inverse();
}

Eigen::Isometry3d CameraBodyWithoutImu() {
  Eigen::Matrix3d R;
  R << 0, -1, 0,  //
      0, 0, -1,   //
      1, 0, 0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  return T;
}

std::optional<Eigen::Vector3d> GpsLeverArm(const CameraInfo& left,
                                           const std::vector<TransformStamped>& static_transforms,
                                           const Eigen::Isometry3d& T_cam0_imu, const std::string& gps_frame) {
  const auto T_cam_gps = FindTransform(static_transforms, left.header.frame_id, gps_frame);
  if (!T_cam_gps) return std::nullopt;
  return (T_cam0_imu.inverse() * RectifiedFromCamera(left) * *T_cam_gps).translation();
}

bool HasPosition(const NavSatFix& nav) {
  return nav.status > NavSatFix::kNoFix && std::isfinite(nav.latitude) && std::isfinite(nav.longitude) &&
         std::isfinite(nav.altitude) && std::abs(nav.latitude) <= 90 && std::abs(nav.longitude) <= 180;
}

std::optional<Eigen::Matrix3d> StatedCovariance(const NavSatFix& nav) {
  const auto& c = nav.position_covariance;
  const bool known = nav.position_covariance_type != NavSatFix::kCovUnknown &&
                     std::all_of(c.begin(), c.end(), [](double v) { return std::isfinite(v); }) && c[0] > 0 &&
                     c[4] > 0 && c[8] > 0;
  if (!known) return std::nullopt;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (i == j || nav.position_covariance_type != NavSatFix::kCovDiagonalKnown)
        cov(i, j) = c[static_cast<size_t>(3 * i + j)];
  return Eigen::Matrix3d(0.5 * (cov + cov.transpose()));
}

}  // namespace locaid::ros
