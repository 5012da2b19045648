#include "ros/camera_model.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locaid::ros {
namespace {

// Shrinks the rectified image's rectangle, one row or column at a time from
// the side with the most border pixels, until no pixel in it is border.
cv::Rect ValidRegion(const cv::Mat& map1, const cv::Mat& map2, cv::Size size) {
  cv::Mat ones(size, CV_8UC1, cv::Scalar(255)), valid;
  cv::remap(ones, valid, map1, map2, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  int x0 = 0, y0 = 0, x1 = size.width, y1 = size.height;  // [x0, x1) x [y0, y1)
  const auto border = [&](int xa, int ya, int xb, int yb) {
    return xb > xa && yb > ya ? (xb - xa) * (yb - ya) - cv::countNonZero(valid(cv::Rect(xa, ya, xb - xa, yb - ya))) : 0;
  };
  while (x1 - x0 > 1 && y1 - y0 > 1) {
    const int sides[4] = {border(x0, y0, x1, y0 + 1), border(x0, y1 - 1, x1, y1), border(x0, y0, x0 + 1, y1),
                          border(x1 - 1, y0, x1, y1)};
    const int worst = static_cast<int>(std::max_element(sides, sides + 4) - sides);
    if (sides[worst] == 0) break;
    if (worst == 0) ++y0;
    if (worst == 1) --y1;
    if (worst == 2) ++x0;
    if (worst == 3) --x1;
  }
  return {x0, y0, x1 - x0, y1 - y0};
}

bool AllZero(const double* v, size_t n) {
  return std::all_of(v, v + n, [](double x) { return x == 0; });
}

}  // namespace

Rectifier::Rectifier(const CameraInfo& info)
    : width_(static_cast<int>(info.width)), height_(static_cast<int>(info.height)) {
  const std::string who = "camera_info of '" + info.header.frame_id + "': ";
  if (info.width == 0 || info.height == 0 || info.width > 1u << 15 || info.height > 1u << 15)
    throw std::runtime_error(who + "size " + std::to_string(info.width) + "x" + std::to_string(info.height));
  if (AllZero(info.k.data(), 9) || AllZero(info.p.data(), 12) || info.p[0] <= 0 || info.p[5] <= 0)
    throw std::runtime_error(who + "K or P is zero (an uncalibrated camera): cannot rectify");
  if (info.binning_x > 1 || info.binning_y > 1)
    throw std::runtime_error(who + "binning " + std::to_string(info.binning_x) + "x" +
                             std::to_string(info.binning_y) + " not supported");
  const bool full_roi = info.roi_width == 0 || (info.roi_width == info.width && info.roi_height == info.height);
  if (!full_roi) throw std::runtime_error(who + "a region of interest smaller than the image is not supported");

  valid_ = crop_ = cv::Rect(0, 0, width_, height_);
  const Eigen::Matrix3d R = RectificationRotation(info);
  const bool no_distortion = AllZero(info.d.data(), info.d.size());
  if (no_distortion && R.isIdentity(1e-9)) return;  // already rectified

  cv::Mat K(3, 3, CV_64F), Rm(3, 3, CV_64F), P(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      K.at<double>(i, j) = info.k[static_cast<size_t>(3 * i + j)];
      Rm.at<double>(i, j) = info.r[static_cast<size_t>(3 * i + j)];
      P.at<double>(i, j) = info.p[static_cast<size_t>(4 * i + j)];
    }
  cv::Mat D(1, static_cast<int>(info.d.size()), CV_64F);
  for (size_t i = 0; i < info.d.size(); ++i) D.at<double>(0, static_cast<int>(i)) = info.d[i];
  const cv::Size size(width_, height_);
  const std::string& model = info.distortion_model;
  if (model == "equidistant") {
    if (info.d.size() != 4) throw std::runtime_error(who + "equidistant needs 4 coefficients, D has " +
                                                     std::to_string(info.d.size()));
    cv::fisheye::initUndistortRectifyMap(K, D, Rm, P, size, CV_16SC2, map1_, map2_);
  } else if (model == "plumb_bob" || model == "rational_polynomial" || (model.empty() && no_distortion)) {
    const size_t n = info.d.size();
    if (!(n == 0 || n == 4 || n == 5 || n == 8 || n == 12 || n == 14))
      throw std::runtime_error(who + model + " with " + std::to_string(n) + " coefficients");
    if (model == "rational_polynomial" && n < 8)
      throw std::runtime_error(who + "rational_polynomial needs 8 coefficients, D has " + std::to_string(n));
    cv::initUndistortRectifyMap(K, n == 0 ? cv::Mat() : D, Rm, P, size, CV_16SC2, map1_, map2_);
  } else {
    throw std::runtime_error(who + "distortion model '" + model +
                             "' not supported (plumb_bob, rational_polynomial, equidistant)");
  }
  valid_ = ValidRegion(map1_, map2_, size);
  if (valid_.width < width_ / 4 || valid_.height < height_ / 4) {
    throw std::runtime_error(who + "rectification leaves a valid region of only " + std::to_string(valid_.width) +
                             "x" + std::to_string(valid_.height) + " pixels: K, D, R and P do not fit together");
  }
}

cv::Mat Rectifier::Rectify(const cv::Mat& raw) const {
  if (raw.cols != width_ || raw.rows != height_) {
    throw std::runtime_error("image size " + std::to_string(raw.cols) + "x" + std::to_string(raw.rows) +
                             " disagrees with its camera_info (" + std::to_string(width_) + "x" +
                             std::to_string(height_) + ")");
  }
  if (passthrough()) return crop_.size() == raw.size() ? raw : raw(crop_).clone();
  cv::Mat rect;
  cv::remap(raw, rect, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return rect;
}

void Rectifier::Crop(const cv::Rect& region) {
  if (region.empty() || (region & crop_) != region) {
    throw std::runtime_error("rectifier: crop " + std::to_string(region.width) + "x" + std::to_string(region.height) +
                             " at (" + std::to_string(region.x) + ", " + std::to_string(region.y) +
                             ") is not inside the image (or a crop before)");
  }
  // The maps of the region only: remap then writes just those pixels.
  if (!passthrough()) {
    const cv::Rect in_maps = region - crop_.tl();  // the maps may be cropped already
    map1_ = map1_(in_maps).clone();
    map2_ = map2_(in_maps).clone();
  }
  crop_ = region;
}

Eigen::Matrix3d RectificationRotation(const CameraInfo& info) {
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = info.r[static_cast<size_t>(3 * i + j)];
  // An all-zero R (some drivers for a monocular camera) means no rotation.
  if (R.isZero(0)) return Eigen::Matrix3d::Identity();
  return R;
}

StereoCamera StereoFromCameraInfo(const CameraInfo& left, const CameraInfo& right) {
  if (left.width != right.width || left.height != right.height) {
    throw std::runtime_error("left and right camera_info sizes differ (" + std::to_string(left.width) + "x" +
                             std::to_string(left.height) + " vs " + std::to_string(right.width) + "x" +
                             std::to_string(right.height) + ")");
  }
  StereoCamera cam;
  cam.fx = left.p[0];
  cam.fy = left.p[5];
  cam.cx = left.p[2];
  cam.cy = left.p[6];
  cam.width = static_cast<int>(left.width);
  cam.height = static_cast<int>(left.height);
  if (!(cam.fx > 0 && cam.fy > 0)) throw std::runtime_error("left camera_info: P has no focal length");
  const double tol = 1e-6 * cam.fx + 1e-9;
  if (std::abs(right.p[0] - cam.fx) > tol || std::abs(right.p[5] - cam.fy) > tol ||
      std::abs(right.p[2] - cam.cx) > tol || std::abs(right.p[6] - cam.cy) > tol) {
    throw std::runtime_error("left and right camera_info P disagree on the rectified intrinsics (fx, fy, cx, cy): "
                             "not a rectified stereo pair");
  }
  cam.baseline_m = -(right.p[3] - left.p[3]) / cam.fx;
  if (!(cam.baseline_m > 0)) {
    throw std::runtime_error("right camera_info: P[3] = " + std::to_string(right.p[3]) +
                             " gives no positive baseline (expected -fx * baseline)");
  }
  return cam;
}

RectifiedStereo MakeRectifiedStereo(const CameraInfo& left, const CameraInfo& right) {
  RectifiedStereo s{Rectifier(left), Rectifier(right), StereoFromCameraInfo(left, right), {}, {}};
  s.crop = s.left.valid_region() & s.right.valid_region();
  s.left.Crop(s.crop);
  s.right.Crop(s.crop);
  s.camera.cx -= s.crop.x;
  s.camera.cy -= s.crop.y;
  s.camera.width = s.crop.width;
  s.camera.height = s.crop.height;
  s.note = "rectified images cropped to " + std::to_string(s.crop.width) + "x" + std::to_string(s.crop.height) +
           " at (" + std::to_string(s.crop.x) + ", " + std::to_string(s.crop.y) + ") of " +
           std::to_string(left.width) + "x" + std::to_string(left.height) + " (no border)";
  return s;
}

}  // namespace locaid::ros
