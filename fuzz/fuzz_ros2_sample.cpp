// libFuzzer target: DDS samples into locaid-ros2 --inputs (ros2/input_setup,
// ros2/input_assembler): the input is a sequence of records [role byte]
// [uint16 little-endian size][size bytes], each a message arriving on the
// topic of that role (left/right image, left/right camera_info, IMU, fix,
// speed, /tf_static) 7 ms after the previous one.
// Contract: the setup reads its first messages without throwing (a bad one
// is skipped), then every record goes through InputAssembler::Add, Tick and
// finally Flush without throwing; what comes out is in the session's terms:
// frames GRAY8 of the rectified camera's size, IMU samples and speeds
// finite, fixes either no-fix or a position in range with finite sigmas or
// a 3x3 covariance; each topic's counters add up (used + dropped <= received).
#include "fuzz/fuzz_support.hpp"
#include "ros2/input_assembler.hpp"
#include "ros2/input_setup.hpp"
#include "ros/camera_model.hpp"

#include <cmath>
#include <exception>
#include <typeinfo>

namespace {

using locaid::ros2::InputRole;

constexpr int kW = 16, kH = 12;

// A 16x12 camera_info (no distortion) of the left or the right camera.
locaid::ros::CameraInfo Camera(double tx) {
  locaid::ros::CameraInfo c;
  c.width = kW;
  c.height = kH;
  c.k = {10, 0, 8, 0, 10, 6, 0, 0, 1};
  c.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.p = {10, 0, 8, tx, 0, 10, 6, 0, 0, 0, 1, 0};
  return c;
}

// The rig of a 16x12 stereo pair and its topics, as locaid-ros2 has them
// once set up (no IMU: the body is the camera turned x forward).
struct Car {
  Car() {
    rig.left_info = Camera(0);
    rig.right_info = Camera(-5);
    rig.rectified = std::make_shared<locaid::ros::RectifiedStereo>(
        locaid::ros::MakeRectifiedStereo(rig.left_info, rig.right_info));
    const char* names[] = {"/l/image_raw", "/r/image_raw", "/l/info", "/r/info", "", "/fix", "/speed", "/tf_static"};
    const std::string_view types[] = {locaid::ros::kImage,     locaid::ros::kImage,     locaid::ros::kCameraInfo,
                                      locaid::ros::kCameraInfo, "",                      locaid::ros::kNavSatFix,
                                      locaid::ros::kTwistStamped, locaid::ros::kTfMessage};
    for (size_t i = 0; i < locaid::ros2::kInputRoleCount; ++i) {
      topics.topic[i] = names[i];
      topics.type[i] = std::string(types[i]);
    }
  }
  locaid::ros2::InputTopics topics;
  locaid::ros2::InputRig rig;
};

void CheckOut(const std::vector<locaid::v1::PushRequest>& out, const locaid::StereoCamera& camera) {
  for (const auto& r : out) {
    if (r.has_frame()) {
      const size_t bytes = static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height);
      LOCAID_FUZZ_CHECK(r.frame().encoding() == locaid::v1::IMAGE_ENCODING_GRAY8, "frame not GRAY8");
      LOCAID_FUZZ_CHECK(r.frame().left().size() == bytes && r.frame().right().size() == bytes,
                        "frame not of the rectified camera's size");
    } else if (r.has_imu()) {
      const auto& a = r.imu().accel_mps2();
      const auto& g = r.imu().gyro_radps();
      LOCAID_FUZZ_CHECK(std::isfinite(a.x() + a.y() + a.z() + g.x() + g.y() + g.z()), "non-finite IMU sample sent");
    } else if (r.has_speed()) {
      LOCAID_FUZZ_CHECK(std::isfinite(r.speed().speed_mps()), "non-finite speed sent");
    } else if (r.has_gps()) {
      const auto& f = r.gps();
      if (f.fix_type() == locaid::v1::GPS_FIX_NONE) continue;
      LOCAID_FUZZ_CHECK(std::abs(f.latitude_deg()) <= 90 && std::abs(f.longitude_deg()) <= 180 &&
                            std::isfinite(f.altitude_m()),
                        "fix position out of range");
      LOCAID_FUZZ_CHECK(f.covariance_enu_m2_size() == 0 || f.covariance_enu_m2_size() == 9, "covariance size");
      LOCAID_FUZZ_CHECK(std::isfinite(f.sigma_horizontal_m()) && std::isfinite(f.sigma_vertical_m()),
                        "non-finite fix sigma");
    } else {
      locaid::fuzz::Fail("an empty push request");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const Car car;
  static constexpr InputRole kRoles[] = {InputRole::kLeftImage, InputRole::kRightImage, InputRole::kLeftInfo,
                                         InputRole::kRightInfo, InputRole::kImu,        InputRole::kGps,
                                         InputRole::kSpeed,     InputRole::kTfStatic};
  try {
    // The setup's own reading of first messages (camera_info, tf, frame ids).
    locaid::ros2::InputSetup setup({"/l/image_raw", "/l/info", "/r/image_raw", "/r/info", "/imu", "/fix", "/speed"},
                                   {0, 1});
    locaid::ros2::InputAssembler assembler(car.topics, car.rig, {});
    std::vector<locaid::v1::PushRequest> out;
    auto now = locaid::ros2::InputClock::now();
    size_t at = 0;
    while (at + 3 <= size) {
      const InputRole role = kRoles[data[at] % 8];  // the IMU role reaches the setup only (the car has none)
      const size_t n = std::min<size_t>(data[at + 1] | (size_t{data[at + 2]} << 8), size - at - 3);
      const std::string_view cdr(reinterpret_cast<const char*>(data + at + 3), n);
      at += 3 + n;
      setup.AddMessage(role == InputRole::kImu ? "/imu" : car.topics.topic_of(role), cdr);
      now += std::chrono::milliseconds(7);
      assembler.Add(role, cdr, now, out);
      if (at % 5 == 0) assembler.Tick(now, out);
    }
    assembler.Flush(out);
    CheckOut(out, car.rig.rectified->camera);
    for (const auto& [role, s] : assembler.stats(now)) {
      // Each message is used or dropped for one reason, or still held (never both).
      LOCAID_FUZZ_CHECK(s.used + s.undecodable + s.late + s.bad + s.unpaired <= s.received,
                        "counters do not add up");
    }
    (void)assembler.Health(now);
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("a DDS sample threw ") + typeid(e).name() + ": " + e.what());
  }
  return 0;
}
