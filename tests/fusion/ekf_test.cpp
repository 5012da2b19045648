// Filter behaviour on simulated drives: consistency (NEES), accuracy, outages,
// recovery, gating, numerical health.
#include "fusion/ekf.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

namespace locaid::fusion {
namespace {

using test::RunFilter;
using test::SimConfig;
using test::Simulate;

constexpr int kNeesRuns = 8;
constexpr int kPosDof = 3;

EkfConfig ConfigFor(const SimConfig& c, bool use_imu) { return test::SimEkfConfig(c, use_imu); }

void ExpectNeesConsistent(bool use_imu) {
  double nees_sum = 0;
  int n = 0;
  for (int run = 0; run < kNeesRuns; ++run) {
    SimConfig c;
    c.duration_s = 90;
    c.seed = 100 + run;
    const auto ev = Simulate(c);
    Ekf ekf(ConfigFor(c, use_imu));
    const auto s = RunFilter(ekf, ev, c);
    ASSERT_TRUE(s.finite) << "run " << run;
    ASSERT_TRUE(s.spd) << "run " << run;
    ASSERT_TRUE(s.symmetric) << "run " << run;
    ASSERT_GT(s.nees_n, 100);
    nees_sum += s.nees_sum / s.nees_n;
    ++n;
  }
  // Time-averaged NEES per run, averaged over runs: N * mean ~ chi2(dof * N)
  // if the samples were independent; the 95 % two-sided bounds.
  const double mean = nees_sum / n;
  const double lo = ChiSquareQuantile(0.025, kPosDof * n) / n;
  const double hi = ChiSquareQuantile(0.975, kPosDof * n) / n;
  EXPECT_GT(mean, lo) << "filter over-pessimistic (NEES " << mean << ")";
  EXPECT_LT(mean, hi) << "filter over-confident (NEES " << mean << ")";
  std::cout << (use_imu ? "IMU" : "no-IMU") << " NEES mean " << mean << " bounds [" << lo << ", "
            << hi << "]\n";
}

TEST(EkfNees, ConsistentWithImu) { ExpectNeesConsistent(true); }
TEST(EkfNees, ConsistentWithoutImu) { ExpectNeesConsistent(false); }

TEST(EkfAccuracy, UrbanCanyonGpsIsSmoothed) {
  // 3 m GPS at 1 Hz: the fused horizontal RMSE must be well below the GPS
  // noise (horizontal RMSE of the raw fixes: 3 m x sqrt(2) = 4.2 m). The 1.0 m
  // product target is measured on the rendered synthetic drive (docs/benchmarks.md).
  // The fixed noise models are exact here; learning them (the default) may
  // cost a little (the learned scales stay >= 1 and so wander above it), at
  // most 5 %.
  constexpr double kMaxRmseM = 1.35, kLearningCost = 1.05;
  for (bool imu : {true, false}) {
    SimConfig c;
    c.duration_s = 150;
    c.seed = 9;
    const auto ev = Simulate(c);
    double rmse[2];
    for (bool learn : {false, true}) {
      EkfConfig config = ConfigFor(c, imu);
      config.vo.learn_noise = config.gps.learn_noise = learn;
      Ekf ekf(config);
      const auto s = RunFilter(ekf, ev, c);
      rmse[learn] = std::sqrt(s.rmse_h_sum2 / s.rmse_n);
    }
    EXPECT_LT(rmse[false], kMaxRmseM) << (imu ? "IMU" : "no IMU");
    EXPECT_LT(rmse[true], kLearningCost * rmse[false]) << (imu ? "IMU" : "no IMU");
    std::cout << (imu ? "IMU" : "no IMU") << ": rmse fixed " << rmse[false] << " m, learned " << rmse[true] << " m\n";
  }
}

TEST(EkfOutage, DeadReckoningAndRecovery) {
  // 30 s outage: error at its end below the target fraction of the distance,
  // mode VO_ONLY inside, back within 2 sigma of the GPS noise within 5 s.
  constexpr double kMaxEndErrorFractionImu = 0.01, kMaxEndErrorFractionNoImu = 0.015;
  constexpr double kMaxReconvergeS = 5.0;
  for (bool imu : {true, false}) {
    SimConfig c;
    c.duration_s = 120;
    c.gps_rate_hz = 10;
    c.gps_sigma_h_m = 1.5;
    c.outage_start_s = 50;
    c.outage_duration_s = 30;
    c.seed = 21;
    const auto ev = Simulate(c);
    Ekf ekf(ConfigFor(c, imu));
    const auto s = RunFilter(ekf, ev, c);
    ASSERT_GT(s.outage_distance_m, 150);
    EXPECT_LT(s.outage_end_error_m / s.outage_distance_m,
              imu ? kMaxEndErrorFractionImu : kMaxEndErrorFractionNoImu)
        << (imu ? "IMU" : "no IMU") << " end error " << s.outage_end_error_m << " m over "
        << s.outage_distance_m << " m";
    EXPECT_GE(s.reconverge_s, 0.0);
    EXPECT_LE(s.reconverge_s, kMaxReconvergeS);
    EXPECT_NE(std::find(s.modes.begin(), s.modes.end(), Mode::kVoOnly), s.modes.end());
    EXPECT_EQ(s.modes.back(), Mode::kGpsFused);
    EXPECT_TRUE(s.finite && s.spd && s.symmetric);
  }
}

TEST(EkfGate, InjectedJumpIsRejectedAndDoesNotPullThePose) {
  constexpr double kJumpM = 30.0;
  constexpr double kMaxPullM = 0.3;
  SimConfig c;
  c.duration_s = 60;
  c.seed = 4;
  auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c, true));
  int gps_seen = 0;
  bool injected = false;
  for (auto& e : ev) {
    if (e.kind == test::SimEvent::kImu) ekf.PropagateImu(e.imu);
    else if (e.kind == test::SimEvent::kFrame) { if (e.vo.t_ns > 0) ekf.ProcessVo(e.vo, true); }
    else {
      ++gps_seen;
      if (ekf.initialized() && gps_seen > 40 && !injected) {
        injected = true;
        EnuFrame geo;
        geo.SetOrigin(e.gps.lat_deg, e.gps.lon_deg, e.gps.alt_m);
        GpsFix bad = e.gps;
        geo.ToGeodetic(Vec3(kJumpM * 0.6, kJumpM * 0.8, 0), bad.lat_deg, bad.lon_deg, bad.alt_m);
        const Vec3 before = ekf.state().p_enu_m;
        const int rejected_before = ekf.stats().gps_rejected;
        EXPECT_TRUE(ekf.UpdateGps(bad).rejected);
        EXPECT_EQ(ekf.stats().gps_rejected, rejected_before + 1);
        EXPECT_LT((ekf.state().p_enu_m - before).norm(), kMaxPullM);
        EXPECT_EQ(ekf.Output(e.gps.t_ns, true).mode, Mode::kGpsDegraded);
        continue;
      }
      ekf.UpdateGps(e.gps);
    }
  }
  EXPECT_TRUE(injected);
}

