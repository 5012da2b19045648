// The GPS gate can never lock GPS out: a run of rejections resets the
// rejected component to GPS (counted on the pose), and horizontal and vertical
// are gated apart. The filter state is made wrong the way it happens in the
// field: from some time on, every fix is offset (the filter's position drifted,
// or the receiver's datum moved), so the gate sees a consistent disagreement.
#include "fusion/ekf.hpp"
#include "sim.hpp"

#include <gtest/gtest.h>

#include <optional>

namespace locaid::fusion {
namespace {

using test::SimConfig;
using test::SimEvent;

constexpr double kStepAtS = 30.0;
constexpr double kEndS = 58.0;  // the simulated drive is 60 s long

struct StepRun {
  int rejected_after_step = 0, rejected_v_after_step = 0, longest_run = 0, horizontal_used_after_step = 0;
  int resets = 0, pose_resets = 0, fixes_after_step = 0;
  std::optional<Mode> mode_at_reset;
  Vec3 error_to_shifted_track_end = Vec3::Zero();  // estimate - (truth + offset), last frame
};

// Feeds a simulated drive; fixes after kStepAtS are moved by offset_enu_m.
StepRun RunWithStep(bool use_imu, const Vec3& offset_enu_m) {
  SimConfig c;
  c.duration_s = 60;
  c.seed = 4;  // no gate false alarm between kStepAtS and kEndS on consistent fixes
  EkfConfig config;
  config.imu.enabled = use_imu;
  config.imu.accel_noise_mps2_sqrt_hz = c.accel_noise;
  config.imu.gyro_noise_radps_sqrt_hz = c.gyro_noise;
  Ekf ekf(config);
  StepRun out;
  int run = 0;
  for (const auto& e : test::Simulate(c)) {
    const bool after = e.truth.t_ns >= static_cast<int64_t>(kStepAtS * 1e9);
    if (e.truth.t_ns > static_cast<int64_t>(kEndS * 1e9)) break;
    if (e.kind == SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
    } else if (e.kind == SimEvent::kGps) {
      GpsFix fix = e.gps;
      if (after) {
        EnuFrame geo;
        geo.SetOrigin(test::kLat0, test::kLon0, test::kAlt0);
        double lat, lon, alt;
        const Vec3 p = geo.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m) + offset_enu_m;
        geo.ToGeodetic(p, lat, lon, alt);
        fix.lat_deg = lat;
        fix.lon_deg = lon;
        fix.alt_m = alt;
      }
      const GpsUpdate u = ekf.UpdateGps(fix);
      run = u.rejected || u.rejected_vertical ? run + 1 : 0;
      if (!after) continue;
      ++out.fixes_after_step;
      out.longest_run = std::max(out.longest_run, run);
      out.rejected_after_step += u.rejected ? 1 : 0;
      out.rejected_v_after_step += u.rejected_vertical ? 1 : 0;
      out.horizontal_used_after_step += u.used ? 1 : 0;
      if (u.reset && !out.mode_at_reset) out.mode_at_reset = ekf.Output(fix.t_ns, true).mode;
    } else if (e.vo.t_ns > 0) {
      ekf.ProcessVo(e.vo, true);
      const FusedPose pose = ekf.Output(e.vo.t_ns, true);
      out.pose_resets = pose.gps_resets;
      if (ekf.initialized() && after)
        out.error_to_shifted_track_end =
            pose.T_enu_body.translation() - test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m + offset_enu_m);
    }
  }
  out.resets = ekf.stats().gps_resets;
  return out;
}

class GpsRecovery : public ::testing::TestWithParam<bool> {};

TEST_P(GpsRecovery, RunOfHorizontalRejectionsResetsToGpsAndIsCounted) {
  const StepRun r = RunWithStep(GetParam(), Vec3(32, -24, 0));  // 40 m, 1 Hz fixes of 3 m
  EXPECT_EQ(r.rejected_after_step, 3) << "the gate refuses exactly gps_reset_after_rejections fixes";
  EXPECT_EQ(r.longest_run, 3);
  EXPECT_EQ(r.resets, 1);
  EXPECT_EQ(r.pose_resets, 1) << "FusedPose reports the reset";
  ASSERT_TRUE(r.mode_at_reset.has_value());
  EXPECT_EQ(*r.mode_at_reset, Mode::kGpsDegraded);
  EXPECT_EQ(r.horizontal_used_after_step, r.fixes_after_step - 3);
  // 26 s later the track follows the fixes (3 m noise, 1 Hz).
  EXPECT_LT(r.error_to_shifted_track_end.head<2>().norm(), 3.0);
}

TEST_P(GpsRecovery, VerticalDisagreementKeepsTheHorizontalFix) {
  const StepRun r = RunWithStep(GetParam(), Vec3(0, 0, 30));  // 30 m up, 5 m vertical sigma
  EXPECT_EQ(r.rejected_after_step, 0) << "the horizontal parts pass their own gate";
  EXPECT_EQ(r.horizontal_used_after_step, r.fixes_after_step);
  EXPECT_EQ(r.rejected_v_after_step, 3);
  EXPECT_EQ(r.resets, 1);
  EXPECT_LT(std::abs(r.error_to_shifted_track_end.z()), 5.0);
  EXPECT_LT(r.error_to_shifted_track_end.head<2>().norm(), 3.0);
}

TEST_P(GpsRecovery, NoResetOnConsistentFixes) {
  const StepRun r = RunWithStep(GetParam(), Vec3::Zero());
  EXPECT_EQ(r.resets, 0);
  EXPECT_LE(r.longest_run, 1);
}

INSTANTIATE_TEST_SUITE_P(ImuAndNoImu, GpsRecovery, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Imu" : "NoImu"; });

}  // namespace
}  // namespace locaid::fusion
