// ROS 2 image messages to gray: every raw encoding, png and jpeg, and the
// reason a bad image is refused.
#include "error_of.hpp"
#include "ros/images.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

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

TEST(RosImages, EveryRawEncodingBecomesTheSameGray) {
  std::string mono(64 * 48, '\0');
  for (size_t i = 0; i < mono.size(); ++i) mono[i] = static_cast<char>(i % 251);
  Image img{{}, 48, 64, "mono8", false, 64, mono};
  const cv::Mat gray = ToGray(img);
  ASSERT_EQ(gray.type(), CV_8UC1);
  // mono16 big-endian: the high byte first; scaled by 1/256.
  std::string m16;
  for (char c : mono) m16 += std::string{c, '\x7f'};
  img = {{}, 48, 64, "mono16", true, 128, m16};
  EXPECT_EQ(cv::norm(ToGray(img), gray, cv::NORM_INF), 0);
  // rgb8 with padded rows (step > 3 * width): grey pixels stay their value.
  std::string rgb;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) rgb += std::string(3, mono[static_cast<size_t>(64 * y + x)]);
    rgb += std::string(8, '\x55');
  }
  for (const std::string enc : {"rgb8", "bgr8"}) {
    img = {{}, 48, 64, enc, false, 64 * 3 + 8, rgb};
    EXPECT_LE(cv::norm(ToGray(img), gray, cv::NORM_INF), 1) << enc;
  }
  EXPECT_EQ(ToGray(Image{{}, 48, 64, "bayer_rggb8", false, 64, mono}).size(), gray.size());
}

TEST(RosImages, BadImagesAreRefusedWithTheReason) {
  const std::string data(100, '\0');
  EXPECT_NE(ErrorOf([&] { ToGray(Image{{}, 10, 10, "yuv422", false, 20, data}); }).find("'yuv422' not supported"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(Image{{}, 10, 10, "mono8", false, 5, data}); }).find("step 5"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(Image{{}, 20, 10, "mono8", false, 10, data}); }).find("100 bytes of data"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(CompressedImage{{}, "png", data}); }).find("does not decode"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(CompressedImage{{}, "tiff", data}); }).find("'tiff' not supported"),
            std::string::npos);
}

TEST(RosImages, PngAndJpegDecode) {
  cv::Mat img(48, 64, CV_8UC1);
  cv::randu(img, 0, 255);
  for (const std::string ext : {".png", ".jpg"}) {
    std::vector<uchar> bytes;
    cv::imencode(ext, img, bytes);
    const std::string s(bytes.begin(), bytes.end());
    const cv::Mat back = ToGray(CompressedImage{{}, ext == ".png" ? "mono8; png compressed " : "jpeg", s});
    ASSERT_EQ(back.size(), img.size());
    if (ext == ".png") {
      EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0);  // lossless
    }
  }
}
}  // namespace
}  // namespace locaid::ros
