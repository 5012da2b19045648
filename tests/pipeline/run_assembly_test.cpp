// AssembleRun, the one assembly of a run that server sessions and
// locaid-replay share: outages placed on the source's drive, the scenario's
// filter settings on top of the caller's, the estimator built from the
// source's rig. That a session streams what locaid-replay computes end to end
// is tests/server/replay_parity_test.cpp.
#include "pipeline/run_assembly.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <optional>
#include <stdexcept>

namespace locaid::pipeline {
namespace {

// A source that only knows its rig and its length.
class RigOnlySource : public FrameSource {
 public:
  explicit RigOnlySource(double duration_s) : duration_s_(duration_s) {
    camera_ = StereoCamera{700, 700, 600, 180, 0.54, 1242, 375};
    T_.translation() << 0.1, -0.2, 0.3;
  }
  SourceItem Next() override {
    SourceItem item;
    item.kind = SourceItem::Kind::kEnd;
    return item;
  }
  double duration_s() const override { return duration_s_; }
  const StereoCamera& camera() const override { return camera_; }
  Eigen::Isometry3d T_cam0_imu() const override { return T_; }

 private:
  double duration_s_;
  StereoCamera camera_;
  Eigen::Isometry3d T_ = Eigen::Isometry3d::Identity();
};

// An estimator that is never asked for anything here.
class NullEstimator : public Estimator {
 public:
  void Fuse(const Measurements&) override {}
  FrameResult Process(const vo::StereoFrame&) override { return {}; }
  const fusion::EnuFrame& enu() const override { return enu_; }

 private:
  fusion::EnuFrame enu_;
};

RunOptions CenteredOutage(double duration_s) {
  RunOptions options;
  options.scenario.name = "test-outage";
  options.scenario.outages.push_back({0, duration_s, true});
  return options;
}

TEST(AssembleRun, PlacesTheOutagesOnTheSourcesDriveAndHandsTheEstimatorTheRig) {
  std::optional<EstimatorInputs> seen;
  const AssembledRun run = AssembleRun(std::make_unique<RigOnlySource>(100), CenteredOutage(10),
                                       [&](const EstimatorInputs& in) {
                                         seen = in;
                                         return std::make_unique<NullEstimator>();
                                       });
  ASSERT_TRUE(run.loop);
  ASSERT_EQ(run.scenario.outages.size(), 1u);
  EXPECT_DOUBLE_EQ(run.scenario.outages[0].start_s, 45.0);  // the middle of 100 s
  EXPECT_FALSE(run.scenario.outages[0].centered);
  EXPECT_EQ(run.notice, "");
  ASSERT_TRUE(seen);
  EXPECT_DOUBLE_EQ(seen->scenario.outages[0].start_s, 45.0);  // the estimator sees the placed scenario
  EXPECT_DOUBLE_EQ(seen->camera.fx, 700);
  EXPECT_DOUBLE_EQ(seen->T_cam0_imu.translation().z(), 0.3);
}

TEST(AssembleRun, AnUnknownLengthLeavesTheOutagesAsGiven) {
  const AssembledRun run = AssembleRun(std::make_unique<RigOnlySource>(0), CenteredOutage(10),
                                       [](const EstimatorInputs&) { return std::make_unique<NullEstimator>(); });
  ASSERT_EQ(run.scenario.outages.size(), 1u);
  EXPECT_TRUE(run.scenario.outages[0].centered);
  EXPECT_EQ(run.notice, "");
}

TEST(AssembleRun, AnOutageOverTheWholeDriveIsSaid) {
  RunOptions options;
  options.scenario.name = "dark-all";
  options.scenario.outages.push_back({0, 30, false});
  const AssembledRun run = AssembleRun(std::make_unique<RigOnlySource>(20), options,
                                       [](const EstimatorInputs&) { return std::make_unique<NullEstimator>(); });
  EXPECT_NE(run.notice.find("cover the whole 20.0 s drive"), std::string::npos) << run.notice;
}

TEST(AssembleRun, TheScenariosFilterSettingsComeOnTopOfTheCallers) {
  RunOptions options;
  options.scenario.imu_grade = sim::ImuGrade::kMems;
  options.scenario.imu_accel_noise_mps2_sqrt_hz = 0.5;
  options.localizer.ekf.imu.accel_noise_mps2_sqrt_hz = 0.01;  // the caller's, lower than the grade needs
  options.localizer.ekf.gps.learn_noise = false;          // the caller's, kept
  std::optional<EstimatorInputs> seen;
  AssembleRun(std::make_unique<RigOnlySource>(60), options, [&](const EstimatorInputs& in) {
    seen = in;
    return std::make_unique<NullEstimator>();
  });
  ASSERT_TRUE(seen);
  EXPECT_DOUBLE_EQ(seen->localizer.ekf.imu.accel_noise_mps2_sqrt_hz, 1.0);  // 2x the MEMS grade's
  EXPECT_FALSE(seen->localizer.ekf.gps.learn_noise);
  // The same settings for a rig alone (a synthetic session checks them before its render).
  const EstimatorInputs early = EstimatorInputsFor(seen->camera, seen->T_cam0_imu, options);
  EXPECT_DOUBLE_EQ(early.localizer.ekf.imu.accel_noise_mps2_sqrt_hz, 1.0);
}

TEST(AssembleRun, WhatTheMakerThrowsComesOut) {
  EXPECT_THROW(AssembleRun(std::make_unique<RigOnlySource>(60), RunOptions{},
                           [](const EstimatorInputs&) -> std::unique_ptr<Estimator> {
                             throw std::invalid_argument("unknown VO method 'x'");
                           }),
               std::invalid_argument);
}

TEST(AssembleRun, TheDefaultMakerIsTheLocalizer) {
  RunOptions options;
  options.localizer.vo_method = "no-such-method";
  EXPECT_THROW(AssembleRun(std::make_unique<RigOnlySource>(60), options), std::invalid_argument);
}

}  // namespace
}  // namespace locaid::pipeline
