// `gps: {measured: degraded}`: measured fixes (a ROS 2 bag's, a client's)
// go through the scenario's receiver model on top of what was recorded: its
// rate, its noise (added to the recorded sigma); `as-recorded` (the default)
// passes them as they are, outages apply either way.
#include "error_of.hpp"
#include "pipeline/scenario_stage.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace locaid::pipeline {
namespace {

// 10 s of measured fixes at 10 Hz, 1 m sigma, all at one place.
SampleBatch TenSecondsOfFixes() {
  SampleBatch b;
  for (int i = 0; i < 100; ++i) {
    ArrivedFix f;
    f.fix.t_ns = int64_t{i} * 100'000'000;
    f.fix.lat_deg = 49.0;
    f.fix.lon_deg = 8.4;
    f.fix.alt_m = 110;
    f.fix.sigma_h_m = 1.0;
    f.fix.sigma_v_m = 2.0;
    b.gps.push_back(f);
  }
  return b;
}

Measurements Stage(const std::string& yaml) {
  ScenarioStage stage(ParseScenarioYaml(yaml, "s.yaml"));
  const SampleBatch batch = TenSecondsOfFixes();
  stage.BeginFrame(0, batch);
  return stage.Apply(batch);
}

TEST(ScenarioMeasuredGps, AsRecordedByDefaultDegradedOnRequest) {
  const Measurements plain = Stage("name: plain\n");
  ASSERT_EQ(plain.gps.size(), 100u);
  EXPECT_EQ(plain.gps[7].lat_deg, 49.0);
  EXPECT_EQ(plain.gps[7].sigma_h_m, 1.0);
  EXPECT_EQ(Stage("gps: {measured: as-recorded, rate_hz: 1, sigma_h_m: 5}\n").gps.size(), 100u)
      << "the receiver model is for fixes made from ground truth unless asked";

  const Measurements worse = Stage("gps: {measured: degraded, rate_hz: 1, sigma_h_m: 5, sigma_v_m: 8}\nseed: 3\n");
  EXPECT_GE(worse.gps.size(), 9u);  // decimated to 1 Hz
  EXPECT_LE(worse.gps.size(), 11u);
  double moved = 0;
  for (const auto& f : worse.gps) {
    EXPECT_NEAR(f.sigma_h_m, std::hypot(1.0, 5.0), 1e-12);
    EXPECT_NEAR(f.sigma_v_m, std::hypot(2.0, 8.0), 1e-12);
    moved = std::max(moved, std::abs(f.lat_deg - 49.0) * 111'000);
  }
  EXPECT_GT(moved, 1.0) << "noise of 5 m was added";
}

TEST(ScenarioMeasuredGps, OutagesApplyToMeasuredFixesEitherWay) {
  for (const std::string measured : {"as-recorded", "degraded"}) {
    const Measurements m = Stage("gps: {measured: " + measured + "}\noutages: [{start_s: 2, duration_s: 3}]\n");
    for (const auto& f : m.gps) {
      const double t = static_cast<double>(f.t_ns) * 1e-9;
      EXPECT_FALSE(t >= 2 && t < 5) << measured << ": a fix at " << t << " s inside the outage";
    }
  }
}

TEST(ScenarioMeasuredGps, ABadValueNamesTheField) {
  const std::string error =
      test_support::ErrorOf<ScenarioError>([] { ParseScenarioYaml("gps: {measured: noisy}\n", "bad.yaml"); });
  EXPECT_NE(error.find("gps.measured"), std::string::npos) << error;
  EXPECT_NE(error.find("'as-recorded' or 'degraded'"), std::string::npos) << error;
}

}  // namespace
}  // namespace locaid::pipeline
