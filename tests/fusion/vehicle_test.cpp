// The EKF's vehicle measurements (fusion/ekf_vehicle.cpp) on simulated drives:
// the speed sensor's scale factor, standstill (ZUPT), bad speed readings, the
// DEAD_RECKONING / LOST / VO_ONLY modes, the non-holonomic constraints, and
// the IMU stillness detector.
#include "fusion/ekf.hpp"
#include "fusion/imu_stillness.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

namespace locaid::fusion {
namespace {

using test::SimConfig;
using test::SimEvent;
using test::Simulate;

constexpr double kG = 9.81;
constexpr int64_t kNsPerS = 1'000'000'000;

EkfConfig ConfigFor(const SimConfig& c) { return test::SimEkfConfig(c, /*use_imu=*/true); }

double ForwardSpeed(const NominalState& x) { return (x.R_enu_body.transpose() * x.v_enu_mps).x(); }

// Feeds sim.hpp events to the filter with a speed reading (from the truth's
// forward speed, `reading` maps it) at every other IMU sample (50 Hz);
// `vo_ok` says per event whether VO works; `use_gps` whether fixes are fused;
// `after_frame` sees each frame once the filter is initialised.
struct DriveHooks {
  std::function<std::optional<SpeedSample>(const SimEvent&)> reading;
  std::function<bool(const SimEvent&)> vo_ok = [](const SimEvent&) { return true; };
  std::function<void(const SimEvent&, const FusedPose&)> after_frame;
};

void Drive(Ekf& ekf, const std::vector<SimEvent>& ev, const DriveHooks& h) {
  int imu_count = 0;
  for (const SimEvent& e : ev) {
    if (e.kind == SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
      if (h.reading && (imu_count++ % 2 == 0))
        if (const auto r = h.reading(e)) ekf.UpdateSpeed(*r);
    } else if (e.kind == SimEvent::kGps) {
      ekf.UpdateGps(e.gps);
    } else if (e.vo.t_ns > 0) {
      const bool ok = h.vo_ok(e);
      ekf.ProcessVo(e.vo, ok);
      const FusedPose pose = ekf.Output(e.vo.t_ns, ok);
      if (ekf.initialized() && h.after_frame) h.after_frame(e, pose);
    }
  }
}

TEST(VehicleSpeed, ScaleFactorConvergesWhileGpsIsGood) {
  constexpr double kScaleError = 0.005;  // reads 0.5 % high (a worn tyre)
  constexpr double kTolerance = 0.0015;
  constexpr double kSigma = 0.05;
  SimConfig c;
  c.duration_s = 60;
  c.seed = 7;
  const auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c));
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01;
  DriveHooks h;
  h.reading = [&](const SimEvent& e) -> std::optional<SpeedSample> {
    return SpeedSample{e.truth.t_ns, (1 + kScaleError) * ForwardSpeed(e.truth.x) + kSigma * n01(rng), kSigma};
  };
  Drive(ekf, ev, h);
  ASSERT_TRUE(ekf.initialized());
  EXPECT_NEAR(ekf.speed_scale_error(), kScaleError, kTolerance);
  std::cout << "speed scale error " << ekf.speed_scale_error() << " (true " << kScaleError << ")\n";
  EXPECT_GT(ekf.stats().speed_used, 2000) << "~50 Hz over ~50 s after initialisation";
  EXPECT_LT(ekf.stats().speed_rejected, ekf.stats().speed_used / 100);
  const FusedPose pose = ekf.Output(ev.back().truth.t_ns, true);
  EXPECT_EQ(pose.speed_used, ekf.stats().speed_used);
  EXPECT_DOUBLE_EQ(pose.speed_scale_error, ekf.speed_scale_error());
  EXPECT_TRUE(ekf.covariance().allFinite());
}

