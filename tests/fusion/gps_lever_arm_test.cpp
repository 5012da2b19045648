// The GPS antenna's lever arm in the filter's GPS model (issue 20).
#include "fusion/ekf.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace locaid::fusion {
namespace {

// Issue 20: a receiver 1.5 m from the IMU. The simulated fixes are of the
// antenna (p + R lever); a filter told where the antenna is tracks the IMU,
// one that is not is biased by up to 1.5 m, turning with the car.
double LeverArmRmse(bool use_imu, bool modelled) {
  test::SimConfig c;
  c.duration_s = 120;
  c.gps_rate_hz = 10;
  c.gps_sigma_h_m = 1.5;
  c.gps_sigma_v_m = 3.0;
  c.seed = 6;
  const Vec3 lever(1.2, 0.9, 0.0);
  EkfConfig config;
  config.imu.enabled = use_imu;
  config.imu.accel_noise_mps2_sqrt_hz = c.accel_noise;
  config.imu.gyro_noise_radps_sqrt_hz = c.gyro_noise;
  if (modelled) config.gps.lever_arm_body_m = lever;
  Ekf ekf(config);
  EnuFrame geo;
  geo.SetOrigin(test::kLat0, test::kLon0, test::kAlt0);
  double sum2 = 0;
  int n = 0;
  for (const auto& e : test::Simulate(c)) {
    if (e.kind == test::SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
    } else if (e.kind == test::SimEvent::kGps) {
      GpsFix fix = e.gps;
      const Vec3 antenna = geo.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m) + e.truth.x.R_enu_body * lever;
      geo.ToGeodetic(antenna, fix.lat_deg, fix.lon_deg, fix.alt_m);
      ekf.UpdateGps(fix);
    } else if (e.vo.t_ns > 0) {
      ekf.ProcessVo(e.vo, true);
      if (!ekf.initialized() || e.truth.t_ns < 20'000'000'000LL) continue;  // after the start-up transient
      const Vec3 err = ekf.Output(e.vo.t_ns, true).T_enu_body.translation() -
                       test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m);
      sum2 += err.head<2>().squaredNorm();
      ++n;
    }
  }
  return std::sqrt(sum2 / std::max(1, n));
}

class GpsLeverArm : public ::testing::TestWithParam<bool> {};

TEST_P(GpsLeverArm, ModelledLeverArmRemovesTheTurningBias) {
  const double without = LeverArmRmse(GetParam(), false), with = LeverArmRmse(GetParam(), true);
  std::printf("[lever arm] %s: horizontal RMSE %.3f m unmodelled, %.3f m modelled (%.2fx)\n",
              GetParam() ? "IMU" : "no IMU", without, with, with / without);
  EXPECT_LT(with, 0.7 * without);
}

INSTANTIATE_TEST_SUITE_P(ImuAndNoImu, GpsLeverArm, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Imu" : "NoImu"; });

}  // namespace
}  // namespace locaid::fusion
