#include "kitti/image_io.hpp"

#include "kitti/types.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <system_error>

namespace locaid::kitti {

cv::Mat ReadGrayImage(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(path.string() + ": image file missing");
  }
  const cv::Mat raw = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  if (raw.empty()) throw Error(path.string() + ": cannot decode image (corrupt or not an image)");
  if (raw.depth() != CV_8U) {
    throw Error(path.string() + ": unsupported pixel depth (expected 8-bit), OpenCV type " +
                std::to_string(raw.type()));
  }
  switch (raw.channels()) {
    case 1:
      return raw;
    case 3: {
      cv::Mat gray;
      cv::cvtColor(raw, gray, cv::COLOR_BGR2GRAY);
      return gray;
    }
    case 4: {
      cv::Mat gray;
      cv::cvtColor(raw, gray, cv::COLOR_BGRA2GRAY);
      return gray;
    }
    default:
      throw Error(path.string() + ": unsupported channel count " + std::to_string(raw.channels()));
  }
}

}  // namespace locaid::kitti