// A straight drive east-north-east at a speed profile v(t): IMU (noise only,
// no bias), GPS at 1 Hz, VO at 10 Hz; the truth's forward speed in
// SimEvent::truth (v_enu along the heading).
std::vector<SimEvent> StraightDrive(double duration_s, const std::function<double(double)>& v_of_t,
                                    const std::function<double(double)>& a_of_t, uint64_t seed) {
  const SimConfig c;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  EnuFrame geo;
  geo.SetOrigin(test::kLat0, test::kLon0, test::kAlt0);
  const double yaw = 0.7;
  const Mat3 R = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  const Vec3 dir = R.col(0);
  std::vector<SimEvent> ev;
  double s = 0;                  // distance along the heading
  double s_prev_frame = 0;
  int64_t t_prev_frame = 0;
  constexpr double kDt = 0.001;
  const int steps = static_cast<int>(duration_s / kDt);
  for (int k = 0; k <= steps; ++k) {
    const double t = k * kDt;
    const int64_t t_ns = static_cast<int64_t>(std::llround(t * 1e9));
    NominalState x;
    x.p_enu_m = s * dir;
    x.v_enu_mps = v_of_t(t) * dir;
    x.R_enu_body = R;
    const test::SimTruth truth{t_ns, x};
    if (k % 10 == 0) {  // IMU 100 Hz
      SimEvent e{SimEvent::kImu, {}, {}, {}, truth, false};
      e.imu.t_ns = t_ns;
      e.imu.accel_mps2 = Vec3(a_of_t(t), 0, kG);
      e.imu.gyro_radps = Vec3::Zero();
      for (int i = 0; i < 3; ++i) {
        e.imu.accel_mps2[i] += c.accel_noise / std::sqrt(0.01) * n01(rng);
        e.imu.gyro_radps[i] += c.gyro_noise / std::sqrt(0.01) * n01(rng);
      }
      ev.push_back(e);
    }
    if (k % 1000 == 0) {  // GPS 1 Hz
      SimEvent e{SimEvent::kGps, {}, {}, {}, truth, false};
      e.gps = test::NoisyFix(geo, c, t_ns, x.p_enu_m, rng, n01);
      ev.push_back(e);
    }
    if (k % 100 == 0) {  // frames 10 Hz
      SimEvent e{SimEvent::kFrame, {}, {}, {}, truth, false};
      e.vo.t_prev_ns = t_prev_frame;
      e.vo.t_ns = t_ns;
      e.vo.T_prev_curr = Eigen::Isometry3d::Identity();
      if (k > 0) e.vo.T_prev_curr.translation() = Vec3(s - s_prev_frame + c.vo_sigma_t_m * n01(rng), 0, 0);
      e.vo.covariance.setZero();
      e.vo.covariance.diagonal() << Vec3::Constant(c.vo_sigma_t_m * c.vo_sigma_t_m),
          Vec3::Constant(c.vo_sigma_rot_rad * c.vo_sigma_rot_rad);
      ev.push_back(e);
      s_prev_frame = s;
      t_prev_frame = t_ns;
    }
    s += v_of_t(t) * kDt + 0.5 * a_of_t(t) * kDt * kDt;
  }
  return ev;
}

TEST(VehicleSpeed, StandstillReadingsHoldTheVelocityAtZero) {
  // 10 m/s for 30 s, braking to 0 over 5 s, standing 20 s.
  constexpr double kCruiseS = 30, kBrakeS = 5, kStandS = 20, kV0 = 10;
  constexpr double kMaxStandstillSpeed = 0.05;
  auto v = [&](double t) { return t < kCruiseS ? kV0 : t < kCruiseS + kBrakeS ? kV0 * (1 - (t - kCruiseS) / kBrakeS) : 0.0; };
  auto a = [&](double t) { return t >= kCruiseS && t < kCruiseS + kBrakeS ? -kV0 / kBrakeS : 0.0; };
  const auto ev = StraightDrive(kCruiseS + kBrakeS + kStandS, v, a, 3);
  Ekf ekf(ConfigFor(SimConfig{}));
  DriveHooks h;
  h.reading = [&](const SimEvent& e) -> std::optional<SpeedSample> {
    return SpeedSample{e.truth.t_ns, ForwardSpeed(e.truth.x), 0.05};
  };
  // VO is lost while the car stands (a dark garage): the readings hold it.
  h.vo_ok = [&](const SimEvent& e) { return static_cast<double>(e.truth.t_ns) / kNsPerS < kCruiseS + kBrakeS; };
  int zupt_at_stop = -1;
  double worst_standstill_speed = 0;
  int standstill_frames = 0;
  h.after_frame = [&](const SimEvent& e, const FusedPose&) {
    const double t = static_cast<double>(e.truth.t_ns) / kNsPerS;
    if (t < kCruiseS + kBrakeS + 1) return;  // settled a second after stopping
    if (zupt_at_stop < 0) zupt_at_stop = ekf.stats().zupt_updates;
    worst_standstill_speed = std::max(worst_standstill_speed, ekf.state().v_enu_mps.norm());
    ++standstill_frames;
  };
  Drive(ekf, ev, h);
  ASSERT_TRUE(ekf.initialized());
  ASSERT_GT(standstill_frames, 150);
  EXPECT_GT(ekf.stats().zupt_updates, zupt_at_stop + 500) << "50 Hz zero readings over ~19 s";
  EXPECT_LT(worst_standstill_speed, kMaxStandstillSpeed);
  std::cout << "standstill: worst speed " << worst_standstill_speed << " m/s, zero-velocity updates "
            << ekf.stats().zupt_updates - zupt_at_stop << "\n";
  EXPECT_TRUE(ekf.state().v_enu_mps.allFinite());
}

