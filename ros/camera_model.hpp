// The camera model of a sensor_msgs/CameraInfo: rectification as image_proc
// does it (the rectified camera is P's left 3x3, the output has CameraInfo's
// size; Rectifier::valid_region() is the part without border) and the
// rectified stereo pair of two cameras. Decoding the images themselves:
// ros/images.hpp.
#pragma once

#include "core/stereo_camera.hpp"
#include "ros/messages.hpp"

#include <opencv2/core.hpp>

#include <Eigen/Geometry>

#include <string>

namespace locaid::ros {

// Rectifies the raw images of one camera. When D is all zero and R the
// identity the images are taken as already rectified (no remap). Throws
// std::runtime_error for a CameraInfo that cannot rectify: all-zero K or P,
// an unknown distortion model, D of the wrong length, binning or a partial
// ROI (not supported).
class Rectifier {
 public:
  explicit Rectifier(const CameraInfo& info);
  // `raw` must have CameraInfo's width x height (throws otherwise).
  cv::Mat Rectify(const cv::Mat& raw) const;
  bool passthrough() const { return map1_.empty(); }
  // The largest rectangle of the rectified image whose every pixel comes from
  // inside the raw image (no black border): the whole image when passing
  // through.
  cv::Rect valid_region() const { return valid_; }
  // From now on Rectify() returns only `region` of the rectified image
  // (computed directly, no full-size image in between). Throws when
  // `region` is not inside the image (or inside the previous crop).
  void Crop(const cv::Rect& region);
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  int width_ = 0, height_ = 0;
  cv::Mat map1_, map2_;
  cv::Rect valid_, crop_;  // crop_: the part Rectify() returns
};

// The rectified stereo pair of the left and right CameraInfo: fx, fy, cx, cy
// from the left P, the baseline from the right P's Tx = -fx * baseline.
// Throws when the two sizes or intrinsics disagree or the baseline is not
// positive.
StereoCamera StereoFromCameraInfo(const CameraInfo& left, const CameraInfo& right);

// Both cameras' rectifiers and the stereo model VO sees: the rectified
// images keep only the part every pixel of which has a source in both raw
// images (no border edge for VO to track; KITTI's rectified size for its
// drives), and the model's principal point moves with that crop. One place,
// for recorded bags and live cameras alike.
struct RectifiedStereo {
  Rectifier left, right;
  StereoCamera camera;
  cv::Rect crop;
  std::string note;  // "rectified images cropped to WxH at (x, y) of WxH (no border)"
};
RectifiedStereo MakeRectifiedStereo(const CameraInfo& left, const CameraInfo& right);

// The rotation from the left camera's optical frame into its rectified frame
// (CameraInfo's R).
Eigen::Matrix3d RectificationRotation(const CameraInfo& info);

}  // namespace locaid::ros
