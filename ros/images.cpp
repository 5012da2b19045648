#include "ros/images.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>

namespace locaid::ros {
namespace {

std::runtime_error ImageError(const std::string& what) { return std::runtime_error("image: " + what); }

// Bytes per pixel and the OpenCV conversion to gray of a raw encoding
// (code < 0: none needed).
struct Encoding {
  int bytes_per_pixel;
  int cv_type;
  int to_gray;
};

const std::map<std::string, Encoding>& Encodings() {
  // ROS's bayer names give the colour of the top-left 2x2 block; OpenCV names
  // the second row's second and third pixels: rggb <-> BayerBG, and so on.
  static const std::map<std::string, Encoding> table = {
      {"mono8", {1, CV_8UC1, -1}},
      {"8UC1", {1, CV_8UC1, -1}},
      {"mono16", {2, CV_16UC1, -1}},
      {"16UC1", {2, CV_16UC1, -1}},
      {"rgb8", {3, CV_8UC3, cv::COLOR_RGB2GRAY}},
      {"bgr8", {3, CV_8UC3, cv::COLOR_BGR2GRAY}},
      {"rgba8", {4, CV_8UC4, cv::COLOR_RGBA2GRAY}},
      {"bgra8", {4, CV_8UC4, cv::COLOR_BGRA2GRAY}},
      {"bayer_rggb8", {1, CV_8UC1, cv::COLOR_BayerBG2GRAY}},
      {"bayer_bggr8", {1, CV_8UC1, cv::COLOR_BayerRG2GRAY}},
      {"bayer_gbrg8", {1, CV_8UC1, cv::COLOR_BayerGR2GRAY}},
      {"bayer_grbg8", {1, CV_8UC1, cv::COLOR_BayerGB2GRAY}},
  };
  return table;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

cv::Mat ToGray(const Image& image) {
  const auto it = Encodings().find(image.encoding);
  if (it == Encodings().end()) {
    throw ImageError("encoding '" + image.encoding +
                     "' not supported (mono8, mono16, rgb8, bgr8, rgba8, bgra8, bayer_*8)");
  }
  const Encoding& e = it->second;
  if (image.width == 0 || image.height == 0 || image.width > 1u << 15 || image.height > 1u << 15) {
    throw ImageError("size " + std::to_string(image.width) + "x" + std::to_string(image.height) + " out of range");
  }
  const uint64_t row = uint64_t{image.width} * static_cast<uint64_t>(e.bytes_per_pixel);
  if (image.step < row) {
    throw ImageError("step " + std::to_string(image.step) + " < width " + std::to_string(image.width) + " x " +
                     std::to_string(e.bytes_per_pixel) + " bytes of " + image.encoding);
  }
  if (image.data.size() < uint64_t{image.step} * image.height) {
    throw ImageError(std::to_string(image.data.size()) + " bytes of data, step x height needs " +
                     std::to_string(uint64_t{image.step} * image.height));
  }
  // A view of the message bytes; every path below copies out of it.
  const cv::Mat view(static_cast<int>(image.height), static_cast<int>(image.width), e.cv_type,
                     const_cast<char*>(image.data.data()), image.step);
  cv::Mat gray;
  if (e.cv_type == CV_16UC1) {
    cv::Mat host = view.clone();
    const bool host_big = false;  // locaid builds for little-endian hosts only (x86-64, arm64)
    if (image.big_endian != host_big) {
      for (int y = 0; y < host.rows; ++y) {
        auto* p = host.ptr<uint16_t>(y);
        for (int x = 0; x < host.cols; ++x) p[x] = static_cast<uint16_t>((p[x] >> 8) | (p[x] << 8));
      }
    }
    host.convertTo(gray, CV_8U, 1.0 / 256.0);
  } else if (e.to_gray < 0) {
    gray = view.clone();
  } else {
    cv::cvtColor(view, gray, e.to_gray);
  }
  return gray;
}

cv::Mat ToGray(const CompressedImage& image) {
  const std::string format = Lower(image.format);
  const bool png = format.find("png") != std::string::npos;
  const bool jpeg = format.find("jpeg") != std::string::npos || format.find("jpg") != std::string::npos;
  if (!png && !jpeg && !format.empty()) {
    throw ImageError("compressed format '" + image.format + "' not supported (png, jpeg)");
  }
  if (image.data.empty()) throw ImageError("compressed image with no data");
  const cv::Mat bytes(1, static_cast<int>(image.data.size()), CV_8UC1, const_cast<char*>(image.data.data()));
  cv::Mat gray = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
  if (gray.empty()) throw ImageError("the " + (format.empty() ? std::string("compressed") : format) +
                                     " data does not decode");
  if (gray.depth() != CV_8U) gray.convertTo(gray, CV_8U, 1.0 / 256.0);
  return gray;
}

}  // namespace locaid::ros