TEST(EkfGate, PersistentOffsetIsEventuallyAccepted) {
  // If every fix disagrees (the filter is wrong, not the GPS), the filter must
  // not reject GPS forever.
  SimConfig c;
  c.duration_s = 80;
  c.gps_rate_hz = 1;
  c.seed = 6;
  auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c, true));
  bool shifted = false;
  for (auto& e : ev) {
    if (e.kind == test::SimEvent::kImu) ekf.PropagateImu(e.imu);
    else if (e.kind == test::SimEvent::kFrame) { if (e.vo.t_ns > 0) ekf.ProcessVo(e.vo, true); }
    else {
      if (ekf.initialized() && !shifted && e.gps.t_ns > 40'000'000'000LL) {
        // Corrupt the filter: shift its belief by 50 m through a wrong "fix"
        // stream is not possible, so shift the GPS instead (a datum change).
        shifted = true;
      }
      if (shifted) {
        EnuFrame geo;
        geo.SetOrigin(e.gps.lat_deg, e.gps.lon_deg, e.gps.alt_m);
        geo.ToGeodetic(Vec3(50, 0, 0), e.gps.lat_deg, e.gps.lon_deg, e.gps.alt_m);
      }
      ekf.UpdateGps(e.gps);
    }
  }
  ASSERT_TRUE(shifted);
  const auto& last = ev.back();
  const Vec3 gt = test::TruthInFilterEnu(ekf, last.truth.x.p_enu_m) + Vec3(50, 0, 0);
  EXPECT_LT((ekf.state().p_enu_m - gt).head<2>().norm(), 5.0);
  EXPECT_TRUE(ekf.covariance().allFinite());
}

TEST(EkfInit, HeadingFromMotionNotFromAttitude) {
  SimConfig c;
  c.duration_s = 30;
  c.seed = 12;
  const auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c, true));
  EXPECT_EQ(ekf.Output(0, true).mode, Mode::kLost);
  test::SimEvent const* last_frame = nullptr;
  for (const auto& e : ev) {
    if (e.kind == test::SimEvent::kImu) ekf.PropagateImu(e.imu);
    else if (e.kind == test::SimEvent::kGps) ekf.UpdateGps(e.gps);
    else if (e.vo.t_ns > 0) { ekf.ProcessVo(e.vo, true); last_frame = &e; }
    if (ekf.initialized()) break;
  }
  ASSERT_TRUE(ekf.initialized());
  ASSERT_NE(last_frame, nullptr);
  const Mat3 R_err = ekf.state().R_enu_body * last_frame->truth.x.R_enu_body.transpose();
  const double yaw_err = std::abs(LogSO3(R_err).z());
  const double sigma_yaw = std::sqrt(ekf.covariance()(8, 8));
  EXPECT_LT(yaw_err, 4 * sigma_yaw + 1e-3);
  EXPECT_LT(yaw_err, 0.2);
}

