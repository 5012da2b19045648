// Scenario files (YAML) for locaid-replay and the server.
//
//   name: my-scenario            # optional (default: file stem)
//   base: urban-canyon           # optional built-in to start from
//   gps: {rate_hz: 1, sigma_h_m: 3, sigma_v_m: 5, bias_sigma_m: 0.3,
//         bias_tau_s: 60, jump_probability: 0.02, jump_size_m: 15,
//         jump_duration_s: 0, stated_sigma_scale: 1}
//     # stated_sigma_scale (0, 100]: the receiver states this multiple of
//     # its sigma (1/3: claims 1 m, delivers 3 m); antenna_body_m [x, y, z]
//     # and measured: as-recorded | degraded (sim/scenario.hpp)
//   imu: {grade: as-recorded | mems, accel_bias_sigma_mps2: 0.05,
//         gyro_bias_sigma_radps: 0.002, accel_noise_mps2_sqrt_hz: 0.01,
//         gyro_noise_radps_sqrt_hz: 0.0005}
//   outages: [{start_s: 20, duration_s: 10}, {start_s: 60, end_s: 75}]
//   camera: [{start_s: 20, duration_s: 10, fault: dark, gain: 0.06, noise_dn: 3},
//            {start_s: 40, end_s: 50, fault: frozen}]
//     # faults on the images before VO (pipeline/camera_faults.hpp), times
//     # from the first frame: dark {gain (0, 1], default 0.06; noise_dn
//     # [0, 255], default 3}, noise {noise_dn, default 8}, blur
//     # {blur_sigma_px (0, 50], default 3}, frozen, drop, left_only,
//     # right_only; a parameter of another fault is an unknown key
//   speed: {rate_hz: 50, sigma_mps: 0.05, scale_error: 0.005}
//     # a simulated vehicle speed sensor from the drive's true forward
//     # speed (reads 0.5 % high here, like a worn tyre); no key: none
//   seed: 7
#pragma once

#include "sim/scenario.hpp"

#include <stdexcept>
#include <string>

namespace locaid::pipeline {

class ScenarioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A built-in name (sim::BuiltinScenarioNames()) or a path to a YAML file.
// Throws ScenarioError "FILE:LINE: field 'gps.sigma_h_m': must be >= 0, got -1"
// (unknown key, wrong type, out-of-range value, outage end before start ...).
sim::Scenario LoadScenario(const std::string& name_or_path);
sim::Scenario ParseScenarioYaml(const std::string& text, const std::string& where);

}  // namespace locaid::pipeline
