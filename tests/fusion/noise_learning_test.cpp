// Learned measurement noise (fusion/noise_scale.hpp, EkfConfig vo.learn_noise
// / gps.learn_noise): the estimator on its own, then the filter on simulated
// drives whose VO and GPS noise differ from what they state by a known factor.
#include "fusion/ekf.hpp"
#include "fusion/noise_scale.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

namespace locaid::fusion {
namespace {

using test::SimConfig;
using test::SimEvent;
using test::Simulate;

// ---------------------------------------------------------------- estimator

TEST(NoiseScaleEstimator, RecoversTheScaleBehindGaussianInnovations) {
  // r ~ N(0, hph + lambda R0) with a predicted part that changes per sample.
  NoiseScaleEstimator est(2, {.prior_samples = 10, .window_samples = 1e9, .min_scale = 0.01, .max_scale = 100});
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u_hph(0.0, 0.5), u_r0(0.5, 2.0);
  const double kTrue[2] = {6.0, 0.2};
  for (int k = 0; k < 20000; ++k) {
    for (int a = 0; a < 2; ++a) {
      const double hph = u_hph(rng), r0 = u_r0(rng);
      est.Add(a, std::sqrt(hph + kTrue[a] * r0) * n01(rng), hph, r0);
    }
  }
  EXPECT_NEAR(est.scale(0), kTrue[0], 0.1 * kTrue[0]);
  EXPECT_NEAR(est.scale(1), kTrue[1], 0.1 * kTrue[1]);
  EXPECT_EQ(est.samples()[0], 20000);
  std::cout << "learned " << est.scale(0) << " / " << est.scale(1) << " (true 6 / 0.2)\n";
}

TEST(NoiseScaleEstimator, StaysWithinItsBoundsAndStartsAtTheModel) {
  NoiseScaleEstimator est(1, {.prior_samples = 5, .window_samples = 50, .min_scale = 0.5, .max_scale = 4});
  EXPECT_EQ(est.scale(0), 1.0) << "no sample yet: the model";
  for (int k = 0; k < 500; ++k) est.Add(0, 100.0, 0.0, 1.0);
  EXPECT_EQ(est.scale(0), 4.0);
  for (int k = 0; k < 500; ++k) est.Add(0, 0.0, 1.0, 1.0);  // all of r^2 explained by the prediction
  EXPECT_EQ(est.scale(0), 0.5);
}

TEST(NoiseScaleEstimator, OneOutlierMovesTheScaleByABoundedStep) {
  NoiseScaleEstimator est(1, {.prior_samples = 30, .window_samples = 300, .min_scale = 0.01, .max_scale = 100});
  est.Add(0, 1e6, 0.0, 1.0);  // a 1e6-sigma outlier
  // Clipped at 3 sigma: one sample of at most 9 / 0.9946 among 31 (weights 1).
  EXPECT_LT(est.scale(0), 1.0 + 9.1 / 31.0);
  EXPECT_GT(est.scale(0), 1.0);
}

TEST(NoiseScaleEstimator, IgnoresNonFiniteAndMeaninglessInput) {
  NoiseScaleEstimator est(1, {});
  est.Add(0, std::numeric_limits<double>::quiet_NaN(), 0.0, 1.0);
  est.Add(0, 1.0, std::numeric_limits<double>::infinity(), 1.0);
  est.Add(0, 1.0, 0.0, 0.0);
  est.Add(0, 1.0, -1.0, 1.0);
  est.Add(3, 1.0, 0.0, 1.0);
  EXPECT_EQ(est.samples()[0], 0);
  EXPECT_EQ(est.scale(0), 1.0);
}

// ---------------------------------------------------------------- filter

// A filter whose VO model is exactly the reported covariance (no inflation,
// per-metre term or floor), so that the learned scale is the factor between
// the VO's true noise and the covariance it reports.
EkfConfig ExactVoModel(const SimConfig& c) {
  EkfConfig e = test::SimEkfConfig(c, /*use_imu=*/true);
  e.vo.cov_scale = 1.0;
  e.vo.sigma_t_per_m = e.vo.sigma_lateral_per_m = e.vo.sigma_vertical_per_m = 0.0;
  e.vo.min_sigma_t_m = e.vo.min_sigma_rot_rad = 1e-9;
  e.vo.boresight_sigma_rad = 0.0;
  e.vo.gate_probability = 1.0 - 1e-12;  // a model 3x off must not be gated away before it is learnt
  e.vo.noise_scale_min = 0.01;
  e.vo.noise_window_frames = 600;
  e.vo.adaptive_rotation_noise = false;  // the learner takes all six axes (AdaptiveVoRotationNoise below: not)
  return e;
}

struct DriveResult {
  std::vector<double> scale_at_frame;  // vo_noise_scale()[0] per initialised frame
  std::vector<bool> learning, in_outage;
};

// Runs the filter over the events; every reported VO covariance is multiplied
// by `reported_factor` (the VO states that multiple of its true variance).
DriveResult Drive(Ekf& ekf, std::vector<SimEvent> ev, double reported_factor) {
  DriveResult out;
  for (SimEvent& e : ev) {
    if (e.kind == SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
    } else if (e.kind == SimEvent::kGps) {
      ekf.UpdateGps(e.gps);
    } else if (e.vo.t_ns > 0) {
      e.vo.covariance *= reported_factor;
      ekf.ProcessVo(e.vo, true);
      const FusedPose pose = ekf.Output(e.vo.t_ns, true);
      if (!ekf.initialized()) continue;
      out.scale_at_frame.push_back(pose.vo_noise_scale[0]);
      out.learning.push_back(pose.vo_noise_learning);
      out.in_outage.push_back(e.in_outage);
    }
  }
  return out;
}

void ExpectVoScaleRecovered(double reported_factor) {
  SimConfig c;
  c.duration_s = 240;
  c.seed = 21;
  c.vo_sigma_t_m = 0.02;  // a VO worse than the sim's default, so it carries weight against the IMU
  Ekf ekf(ExactVoModel(c));
  Drive(ekf, Simulate(c), reported_factor);
  ASSERT_TRUE(ekf.initialized());
  const double expected = 1.0 / reported_factor;
  const Vec6& got = ekf.vo_noise_scale();
  std::cout << "VO reports " << reported_factor << "x its variance; learned scale " << got.transpose()
            << " (true " << expected << ")\n";
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(got[i], expected, 0.2 * expected) << "axis " << i;
}

TEST(LearnedVoNoise, AVoThatUnderstatesItsNoiseIsFoundWithin20Percent) { ExpectVoScaleRecovered(1.0 / 4.0); }

TEST(LearnedVoNoise, AVoThatOverstatesItsNoiseIsFoundWithin20Percent) { ExpectVoScaleRecovered(4.0); }

TEST(LearnedVoNoise, TheScaleIsFrozenWhileGpsIsOut) {
  SimConfig c;
  c.duration_s = 120;
  c.seed = 5;
  c.outage_start_s = 60;
  c.outage_duration_s = 30;
  Ekf ekf(ExactVoModel(c));
  const DriveResult r = Drive(ekf, Simulate(c), 1.0 / 4.0);
  ASSERT_FALSE(r.scale_at_frame.empty());
  // The filter notices the outage 1.5 GPS periods after the last fix; from
  // then until GPS is back the scale must not move.
  int outage_frames = 0;
  double at_outage_start = -1;
  for (size_t k = 0; k < r.scale_at_frame.size(); ++k) {
    if (!r.in_outage[k]) continue;
    if (r.learning[k]) {
      EXPECT_LT(at_outage_start, 0) << "learning again inside the outage at frame " << k;
      continue;
    }
    if (at_outage_start < 0) at_outage_start = r.scale_at_frame[k];
    EXPECT_EQ(r.scale_at_frame[k], at_outage_start) << "frame " << k;
    ++outage_frames;
  }
  EXPECT_GT(outage_frames, 250) << "~28 s of frozen frames at 10 Hz";
  EXPECT_GT(at_outage_start, 1.5) << "it had learnt something before the outage";
  EXPECT_TRUE(r.learning.back()) << "learning again once GPS is back";
}

TEST(LearnedVoNoise, TheFixedModelStaysAsConfigured) {
  SimConfig c;
  c.duration_s = 60;
  c.seed = 2;
  EkfConfig config = ExactVoModel(c);
  config.vo.learn_noise = false;
  config.gps.learn_noise = false;
  Ekf ekf(config);
  const DriveResult r = Drive(ekf, Simulate(c), 1.0 / 4.0);
  ASSERT_FALSE(r.scale_at_frame.empty());
  EXPECT_EQ(ekf.vo_noise_scale(), Vec6::Ones());
  EXPECT_EQ(ekf.gps_noise_scale_horizontal(), 1.0);
  for (bool l : r.learning) EXPECT_FALSE(l);
}

// ------------------------------------------------ adaptive rotation noise

// With the adaptation on (the default), a rotation axis takes the larger of
// the learner's scale and the adaptation's; the translation axes are the
// learner's. learn = false: the learner held at the model (min = max = 1),
// the adaptation alone; the fixed model is vo.learn_noise = false.
// The drive of these tests: 4 min, VO translation noise 2 cm.
SimConfig RotationNoiseDrive() {
  SimConfig c;
  c.duration_s = 240;
  c.seed = 21;
  c.vo_sigma_t_m = 0.02;
  return c;
}

Vec6 ScaleWithAdaptiveRotation(double reported_factor, double max_scale, bool learn = true, bool adapt = true) {
  const SimConfig c = RotationNoiseDrive();
  EkfConfig config = ExactVoModel(c);
  if (!learn) config.vo.noise_scale_min = config.vo.noise_scale_max = 1.0;
  config.vo.adaptive_rotation_noise = adapt;
  config.vo.adaptive_rotation_noise_max_scale = max_scale;
  Ekf ekf(config);
  Drive(ekf, Simulate(c), reported_factor);
  EXPECT_TRUE(ekf.initialized());
  std::cout << "VO reports " << reported_factor << "x its variance, learn " << learn << ", adapt " << adapt
            << ", rotation clamp " << max_scale << ": scale " << ekf.vo_noise_scale().transpose() << "\n";
  return ekf.vo_noise_scale();
}

TEST(AdaptiveVoRotationNoise, AloneItScalesUpTheRotationOfAVoThatUnderstatesItsNoise) {
  const Vec6 got = ScaleWithAdaptiveRotation(1.0 / 4.0, 400, /*learn=*/false);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(got[i], 1.0) << "translation axis " << i << " (fixed: not learning)";
  for (int i = 3; i < 6; ++i) EXPECT_GT(got[i], 2.0) << "rotation axis " << i - 3 << " (the adaptation's)";
}

TEST(AdaptiveVoRotationNoise, WithTheLearnerEachRotationAxisTakesTheLargerScale) {
  const Vec6 both = ScaleWithAdaptiveRotation(1.0 / 4.0, 400);
  const Vec6 learner = ScaleWithAdaptiveRotation(1.0 / 4.0, 400, /*learn=*/true, /*adapt=*/false);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(both[i], 4.0, 0.8) << "translation axis " << i << " (the learner's)";
  for (int i = 3; i < 6; ++i) EXPECT_GT(both[i], 2.0) << "rotation axis " << i - 3;
  // Where the adaptation asks for more than the learner (yaw in this drive),
  // that axis carries it.
  EXPECT_GT(both[5], 1.1 * learner[5]);
}

TEST(AdaptiveVoRotationNoise, AClampOfOneLeavesTheRotationAxesToTheLearner) {
  // The same as the learner alone where its scale is >= 1 (its default
  // floor); the sim's model allows 0.01, so early frames may differ a little.
  const Vec6 clamped = ScaleWithAdaptiveRotation(1.0 / 4.0, 1.0);
  const Vec6 learner = ScaleWithAdaptiveRotation(1.0 / 4.0, 400, /*learn=*/true, /*adapt=*/false);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(clamped[i], learner[i], 0.01 * learner[i]) << "axis " << i;
  const Vec6 fixed = ScaleWithAdaptiveRotation(1.0 / 4.0, 1.0, /*learn=*/false);
  EXPECT_EQ(fixed, Vec6::Ones()) << "neither";
}

TEST(AdaptiveVoRotationNoise, TheFixedModelHasNoAdaptation) {
  const SimConfig c = RotationNoiseDrive();
  EkfConfig config = ExactVoModel(c);
  config.vo.adaptive_rotation_noise = true;
  config.vo.learn_noise = false;
  Ekf ekf(config);
  Drive(ekf, Simulate(c), 1.0 / 4.0);
  EXPECT_EQ(ekf.vo_noise_scale(), Vec6::Ones());
}

TEST(AdaptiveVoRotationNoise, AConsistentVoLeavesTheModelAsItIs) {
  const Vec6 got = ScaleWithAdaptiveRotation(1.0, 400, /*learn=*/false);
  for (int i = 3; i < 6; ++i) EXPECT_LT(got[i], 1.6) << "rotation axis " << i - 3;
}

TEST(LearnedGpsNoise, AReceiverThatClaimsAThirdOfItsNoiseIsFound) {
  // True noise 3 m / 5 m, stated 1 m / 1.667 m: the scale is 9.
  SimConfig c;
  c.duration_s = 180;
  c.seed = 9;
  c.gps_rate_hz = 5;
  std::vector<SimEvent> ev = Simulate(c);
  for (SimEvent& e : ev) {
    if (e.kind != SimEvent::kGps) continue;
    e.gps.sigma_h_m /= 3;
    e.gps.sigma_v_m /= 3;
  }
  EkfConfig config = test::SimEkfConfig(c, /*use_imu=*/true);
  config.gps.noise_window_fixes = 150;
  Ekf ekf(config);
  Drive(ekf, ev, 1.0);
  ASSERT_TRUE(ekf.initialized());
  std::cout << "learned GPS scale " << ekf.gps_noise_scale_horizontal() << " / " << ekf.gps_noise_scale_vertical()
            << " (true 9)\n";
  EXPECT_NEAR(ekf.gps_noise_scale_horizontal(), 9.0, 0.2 * 9.0);
  EXPECT_NEAR(ekf.gps_noise_scale_vertical(), 9.0, 0.2 * 9.0);
  EXPECT_LE(ekf.stats().gps_resets, 2) << "learning the noise, not resetting to each fix";
  // The start-up used the fixes' scatter, not their claim: the heading is right.
  const Mat3& R = ekf.state().R_enu_body;
  const Mat3& R_true = ev.back().truth.x.R_enu_body;
  EXPECT_LT(std::abs(LogSO3(R_true.transpose() * R).z()), 0.05);
}

}  // namespace
}  // namespace locaid::fusion
