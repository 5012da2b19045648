// The camera model of a CameraInfo: rectification (passing through, remapped,
// cropped; what cannot rectify) and the stereo pair from two CameraInfo.
#include "error_of.hpp"
#include "ros/camera_model.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace locaid::ros {
namespace {

template <typename F>
std::string ErrorOf(F&& f) {
  return test_support::ErrorOf<std::exception>(std::forward<F>(f));
}

CameraInfo Info(double tx, std::vector<double> d = {}, std::string model = "plumb_bob") {
  CameraInfo c;
  c.header.frame_id = "cam";
  c.width = 64;
  c.height = 48;
  c.distortion_model = std::move(model);
  c.d = std::move(d);
  c.k = {50, 0, 32, 0, 50, 24, 0, 0, 1};
  c.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.p = {50, 0, 32, tx, 0, 50, 24, 0, 0, 0, 1, 0};
  return c;
}

TEST(Rectifier, RectifiedInputPassesThroughAndRawIsRemapped) {
  const Rectifier already(Info(0));
  EXPECT_TRUE(already.passthrough());
  const Rectifier raw(Info(0, {-0.3, 0.1, 0, 0, 0}));
  EXPECT_FALSE(raw.passthrough());
  cv::Mat img(48, 64, CV_8UC1, cv::Scalar(200));
  EXPECT_EQ(raw.Rectify(img).size(), img.size());
  EXPECT_NE(ErrorOf([&] { raw.Rectify(cv::Mat(10, 10, CV_8UC1)); }).find("disagrees with its camera_info"),
            std::string::npos);
  // A crop gives exactly that part of the full rectified image.
  cv::Mat texture(48, 64, CV_8UC1);
  cv::randu(texture, 0, 255);
  const cv::Mat full = Rectifier(Info(0, {0.3, 0.1, 0, 0, 0})).Rectify(texture);
  Rectifier cropped(Info(0, {0.3, 0.1, 0, 0, 0}));  // corners map outside the raw image
  const cv::Rect region = cropped.valid_region();
  ASSERT_LT(region.area(), 64 * 48);
  cropped.Crop(region);
  EXPECT_EQ(cv::norm(cropped.Rectify(texture), full(region), cv::NORM_INF), 0);
  EXPECT_NE(ErrorOf([&] { cropped.Crop(cv::Rect(0, 0, 64, 48)); }).find("not inside"), std::string::npos);
  EXPECT_FALSE(Rectifier(Info(0, {0.1, 0.01, 0, 0}, "equidistant")).passthrough());
  EXPECT_FALSE(Rectifier(Info(0, {0.1, 0.01, 0, 0, 0, 0, 0, 0}, "rational_polynomial")).passthrough());
}

TEST(Rectifier, CameraInfoThatCannotRectifyIsRefused) {
  CameraInfo zero;
  zero.width = 64;
  zero.height = 48;
  EXPECT_NE(ErrorOf([&] { Rectifier{zero}; }).find("uncalibrated"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { Rectifier{Info(0, {0.1}, "fisheye_x")}; }).find("'fisheye_x' not supported"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { Rectifier{Info(0, {0.1, 0.2}, "equidistant")}; }).find("needs 4"), std::string::npos);
  auto binned = Info(0);
  binned.binning_x = 2;
  EXPECT_NE(ErrorOf([&] { Rectifier{binned}; }).find("binning"), std::string::npos);
}

TEST(StereoFromCameraInfo, BaselineFromTheRightP) {
  const StereoCamera cam = StereoFromCameraInfo(Info(0), Info(-50 * 0.54));
  EXPECT_NEAR(cam.baseline_m, 0.54, 1e-12);
  EXPECT_EQ(cam.width, 64);
  EXPECT_NE(ErrorOf([] { StereoFromCameraInfo(Info(-27), Info(0)); }).find("no positive baseline"), std::string::npos);
  auto other = Info(-27);
  other.p[2] = 40;
  EXPECT_NE(ErrorOf([&] { StereoFromCameraInfo(Info(0), other); }).find("not a rectified stereo pair"),
            std::string::npos);
}

}  // namespace
}  // namespace locaid::ros