// 10 m/s straight, GPS throughout.
std::vector<SimEvent> Cruise(double duration_s) {
  return StraightDrive(duration_s, [](double) { return 10.0; }, [](double) { return 0.0; }, 5);
}

TEST(VehicleSpeed, ReadingBeforeInitialisationIsNeitherUsedNorRejected) {
  Ekf ekf(ConfigFor(SimConfig{}));
  ASSERT_FALSE(ekf.initialized());
  const SpeedUpdate u = ekf.UpdateSpeed({1'000'000, 10.0, 0.05});
  EXPECT_FALSE(u.used);
  EXPECT_FALSE(u.rejected);
  const SpeedUpdate nan = ekf.UpdateSpeed({2'000'000, std::numeric_limits<double>::quiet_NaN(), 0.05});
  EXPECT_FALSE(nan.used);
  EXPECT_FALSE(nan.rejected) << "before initialisation nothing is judged";
  EXPECT_EQ(ekf.stats().speed_used, 0);
  EXPECT_EQ(ekf.stats().speed_rejected, 0);
}

TEST(VehicleSpeed, NonFiniteAndContradictingReadingsAreRejected) {
  const auto ev = Cruise(40);
  Ekf ekf(ConfigFor(SimConfig{}));
  DriveHooks h;
  h.reading = [](const SimEvent& e) -> std::optional<SpeedSample> {
    return SpeedSample{e.truth.t_ns, ForwardSpeed(e.truth.x), 0.05};
  };
  Drive(ekf, ev, h);
  ASSERT_TRUE(ekf.initialized());
  ASSERT_NEAR(ForwardSpeed(ekf.state()), 10.0, 0.2);
  const int64_t t_ns = ev.back().truth.t_ns;
  const int used = ekf.stats().speed_used, rejected = ekf.stats().speed_rejected;

  const SpeedUpdate nan = ekf.UpdateSpeed({t_ns + 1'000'000, std::numeric_limits<double>::quiet_NaN(), 0.05});
  EXPECT_TRUE(nan.rejected);
  EXPECT_FALSE(nan.used);
  EXPECT_EQ(ekf.stats().speed_rejected, rejected + 1);
  const SpeedUpdate inf = ekf.UpdateSpeed({t_ns + 2'000'000, std::numeric_limits<double>::infinity(), 0.05});
  EXPECT_TRUE(inf.rejected);
  EXPECT_EQ(ekf.stats().speed_rejected, rejected + 2);
  EXPECT_TRUE(ekf.state().v_enu_mps.allFinite());
  EXPECT_TRUE(ekf.state().p_enu_m.allFinite());
  EXPECT_TRUE(ekf.covariance().allFinite());

  // Reversing at 10 m/s while the filter (and the IMU) say +10 forward: gated.
  const NominalState before = ekf.state();
  const Eigen::MatrixXd P_before = ekf.covariance();
  const SpeedUpdate back = ekf.UpdateSpeed({t_ns + 3'000'000, -10.0, 0.05});
  EXPECT_TRUE(back.rejected);
  EXPECT_FALSE(back.used);
  EXPECT_GT(back.nis, ChiSquareQuantile(0.9999, 1)) << "refused by the 1-dof gate";
  EXPECT_EQ(ekf.stats().speed_rejected, rejected + 3);
  EXPECT_EQ(ekf.stats().speed_used, used);
  // Only the propagation over 2 ms may move the state, not the reading.
  EXPECT_LT((ekf.state().v_enu_mps - before.v_enu_mps).norm(), 0.01);
  EXPECT_NEAR(ForwardSpeed(ekf.state()), 10.0, 0.2);
  EXPECT_EQ(ekf.covariance().rows(), P_before.rows());
}

