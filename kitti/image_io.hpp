// Reading KITTI images as 8-bit grayscale.
#pragma once

#include <opencv2/core.hpp>

#include <filesystem>

namespace locaid::kitti {

// Reads `path` as CV_8UC1 (3/4-channel 8-bit images are converted with
// BGR(A)->GRAY). Throws kitti::Error "PATH: reason" when the file is missing,
// cannot be decoded, or is not 8-bit.
cv::Mat ReadGrayImage(const std::filesystem::path& path);

}  // namespace locaid::kitti
