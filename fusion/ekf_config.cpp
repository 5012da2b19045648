#include "fusion/ekf_config.hpp"

namespace locaid::fusion {

std::vector<EkfSetting> NumericEkfSettings(EkfConfig& c) {
  return {
      {"imu.gravity_mps2", "gravity_mps2", &c.imu.gravity_mps2},
      {"imu.accel_noise_mps2_sqrt_hz", "accel_noise_mps2_sqrt_hz", &c.imu.accel_noise_mps2_sqrt_hz},
      {"imu.gyro_noise_radps_sqrt_hz", "gyro_noise_radps_sqrt_hz", &c.imu.gyro_noise_radps_sqrt_hz},
      {"imu.accel_bias_walk_mps3_sqrt_hz", "accel_bias_walk_mps3_sqrt_hz", &c.imu.accel_bias_walk_mps3_sqrt_hz},
      {"imu.gyro_bias_walk_radps2_sqrt_hz", "gyro_bias_walk_radps2_sqrt_hz", &c.imu.gyro_bias_walk_radps2_sqrt_hz},
      {"imu.max_gap_s", "max_imu_gap_s", &c.imu.max_gap_s},
      {"gps.gate_probability", "gps_gate_probability", &c.gps.gate_probability},
      {"gps.lever_arm_x_m", "gps_lever_arm_x_m", &c.gps.lever_arm_body_m.x()},
      {"gps.lever_arm_y_m", "gps_lever_arm_y_m", &c.gps.lever_arm_body_m.y()},
      {"gps.lever_arm_z_m", "gps_lever_arm_z_m", &c.gps.lever_arm_body_m.z()},
      {"gps.latency_s", "gps_latency_s", &c.gps.latency_s},
      {"gps.noise_prior_fixes", "gps_noise_prior_fixes", &c.gps.noise_prior_fixes},
      {"gps.noise_window_fixes", "gps_noise_window_fixes", &c.gps.noise_window_fixes},
      {"gps.noise_scale_min", "gps_noise_scale_min", &c.gps.noise_scale_min},
      {"gps.noise_scale_max", "gps_noise_scale_max", &c.gps.noise_scale_max},
      {"gps.degraded_hold_s", "degraded_hold_s", &c.gps.degraded_hold_s},
      {"gps.vo_only_after_periods", "vo_only_after_periods", &c.gps.vo_only_after_periods},
      {"vo.cov_scale", "vo_cov_scale", &c.vo.cov_scale},
      {"vo.sigma_t_per_m", "vo_sigma_t_per_m", &c.vo.sigma_t_per_m},
      {"vo.sigma_lateral_per_m", "vo_sigma_lateral_per_m", &c.vo.sigma_lateral_per_m},
      {"vo.sigma_vertical_per_m", "vo_sigma_vertical_per_m", &c.vo.sigma_vertical_per_m},
      {"vo.min_sigma_t_m", "vo_min_sigma_t_m", &c.vo.min_sigma_t_m},
      {"vo.min_sigma_rot_rad", "vo_min_sigma_rot_rad", &c.vo.min_sigma_rot_rad},
      {"vo.gate_probability", "vo_gate_probability", &c.vo.gate_probability},
      {"vo.boresight_sigma_rad", "vo_boresight_sigma_rad", &c.vo.boresight_sigma_rad},
      {"vo.scale_sigma", "vo_scale_sigma", &c.vo.scale_sigma},
      {"vo.lost_sigma_no_imu_mps", "no_imu_lost_sigma_mps", &c.vo.lost_sigma_no_imu_mps},
      {"vo.noise_prior_frames", "vo_noise_prior_frames", &c.vo.noise_prior_frames},
      {"vo.noise_window_frames", "vo_noise_window_frames", &c.vo.noise_window_frames},
      {"vo.noise_scale_min", "vo_noise_scale_min", &c.vo.noise_scale_min},
      {"vo.noise_scale_max", "vo_noise_scale_max", &c.vo.noise_scale_max},
      {"vo.noise_rotation_scale_max", "vo_noise_rotation_scale_max", &c.vo.noise_rotation_scale_max},
      {"vo.adaptive_rotation_noise_max_scale", "adaptive_vo_rotation_noise_max_scale",
       &c.vo.adaptive_rotation_noise_max_scale},
      {"vehicle.nhc_sigma_lateral_mps", "nhc_sigma_lateral_mps", &c.vehicle.nhc_sigma_lateral_mps},
      {"vehicle.nhc_sigma_vertical_mps", "nhc_sigma_vertical_mps", &c.vehicle.nhc_sigma_vertical_mps},
      {"vehicle.zupt_speed_mps", "zupt_speed_mps", &c.vehicle.zupt_speed_mps},
      {"vehicle.zupt_sigma_mps", "zupt_sigma_mps", &c.vehicle.zupt_sigma_mps},
      {"vehicle.zupt_window_s", "zupt_window_s", &c.vehicle.zupt_window_s},
      {"vehicle.zupt_gyro_radps", "zupt_gyro_radps", &c.vehicle.zupt_gyro_radps},
      {"vehicle.zupt_accel_mps2", "zupt_accel_mps2", &c.vehicle.zupt_accel_mps2},
      {"vehicle.zupt_max_estimated_speed_mps", "zupt_max_estimated_speed_mps", &c.vehicle.zupt_max_estimated_speed_mps},
      {"vehicle.speed_sigma_mps", "speed_sigma_mps", &c.vehicle.speed_sigma_mps},
      {"vehicle.speed_scale_sigma", "speed_scale_sigma", &c.vehicle.speed_scale_sigma},
      {"vehicle.speed_gate_probability", "speed_gate_probability", &c.vehicle.speed_gate_probability},
      {"startup.min_baseline_m", "init_min_baseline_m", &c.startup.min_baseline_m},
      {"startup.min_baseline_sigmas", "init_min_baseline_sigmas", &c.startup.min_baseline_sigmas},
      {"startup.cov_inflation", "init_cov_inflation", &c.startup.cov_inflation},
      {"startup.velocity_sigma_mps", "init_velocity_sigma_mps", &c.startup.velocity_sigma_mps},
      {"startup.roll_pitch_sigma_rad", "init_roll_pitch_sigma_rad", &c.startup.roll_pitch_sigma_rad},
      {"startup.accel_bias_sigma_mps2", "init_accel_bias_sigma_mps2", &c.startup.accel_bias_sigma_mps2},
      {"startup.gyro_bias_sigma_radps", "init_gyro_bias_sigma_radps", &c.startup.gyro_bias_sigma_radps},
  };
}

double* FindEkfSetting(EkfConfig& config, std::string_view name) {
  for (const auto& s : NumericEkfSettings(config)) {
    if (s.name == name || s.flat_name == name) return s.value;
  }
  return nullptr;
}

}  // namespace locaid::fusion