// sim.hpp's drive with GPS lost from outage_start_s to its end.
SimConfig OutageToTheEnd(double duration_s, double outage_start_s, uint64_t seed) {
  SimConfig c;
  c.duration_s = duration_s;
  c.outage_start_s = outage_start_s;
  c.outage_duration_s = duration_s;
  c.seed = seed;
  return c;
}

// Modes over an outage of GPS (from 40 s on) where VO is lost from 45 s on.
Mode LastModeInOutage(bool use_imu, bool vo_lost) {
  const SimConfig c = OutageToTheEnd(55, 40, 4);
  const auto ev = Simulate(c);
  EkfConfig config = ConfigFor(c);
  config.imu.enabled = use_imu;
  Ekf ekf(config);
  Mode last = Mode::kGpsFused;
  DriveHooks h;
  h.vo_ok = [&](const SimEvent& e) { return !(vo_lost && e.truth.t_ns > 45 * kNsPerS); };
  h.after_frame = [&](const SimEvent&, const FusedPose& pose) { last = pose.mode; };
  std::vector<SimEvent> feed;
  for (const SimEvent& e : ev)
    if (use_imu || e.kind != SimEvent::kImu) feed.push_back(e);
  Drive(ekf, feed, h);
  EXPECT_TRUE(ekf.initialized());
  return last;
}

TEST(VehicleModes, DeadReckoningLostAndVoOnly) {
  EXPECT_EQ(LastModeInOutage(/*use_imu=*/true, /*vo_lost=*/true), Mode::kDeadReckoning);
  EXPECT_STREQ(ToString(Mode::kDeadReckoning), "DEAD_RECKONING");
  EXPECT_EQ(LastModeInOutage(/*use_imu=*/false, /*vo_lost=*/true), Mode::kLost);
  EXPECT_EQ(LastModeInOutage(/*use_imu=*/true, /*vo_lost=*/false), Mode::kVoOnly);
  EXPECT_EQ(LastModeInOutage(/*use_imu=*/false, /*vo_lost=*/false), Mode::kVoOnly);
}

TEST(VehicleModes, DeadReckoningEndsWhenTheImuStops) {
  // IMU mode, no GPS and VO lost: DEAD_RECKONING while the samples come, LOST
  // once the newest is older than max_imu_gap_s.
  const SimConfig c = OutageToTheEnd(50, 40, 1);
  const auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c));
  DriveHooks h;
  h.vo_ok = [](const SimEvent& e) { return e.truth.t_ns <= 42 * kNsPerS; };
  Drive(ekf, ev, h);
  const int64_t t_end = ev.back().truth.t_ns;
  EXPECT_EQ(ekf.Output(t_end, false).mode, Mode::kDeadReckoning);
  const auto gap_ns = static_cast<int64_t>((ekf.config().imu.max_gap_s + 0.5) * kNsPerS);
  EXPECT_EQ(ekf.Output(t_end + gap_ns, false).mode, Mode::kLost);
}

// Worst |lateral body velocity| of the estimate over the frames with VO lost
// and no GPS, and the nhc_updates count, on sim.hpp's turning drive, with a
// speed sensor (the forward speed is measured; nothing measures the lateral
// speed but the constraints) or without one.
struct NhcRun {
  double worst_lateral_mps = 0;
  int frames = 0;
  int nhc_updates = 0;
  int nhc_updates_before_outage = -1;
};

NhcRun OutageWithVoLost(bool constraints, bool speed_sensor = true) {
  SimConfig c = OutageToTheEnd(70, 50, 21);
  c.gps_rate_hz = 10;
  c.gps_sigma_h_m = 1.5;
  const auto ev = Simulate(c);
  EkfConfig config = ConfigFor(c);
  config.vehicle.constraints = constraints;
  Ekf ekf(config);
  NhcRun run;
  DriveHooks h;
  // A car with a speed sensor (true forward speed); the cameras blind in the outage.
  if (speed_sensor)
    h.reading = [](const SimEvent& e) -> std::optional<SpeedSample> {
      return SpeedSample{e.truth.t_ns, ForwardSpeed(e.truth.x), 0.05};
    };
  h.vo_ok = [](const SimEvent& e) { return !e.in_outage; };
  h.after_frame = [&](const SimEvent& e, const FusedPose&) {
    if (!e.in_outage) {
      run.nhc_updates_before_outage = ekf.stats().nhc_updates;
      return;
    }
    const Vec3 v_body = ekf.state().R_enu_body.transpose() * ekf.state().v_enu_mps;
    run.worst_lateral_mps = std::max(run.worst_lateral_mps, std::abs(v_body.y()));
    ++run.frames;
  };
  Drive(ekf, ev, h);
  run.nhc_updates = ekf.stats().nhc_updates;
  return run;
}