// Every 10th frame pair of the outage is missing (VO LOST, as the real
// excerpt's frames 22/23): the next VO motion spans three frame periods and
// starts at the frame before the gap (t_prev_ns). The filter must apply it once,
// not coast over the gap and then add the whole motion again.
std::vector<test::SimEvent> WithMissingFramePairs(std::vector<test::SimEvent> ev, std::vector<bool>& vo_ok) {
  vo_ok.assign(ev.size(), true);
  int frame = 0;
  int64_t anchor_ns = 0;
  Eigen::Isometry3d since_anchor = Eigen::Isometry3d::Identity();  // measured motions of the gap
  for (size_t i = 0; i < ev.size(); ++i) {
    if (ev[i].kind != test::SimEvent::kFrame) continue;
    VoMeasurement& vo = ev[i].vo;
    const int k = frame++ % 10;
    if (ev[i].in_outage && (k == 3 || k == 4)) {
      since_anchor = since_anchor * vo.T_prev_curr;
      vo_ok[i] = false;  // t_prev_ns stays the previous frame's, as the pipeline passes it
      vo.T_prev_curr = Eigen::Isometry3d::Identity();
      continue;
    }
    if (k == 5 && ev[i].in_outage) {
      vo.T_prev_curr = since_anchor * vo.T_prev_curr;
      vo.t_prev_ns = anchor_ns;
    }
    since_anchor = Eigen::Isometry3d::Identity();
    anchor_ns = vo.t_ns;
  }
  return ev;
}

class EkfMissingFrames : public ::testing::TestWithParam<bool> {};

TEST_P(EkfMissingFrames, MotionSpanningMissingFramesIsAppliedOnce) {
  SimConfig c;
  c.duration_s = 60;
  c.outage_start_s = 30;
  c.outage_duration_s = 40;  // the drive ends inside the outage
  c.seed = 4;
  const auto ev = Simulate(c);
  std::vector<bool> vo_ok;
  const auto gapped = WithMissingFramePairs(ev, vo_ok);
  auto run = [&](const std::vector<test::SimEvent>& events, const std::vector<bool>* ok) {
    Ekf ekf(ConfigFor(c, GetParam()));
    Vec3 err = Vec3::Zero();
    for (size_t i = 0; i < events.size(); ++i) {
      const auto& e = events[i];
      if (e.kind == test::SimEvent::kImu) ekf.PropagateImu(e.imu);
      else if (e.kind == test::SimEvent::kGps) ekf.UpdateGps(e.gps);
      else if (e.vo.t_ns > 0) {
        const bool good = ok ? (*ok)[i] : true;
        ekf.ProcessVo(e.vo, good);
        err = ekf.Output(e.vo.t_ns, good).T_enu_body.translation() - test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m);
      }
    }
    EXPECT_EQ(ekf.stats().vo_anchor_mismatches, 0);
    return err.head<2>().norm();
  };
  const double reference_m = run(ev, nullptr);
  const double gapped_m = run(gapped, &vo_ok);
  // 30 s of outage at ~8 m/s with 60 missing frames: coasting over each gap and
  // then adding the spanning motion again would put the car ~1 m per gap ahead.
  EXPECT_LT(gapped_m, reference_m + 2.0) << "reference " << reference_m << " m";
}

INSTANTIATE_TEST_SUITE_P(ImuAndNoImu, EkfMissingFrames, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Imu" : "NoImu"; });

TEST(EkfModes, LostWhenVoFailsWithoutGps) {
  SimConfig c;
  c.duration_s = 39.95;  // ends inside the outage
  c.outage_start_s = 20;
  c.outage_duration_s = 25;
  c.seed = 2;
  const auto ev = Simulate(c);
  Ekf ekf(ConfigFor(c, false));
  Mode last = Mode::kGpsFused;
  for (const auto& e : ev) {
    if (e.kind == test::SimEvent::kGps) {
      ekf.UpdateGps(e.gps);
    } else if (e.kind == test::SimEvent::kFrame && e.vo.t_ns > 0) {
      const bool vo_ok = !(e.in_outage && e.truth.t_ns > 30'000'000'000LL);
      ekf.ProcessVo(e.vo, vo_ok);
      last = ekf.Output(e.vo.t_ns, vo_ok).mode;
      if (e.in_outage && e.truth.t_ns > 25'000'000'000LL && vo_ok) {
        EXPECT_EQ(last, Mode::kVoOnly);
      }
    }
  }
  EXPECT_EQ(last, Mode::kLost);
  EXPECT_TRUE(ekf.covariance().allFinite());
}

}  // namespace
}  // namespace locaid::fusion
