// libFuzzer target: decoding of frames pushed by clients
// (pipeline/live_frame_source.hpp DecodeLiveImage: PNG through cv::imdecode, or raw
// GRAY8 bytes). Contract: returns a CV_8UC1 image of exactly the camera size or
// throws std::invalid_argument / cv::Exception. OpenCV and libpng are not
// instrumented, so coverage feedback stops at DecodeLiveImage: this target
// catches crashes and memory errors, it does not explore libpng in depth.
#include "core/stereo_camera.hpp"
#include "fuzz/fuzz_support.hpp"
#include "pipeline/live_frame_source.hpp"

#include <opencv2/core.hpp>

#include <exception>
#include <typeinfo>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  // First byte: bit 0 selects PNG vs raw GRAY8. PNG: bit 1 picks the camera
  // size, 1392x512 (KITTI extract frames, the real seeds) or 64x48 (small
  // seeds). Raw: bits 1-7 pick a small size so inputs of matching length occur.
  const bool png = (data[0] & 1) != 0;
  locaid::StereoCamera camera;
  if (png) {
    const bool kitti_size = (data[0] & 2) != 0;
    camera.width = kitti_size ? 1392 : 64;
    camera.height = kitti_size ? 512 : 48;
  } else {
    camera.width = 1 + ((data[0] >> 1) & 0x0f) * 8;
    camera.height = 1 + ((data[0] >> 5) & 0x07) * 4;
  }
  const std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    const cv::Mat image = locaid::pipeline::DecodeLiveImage(bytes, png, camera, "left");
    LOCAID_FUZZ_CHECK(image.type() == CV_8UC1, "decoded image is not CV_8UC1");
    LOCAID_FUZZ_CHECK(image.cols == camera.width && image.rows == camera.height,
                      "decoded image has the wrong size");
  } catch (const std::invalid_argument&) {
  } catch (const cv::Exception&) {
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("DecodeLiveImage threw ") + typeid(e).name() + ": " + e.what());
  }
  return 0;
}