TEST(VehicleConstraints, NhcHoldsTheLateralVelocityInAnOutage) {
  constexpr double kMaxLateralMps = 0.3;
  const NhcRun on = OutageWithVoLost(true);
  ASSERT_GT(on.frames, 150);
  EXPECT_LT(on.worst_lateral_mps, kMaxLateralMps);
  EXPECT_GT(on.nhc_updates, on.frames) << "every frame fuses the constraints, in the outage and before";
  const NhcRun off = OutageWithVoLost(false);
  EXPECT_EQ(off.nhc_updates, 0);
  EXPECT_LT(on.worst_lateral_mps, 0.5 * off.worst_lateral_mps) << "the constraints, not the drive, hold it";
  std::cout << "worst lateral velocity in the outage: NHC " << on.worst_lateral_mps << " m/s, none "
            << off.worst_lateral_mps << " m/s\n";
}

TEST(VehicleConstraints, WithoutASpeedSensorTheyHoldTheFramesVoCannotUse) {
  // By default (vehicle.constraints_need_speed) a car without a speed sensor
  // gets no constraint while VO tracks and one at every frame VO cannot use:
  // blind, the IMU alone would let the lateral velocity run. Until
  // 2026-11-29 they waited for a speed reading even then (real excerpt, blind
  // 10 s tunnel with a MEMS IMU, 20 seeds: 7.33 % median end error against
  // 3.26 %; docs/experiments/tunnel-experiments.md).
  ASSERT_TRUE(EkfConfig::Vehicle{}.constraints_need_speed);
  const NhcRun blind = OutageWithVoLost(true, /*speed_sensor=*/false);
  ASSERT_GT(blind.frames, 150);
  EXPECT_EQ(blind.nhc_updates_before_outage, 0) << "VO tracks before the outage: no constraint without speed";
  EXPECT_GE(blind.nhc_updates, blind.frames - 2) << "every blind frame fuses them";
  const NhcRun off = OutageWithVoLost(false, /*speed_sensor=*/false);
  EXPECT_EQ(off.nhc_updates, 0);
  EXPECT_LT(blind.worst_lateral_mps, 0.75 * off.worst_lateral_mps) << "the constraints, not the drive, hold it";
  std::cout << "no speed sensor, worst lateral velocity in the blind outage: NHC " << blind.worst_lateral_mps
            << " m/s, none " << off.worst_lateral_mps << " m/s\n";
}

// IMU samples at 100 Hz: a standing car (noise only) or a vibrating one.
ImuSample Sample(int i, double accel_wobble_mps2, double gyro_wobble_radps) {
  ImuSample s;
  s.t_ns = static_cast<int64_t>(i) * 10'000'000;
  const double phase = (i % 2 == 0) ? 1.0 : -1.0;
  s.accel_mps2 = Vec3(0.001 * std::sin(i), 0, kG + phase * accel_wobble_mps2);
  s.gyro_radps = Vec3(0, 0, phase * gyro_wobble_radps);
  return s;
}

TEST(ImuStillness, StillSamplesAreStillAndVibrationIsNot) {
  const StillnessThresholds t;  // 0.5 s, 0.01 rad/s, 0.1 m/s^2, 10 samples
  ImuStillness still;
  for (int i = 0; i < 100; ++i) still.Add(Sample(i, 0.0, 0.0), t.window_s);
  EXPECT_TRUE(still.Still(t));

  ImuStillness shaking;
  for (int i = 0; i < 100; ++i) shaking.Add(Sample(i, 0.5, 0.0), t.window_s);
  EXPECT_FALSE(shaking.Still(t)) << "accelerations 0.5 m/s^2 off their mean";
  ImuStillness turning;
  for (int i = 0; i < 100; ++i) turning.Add(Sample(i, 0.0, 0.05), t.window_s);
  EXPECT_FALSE(turning.Still(t)) << "angular rate 0.05 rad/s off its mean";

  // Motion that ended more than a window ago is forgotten.
  ImuStillness stopped;
  for (int i = 0; i < 50; ++i) stopped.Add(Sample(i, 0.5, 0.05), t.window_s);
  EXPECT_FALSE(stopped.Still(t));
  for (int i = 50; i < 120; ++i) stopped.Add(Sample(i, 0.0, 0.0), t.window_s);
  EXPECT_TRUE(stopped.Still(t));

  ImuStillness few;
  for (int i = 0; i < t.min_samples - 1; ++i) few.Add(Sample(i, 0.0, 0.0), t.window_s);
  EXPECT_FALSE(few.Still(t)) << "fewer than min_samples";
}

