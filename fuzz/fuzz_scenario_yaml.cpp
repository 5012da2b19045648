// libFuzzer target: scenario YAML (pipeline/scenario_yaml.hpp), every key
// it reads today: name, base (the built-ins), gps.{rate_hz, sigma_h_m,
// sigma_v_m, bias_sigma_m, bias_tau_s, jump_probability, jump_size_m,
// jump_duration_s, antenna_body_m, measured, stated_sigma_scale}, imu.{grade,
// accel_bias_sigma_mps2, gyro_bias_sigma_radps, accel_noise_mps2_sqrt_hz,
// gyro_noise_radps_sqrt_hz}, outages[].{start_s, duration_s, end_s,
// centered}, camera[].{start_s, duration_s, end_s, fault, gain, noise_dn,
// blur_sigma_px}, speed.{rate_hz, sigma_mps, scale_error}, seed.
// Contract: ParseScenarioYaml returns a scenario or throws
// pipeline::ScenarioError (no yaml-cpp or std exception escapes); an accepted
// scenario passes sim::ValidateScenario, its outages placed on a drive
// (PlaceOutagesForDrive) and it drives a GpsReceiverSim (with an attitude, so the
// antenna lever arm is used) and an ImuDegrader over a short synthetic drive
// without undefined behaviour, every fix, sample and speed reading finite
// (readings in time order, within the drive); its camera faults
// go through a CameraFaultStage over small stereo pairs of the same drive,
// each image coming out empty or of its size and type.
#include "fuzz/fuzz_support.hpp"
#include "sim/scenario.hpp"
#include "pipeline/camera_faults.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <exception>
#include <typeinfo>

namespace {

constexpr int kSamples = 200;
constexpr int64_t kStepNs = 100'000'000;  // 10 Hz OXTS: a 20 s drive
constexpr double kDriveS = 20.0;
constexpr int64_t kStartNs = 1'317'000'000'000'000'000;

void Exercise(const locaid::sim::Scenario& scenario) {
  namespace fusion = locaid::fusion;
  namespace sim = locaid::sim;
  sim::ValidateScenario(scenario);
  const sim::Scenario placed = sim::PlaceOutagesForDrive(scenario, kDriveS);
  for (const sim::OutageWindow& o : placed.outages) {
    LOCAID_FUZZ_CHECK(!o.centered && std::isfinite(o.start_s) && o.start_s >= 0, "outage not placed");
  }
  sim::GpsReceiverSim gps(placed);
  sim::ImuDegrader imu(placed);
  sim::SpeedSimulator speed(placed);
  int64_t last_reading_ns = 0;
  const Eigen::Matrix3d R_enu_body = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int i = 0; i < kSamples; ++i) {
    const int64_t t_ns = kStartNs + i * kStepNs;
    if (const auto fix = gps.Apply(t_ns, 49.0 + 1e-6 * i, 8.4, 110.0, &R_enu_body)) {
      LOCAID_FUZZ_CHECK(fix->t_ns == t_ns, "fix time changed");
      LOCAID_FUZZ_CHECK(std::isfinite(fix->lat_deg) && std::isfinite(fix->lon_deg) && std::isfinite(fix->alt_m),
                        "non-finite degraded fix");
      LOCAID_FUZZ_CHECK(std::isfinite(fix->sigma_h_m) && fix->sigma_h_m >= 0 && std::isfinite(fix->sigma_v_m) &&
                            fix->sigma_v_m >= 0,
                        "bad sigma on a degraded fix");
    }
    (void)gps.InOutage(t_ns);
    fusion::ImuSample sample;
    sample.t_ns = t_ns;
    sample.accel_mps2 = Eigen::Vector3d(0.1, 0.0, 9.81);
    sample.gyro_radps = Eigen::Vector3d(0.0, 0.0, 0.01);
    const fusion::ImuSample degraded = imu.Apply(sample);
    LOCAID_FUZZ_CHECK(degraded.accel_mps2.allFinite() && degraded.gyro_radps.allFinite(),
                      "non-finite degraded IMU sample");
    for (const fusion::SpeedSample& r : speed.Apply(t_ns, 10.0 + 0.05 * i)) {
      LOCAID_FUZZ_CHECK(std::isfinite(r.speed_mps) && std::isfinite(r.sigma_mps) && r.sigma_mps >= 0,
                        "non-finite simulated speed reading");
      LOCAID_FUZZ_CHECK(r.t_ns > last_reading_ns && r.t_ns <= t_ns && r.t_ns >= kStartNs,
                        "speed reading out of order or outside the drive");
      last_reading_ns = r.t_ns;
    }
  }
  // Camera faults over 20 s of 10 Hz frames (images small: a blur of 50 px
  // sigma is a 301 px kernel on them).
  locaid::pipeline::CameraFaultStage camera(placed);
  const cv::Mat left(8, 16, CV_8UC1, cv::Scalar(100)), right(8, 16, CV_8UC1, cv::Scalar(120));
  for (int i = 0; i < kSamples; ++i) {
    locaid::vo::StereoFrame frame{kStartNs + i * kStepNs, left, right};
    camera.Apply(frame);
    for (const cv::Mat* image : {&frame.left, &frame.right})
      LOCAID_FUZZ_CHECK(image->empty() || (image->size() == left.size() && image->type() == CV_8UC1),
                        "camera fault changed an image's size or type");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  locaid::sim::Scenario scenario;
  try {
    scenario = locaid::pipeline::ParseScenarioYaml(text, "fuzz.yaml");
  } catch (const locaid::pipeline::ScenarioError&) {
    return 0;
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("ParseScenarioYaml threw ") + typeid(e).name() + ": " + e.what());
  }
  try {
    Exercise(scenario);
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("accepted scenario fails: ") + typeid(e).name() + ": " + e.what());
  }
  return 0;
}
