// From ROS 2 image messages to the 8-bit gray images VO reads: raw encodings
// and png/jpeg. Rectification is the camera model's (ros/camera_model.hpp).
#pragma once

#include "ros/messages.hpp"

#include <opencv2/core.hpp>

namespace locaid::ros {

// 8-bit gray of an Image: mono8 as is, mono16 (either byte order) scaled by
// 1/256, rgb8 / bgr8 / rgba8 / bgra8 to gray, bayer_{rggb,bggr,gbrg,grbg}8
// demosaiced to gray. Throws std::runtime_error naming the encoding, or the
// size that disagrees with step * height.
cv::Mat ToGray(const Image& image);
// png or jpeg (by the format string, else by the data's signature).
cv::Mat ToGray(const CompressedImage& image);

}  // namespace locaid::ros