TEST(ImuStillness, WindowHoldsAtMostMaxSamples) {
  // 1 MHz samples over a 1 s window would be a million; the window keeps the
  // newest kMaxSamples. A vibration older than those is forgotten.
  StillnessThresholds t;
  t.window_s = 1.0;
  ImuStillness w;
  const auto n = static_cast<int>(ImuStillness::kMaxSamples);
  for (int i = 0; i < n; ++i) {
    ImuSample s = Sample(i, 0.5, 0.0);
    s.t_ns = i * 1000;
    w.Add(s, t.window_s);
  }
  EXPECT_FALSE(w.Still(t));
  for (int i = n; i < 2 * n; ++i) {
    ImuSample s = Sample(i, 0.0, 0.0);
    s.t_ns = static_cast<int64_t>(i) * 1000;
    w.Add(s, t.window_s);
  }
  EXPECT_TRUE(w.Still(t)) << "all within 1 s, yet only the newest kMaxSamples (still) are held";
  // Samples going back in time are ignored.
  ImuSample old = Sample(0, 5.0, 1.0);
  old.t_ns = 0;
  w.Add(old, t.window_s);
  EXPECT_TRUE(w.Still(t));
}

TEST(VehicleConstraints, ByDefaultTheyWaitForASpeedSensorWhileVoTracks) {
  // Without speed readings and with VO tracking throughout, the default
  // (vehicle_constraints_need_speed) fuses no constraint; asked for without
  // speed, every frame fuses them.
  SimConfig c;
  c.duration_s = 30;
  c.seed = 5;
  const auto ev = Simulate(c);
  auto nhc_updates = [&](bool need_speed) {
    EkfConfig config = ConfigFor(c);
    config.vehicle.constraints_need_speed = need_speed;
    Ekf ekf(config);
    Drive(ekf, ev, DriveHooks{});
    EXPECT_TRUE(ekf.initialized());
    EXPECT_EQ(ekf.stats().speed_used, 0);
    return ekf.stats().nhc_updates + ekf.stats().zupt_updates;
  };
  EXPECT_EQ(nhc_updates(true), 0);
  EXPECT_GT(nhc_updates(false), 100);
}

TEST(VehicleSpeed, AStuckAtZeroSensorDoesNotStopAMovingCar) {
  // Two seconds of 0 readings (a CAN dropout sending 0) while the car drives
  // on with GPS and VO: the zero-velocity update is gated, so they are refused.
  SimConfig c;
  c.duration_s = 40;
  c.seed = 9;
  const auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c));
  DriveHooks h;
  auto stuck = [](const SimEvent& e) { return e.truth.t_ns >= 30 * kNsPerS && e.truth.t_ns < 32 * kNsPerS; };
  h.reading = [&](const SimEvent& e) -> std::optional<SpeedSample> {
    return SpeedSample{e.truth.t_ns, stuck(e) ? 0.0 : ForwardSpeed(e.truth.x), 0.05};
  };
  double slowest_ratio = std::numeric_limits<double>::infinity();
  h.after_frame = [&](const SimEvent& e, const FusedPose&) {
    if (!stuck(e)) return;
    slowest_ratio = std::min(slowest_ratio, ForwardSpeed(ekf.state()) / ForwardSpeed(e.truth.x));
  };
  Drive(ekf, ev, h);
  ASSERT_TRUE(std::isfinite(slowest_ratio)) << "frames inside the stuck window";
  EXPECT_GT(slowest_ratio, 0.9) << "the zero readings pulled the estimate down";
  EXPECT_GE(ekf.stats().speed_rejected, 90) << "~100 zero readings (50 Hz over 2 s), refused";
}

}  // namespace
}  // namespace locaid::fusion
