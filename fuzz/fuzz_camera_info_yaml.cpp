// libFuzzer target: camera_info YAML files (ros/camera_info_yaml.hpp), the
// calibration of a camera the server reads through GStreamer.
// Contract: ParseCameraInfoYaml returns a CameraInfo or throws
// std::invalid_argument (no yaml-cpp or other exception escapes). An
// accepted one either makes a Rectifier or is refused by it with
// std::runtime_error (what the server reports for such a file); a Rectifier
// rectifies an image of the camera_info's size (when small enough to try)
// into an 8-bit image of its valid region's size, and refuses another size
// with std::runtime_error.
#include "fuzz/fuzz_support.hpp"
#include "ros/camera_info_yaml.hpp"
#include "ros/camera_model.hpp"

#include <opencv2/core.hpp>

#include <exception>
#include <typeinfo>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  locaid::ros::CameraInfo info;
  try {
    info = locaid::ros::ParseCameraInfoYaml(text, "fuzz.yaml");
  } catch (const std::invalid_argument&) {
    return 0;
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("ParseCameraInfoYaml threw ") + typeid(e).name() + ": " + e.what());
  }
  // A rectifier of a huge camera would only measure the allocator.
  if (static_cast<uint64_t>(info.width) * info.height > 64 * 64) return 0;
  try {
    locaid::ros::Rectifier rectifier(info);
    const cv::Mat raw(static_cast<int>(info.height), static_cast<int>(info.width), CV_8UC1, cv::Scalar(90));
    // Before a crop the whole camera comes out, border included; the valid
    // region lies inside it, and cropped to it that is what comes out.
    const cv::Mat full = rectifier.Rectify(raw);
    LOCAID_FUZZ_CHECK(full.type() == CV_8UC1 && full.size() == raw.size(),
                      "rectified image of another size or type than its camera (no crop yet)");
    const cv::Rect valid = rectifier.valid_region();
    LOCAID_FUZZ_CHECK(!valid.empty() && (valid & cv::Rect(0, 0, raw.cols, raw.rows)) == valid,
                      "valid region empty or outside the image");
    rectifier.Crop(valid);
    const cv::Mat rectified = rectifier.Rectify(raw);
    LOCAID_FUZZ_CHECK(rectified.type() == CV_8UC1 && rectified.size() == valid.size(),
                      "rectified image of another size or type than its valid region");
    try {
      (void)rectifier.Rectify(cv::Mat(3, 5, CV_8UC1, cv::Scalar(1)));
      LOCAID_FUZZ_CHECK(info.width == 5 && info.height == 3, "an image of another size was rectified");
    } catch (const std::runtime_error&) {
    }
  } catch (const std::runtime_error&) {
    // refused by the rectifier, with its reason
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("an accepted camera_info fails in the rectifier: ") + typeid(e).name() + ": " +
                       e.what());
  }
  return 0;
}
