// What a real receiver adds to a fix (issue 20): fixes that arrive late, a
// full covariance instead of sigmas, 2-D fixes without altitude, and velocity.
#include "fusion/ekf.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <functional>

namespace locaid::fusion {
namespace {

struct Errors {
  double rmse_h_m = 0, rmse_v_m = 0, rmse_vel_mps = 0, max_v_m = 0;
  int rejected = 0, rejected_vertical = 0;
};

EkfConfig SimEkfConfig(const test::SimConfig& c) {
  EkfConfig config;
  config.imu.accel_noise_mps2_sqrt_hz = c.accel_noise;
  config.imu.gyro_noise_radps_sqrt_hz = c.gyro_noise;
  return config;
}

// Runs the simulated drive; `shape` edits each fix, and each fix reaches the
// filter `delay_s` after its time stamp (after the IMU samples of that span,
// as a live receiver's fixes do).
Errors RunDrive(const test::SimConfig& c, double delay_s, const std::function<void(GpsFix&, const test::SimEvent&)>& shape) {
  Ekf ekf(SimEkfConfig(c));
  std::deque<GpsFix> waiting;
  const auto delay_ns = static_cast<int64_t>(delay_s * 1e9);
  double sum_h = 0, sum_v = 0, sum_vel = 0, max_v = 0;
  int n = 0;
  for (const auto& e : test::Simulate(c)) {
    const int64_t now_ns = e.kind == test::SimEvent::kImu ? e.imu.t_ns : e.kind == test::SimEvent::kGps ? e.gps.t_ns : e.vo.t_ns;
    while (!waiting.empty() && waiting.front().t_ns + delay_ns <= now_ns) {
      ekf.UpdateGps(waiting.front());
      waiting.pop_front();
    }
    if (e.kind == test::SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
    } else if (e.kind == test::SimEvent::kGps) {
      GpsFix fix = e.gps;
      shape(fix, e);
      if (delay_ns == 0) ekf.UpdateGps(fix);
      else waiting.push_back(fix);
    } else if (e.vo.t_ns > 0) {
      ekf.ProcessVo(e.vo, true);
      if (!ekf.initialized() || e.truth.t_ns < 20'000'000'000LL) continue;
      const FusedPose pose = ekf.Output(e.vo.t_ns, true);
      const Vec3 err = pose.T_enu_body.translation() - test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m);
      sum_h += err.head<2>().squaredNorm();
      sum_v += err.z() * err.z();
      max_v = std::max(max_v, std::abs(err.z()));
      sum_vel += (pose.v_enu_mps - e.truth.x.v_enu_mps).squaredNorm();
      ++n;
    }
  }
  Errors out;
  out.rmse_h_m = std::sqrt(sum_h / std::max(1, n));
  out.rmse_v_m = std::sqrt(sum_v / std::max(1, n));
  out.rmse_vel_mps = std::sqrt(sum_vel / std::max(1, n));
  out.max_v_m = max_v;
  out.rejected = ekf.stats().gps_rejected;
  out.rejected_vertical = ekf.stats().gps_rejected_vertical;
  return out;
}

test::SimConfig TenHzGps() {
  test::SimConfig c;
  c.duration_s = 90;
  c.gps_rate_hz = 10;
  c.gps_sigma_h_m = 0.5;
  c.gps_sigma_v_m = 1.0;
  c.seed = 4;
  return c;
}

void AsIs(GpsFix&, const test::SimEvent&) {}

TEST(GpsTypedFix, LateFixesAreComparedWithWhereTheAntennaWasThen) {
  // 0.3 s late at ~10 m/s is 3 m: without the latency model each late fix
  // would pull the state back along the track.
  const test::SimConfig c = TenHzGps();
  const Errors on_time = RunDrive(c, 0.0, AsIs), late = RunDrive(c, 0.3, AsIs);
  std::printf("[late fixes] horizontal RMSE on time %.3f m, 0.3 s late %.3f m; rejected %d / %d\n", on_time.rmse_h_m,
              late.rmse_h_m, on_time.rejected, late.rejected);
  EXPECT_LT(late.rmse_h_m, 1.5 * on_time.rmse_h_m + 0.05);
  EXPECT_LE(late.rejected, on_time.rejected + 5);
}

TEST(GpsTypedFix, ACovarianceMatrixActsAsTheSigmasItHolds) {
  const test::SimConfig c = TenHzGps();
  const Errors sigmas = RunDrive(c, 0.0, AsIs);
  const Errors matrix = RunDrive(c, 0.0, [](GpsFix& f, const test::SimEvent&) {
    f.cov_enu_m2 = Vec3(f.sigma_h_m * f.sigma_h_m, f.sigma_h_m * f.sigma_h_m, f.sigma_v_m * f.sigma_v_m).asDiagonal();
    f.sigma_h_m = f.sigma_v_m = 1000;  // ignored when the matrix is there
  });
  EXPECT_NEAR(matrix.rmse_h_m, sigmas.rmse_h_m, 1e-9);
  EXPECT_NEAR(matrix.rmse_v_m, sigmas.rmse_v_m, 1e-9);
}

TEST(GpsTypedFix, ABadCovarianceOrVelocityIsRefusedBeforeItSetsAnything) {
  Ekf ekf;
  GpsFix fix;
  fix.t_ns = 1'000'000'000;
  fix.lat_deg = 49;
  fix.lon_deg = 8;
  fix.cov_enu_m2 = Mat3::Identity();
  (*fix.cov_enu_m2)(0, 0) = -1;  // not positive definite
  EXPECT_TRUE(ekf.UpdateGps(fix).rejected);
  fix.cov_enu_m2 = Mat3::Identity();
  (*fix.cov_enu_m2)(0, 1) = 0.5;  // not symmetric
  EXPECT_TRUE(ekf.UpdateGps(fix).rejected);
  fix.cov_enu_m2.reset();
  fix.v_enu_mps = Vec3(1, NAN, 0);
  EXPECT_TRUE(ekf.UpdateGps(fix).rejected);
  EXPECT_EQ(ekf.stats().gps_rejected, 3);
  EXPECT_FALSE(ekf.enu().has_origin());
}

TEST(GpsTypedFix, TwoDFixesLeaveTheAltitudeAlone) {
  // A 2-D fix's altitude is whatever the receiver last had: here 80 m off.
  // Fused it would drag the track up (or be rejected); it must be neither.
  const test::SimConfig c = TenHzGps();
  const Errors e = RunDrive(c, 0.0, [](GpsFix& f, const test::SimEvent& ev) {
    if (ev.truth.t_ns < 5'000'000'000LL) return;  // a 3-D start sets the altitude
    f.has_altitude = false;
    f.alt_m += 80;
  });
  std::printf("[2-D fixes] vertical RMSE %.3f m, max %.3f m, vertical rejections %d\n", e.rmse_v_m, e.max_v_m,
              e.rejected_vertical);
  EXPECT_EQ(e.rejected_vertical, 0);
  EXPECT_LT(e.max_v_m, 10.0);
}

TEST(GpsTypedFix, ReceiverVelocityTightensTheVelocityEstimate) {
  test::SimConfig c = TenHzGps();
  c.gps_rate_hz = 1;
  c.gps_sigma_h_m = 3.0;
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n01;
  const Errors without = RunDrive(c, 0.0, AsIs);
  const Errors with = RunDrive(c, 0.0, [&](GpsFix& f, const test::SimEvent& ev) {
    f.v_enu_mps = ev.truth.x.v_enu_mps + 0.05 * Vec3(n01(rng), n01(rng), n01(rng));
    f.sigma_v_enu_mps = 0.05;
  });
  std::printf("[gps velocity] velocity RMSE %.4f m/s without, %.4f m/s with\n", without.rmse_vel_mps,
              with.rmse_vel_mps);
  EXPECT_LT(with.rmse_vel_mps, 0.8 * without.rmse_vel_mps);
}

}  // namespace
}  // namespace locaid::fusion
