// A ray-cast stereo scene with known geometry for VO tests: a textured road
// (floor), two walls and a far wall, rendered for any cam0 pose. Fixed seed.
#pragma once

#include "core/stereo_camera.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>

namespace locaid::vo::testing {

inline StereoCamera SyntheticCamera() {
  StereoCamera cam;
  cam.fx = cam.fy = 400;
  cam.cx = 320;
  cam.cy = 120;
  cam.baseline_m = 0.54;
  cam.width = 640;
  cam.height = 240;
  return cam;
}

class CorridorScene {
 public:
  explicit CorridorScene(uint64_t seed = 7) {
    cv::RNG rng(seed);
    cv::Mat noise(kTex, kTex, CV_32F);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 255);
    cv::Mat fine, coarse;
    cv::GaussianBlur(noise, fine, cv::Size(0, 0), 1.5);
    cv::GaussianBlur(noise, coarse, cv::Size(0, 0), 6);
    cv::Mat tex = (fine - 127.5) * 4 + (coarse - 127.5) * 8 + 127.5;
    tex.convertTo(texture_, CV_32F);
  }

  // Renders the left (cam0) or right image seen from T_world_cam0.
  cv::Mat Render(const StereoCamera& cam, const Eigen::Isometry3d& T_world_cam0,
                 bool right) const {
    cv::Mat image(cam.height, cam.width, CV_8UC1);
    Eigen::Isometry3d T_world_cam = T_world_cam0;
    if (right) T_world_cam = T_world_cam0 * Eigen::Translation3d(cam.baseline_m, 0, 0);
    const Eigen::Matrix3d R = T_world_cam.rotation();
    const Eigen::Vector3d o = T_world_cam.translation();
    for (int v = 0; v < cam.height; ++v) {
      uchar* row = image.ptr<uchar>(v);
      for (int u = 0; u < cam.width; ++u) {
        const Eigen::Vector3d d =
            R * Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
        row[u] = Shade(o, d);
      }
    }
    return image;
  }

 private:
  static constexpr int kTex = 1024;
  static constexpr double kPxPerM = 40;
  // Planes: floor y = 1.6 (y down), walls x = -7 / +7, far wall z = 120.
  uchar Shade(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = std::numeric_limits<double>::infinity();
    double a = 0, b = 0;
    int plane = -1;
    const auto hit = [&](double t, int id) {
      if (t > 1e-6 && t < best) {
        best = t;
        plane = id;
      }
    };
    if (std::abs(d.y()) > 1e-9) hit((1.6 - o.y()) / d.y(), 0);
    if (std::abs(d.x()) > 1e-9) {
      hit((-7.0 - o.x()) / d.x(), 1);
      hit((7.0 - o.x()) / d.x(), 2);
    }
    if (std::abs(d.z()) > 1e-9) hit((120.0 - o.z()) / d.z(), 3);
    if (plane < 0) return 128;
    const Eigen::Vector3d p = o + best * d;
    switch (plane) {
      case 0: a = p.x(); b = p.z(); break;
      case 1: a = p.z(); b = p.y() + 3; break;
      case 2: a = p.z() + 11; b = p.y() + 7; break;
      default: a = p.x() + 5; b = p.y() + 13; break;
    }
    return Sample(a * kPxPerM, b * kPxPerM);
  }

  uchar Sample(double x, double y) const {
    const double fx = std::floor(x), fy = std::floor(y);
    const double ax = x - fx, ay = y - fy;
    const auto at = [&](long i, long j) {
      const int ii = static_cast<int>(((i % kTex) + kTex) % kTex);
      const int jj = static_cast<int>(((j % kTex) + kTex) % kTex);
      return static_cast<double>(texture_.at<float>(jj, ii));
    };
    const long i = static_cast<long>(fx), j = static_cast<long>(fy);
    const double val = (1 - ax) * (1 - ay) * at(i, j) + ax * (1 - ay) * at(i + 1, j) +
                       (1 - ax) * ay * at(i, j + 1) + ax * ay * at(i + 1, j + 1);
    return cv::saturate_cast<uchar>(val);
  }

  cv::Mat texture_;
};

// Pose of cam0 at frame k: forward speed_m_per_frame along z with a slow yaw.
inline Eigen::Isometry3d CorridorPose(int k, double speed_m_per_frame = 1.0,
                                      double yaw_rad_per_frame = 0.004) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  double yaw = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int i = 0; i < k; ++i) {
    yaw += yaw_rad_per_frame;
    p += Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) * Eigen::Vector3d(0, 0, speed_m_per_frame);
  }
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = p;
  return T;
}

}  // namespace locaid::vo::testing
