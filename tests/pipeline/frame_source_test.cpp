// Pushed-image decoding: the PNG size is read from the IHDR header and
// checked before any pixel is decoded.
#include "core/stereo_camera.hpp"
#include "pipeline/live_frame_source.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <stdexcept>
#include <vector>

namespace locaid::pipeline {
namespace {

StereoCamera Camera(int w, int h) { return StereoCamera{30, 30, w / 2.0, h / 2.0, 0.5, w, h}; }

std::string EncodePng(int w, int h) {
  cv::Mat img(h, w, CV_8UC1);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) img.at<uint8_t>(r, c) = static_cast<uint8_t>((r * 7 + c * 3) & 0xff);
  std::vector<uint8_t> buf;
  EXPECT_TRUE(cv::imencode(".png", img, buf));
  return std::string(buf.begin(), buf.end());
}

// Rewrites the IHDR width/height (bytes 16..23, big endian).
std::string DeclareSize(std::string png, uint32_t w, uint32_t h) {
  for (int i = 0; i < 4; ++i) {
    png[static_cast<size_t>(16 + i)] = static_cast<char>((w >> (24 - 8 * i)) & 0xff);
    png[static_cast<size_t>(20 + i)] = static_cast<char>((h >> (24 - 8 * i)) & 0xff);
  }
  return png;
}

std::string DecodeError(const std::string& bytes, const StereoCamera& cam) {
  try {
    DecodeLiveImage(bytes, true, cam, "left");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(LiveImage, PngHeaderSizeIsReadWithoutDecoding) {
  const std::string png = EncodePng(40, 20);
  const auto size = ReadPngSize(png);
  ASSERT_TRUE(size.has_value());
  EXPECT_EQ(size->width, 40u);
  EXPECT_EQ(size->height, 20u);
  EXPECT_FALSE(ReadPngSize("not a png").has_value());
  EXPECT_FALSE(ReadPngSize(png.substr(0, 23)).has_value());
  const auto bomb = ReadPngSize(DeclareSize(png, 30000, 30000));
  ASSERT_TRUE(bomb.has_value());
  EXPECT_EQ(bomb->width, 30000u);
}

TEST(LiveImage, MatchingPngDecodesAndOtherSizesAreRejectedNamingBoth) {
  const auto cam = Camera(40, 20);
  const std::string png = EncodePng(40, 20);
  const cv::Mat img = DecodeLiveImage(png, true, cam, "left");
  EXPECT_EQ(img.cols, 40);
  EXPECT_EQ(img.rows, 20);
  EXPECT_EQ(img.at<uint8_t>(3, 5), static_cast<uint8_t>((3 * 7 + 5 * 3) & 0xff));
  EXPECT_EQ(PngSizeMismatch(png, cam, "left"), "");

  // The header says 30000x30000 px; decoding it would allocate ~900 MB.
  const std::string bomb = DeclareSize(png, 30000, 30000);
  const std::string e = DecodeError(bomb, cam);
  EXPECT_NE(e.find("left image"), std::string::npos) << e;
  EXPECT_NE(e.find("30000x30000"), std::string::npos) << e;
  EXPECT_NE(e.find("40x20"), std::string::npos) << e;
  EXPECT_EQ(PngSizeMismatch(bomb, cam, "right").rfind("right image: PNG declares 30000x30000 px", 0), 0u);
  // A genuine PNG of another size is rejected the same way.
  EXPECT_NE(DecodeError(EncodePng(41, 20), cam).find("41x20"), std::string::npos);
  EXPECT_NE(DecodeError("garbage bytes, long enough to have a header", cam).find("not a PNG"), std::string::npos);
}

}  // namespace
}  // namespace locaid::pipeline
