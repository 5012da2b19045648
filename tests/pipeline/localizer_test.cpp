// The Localizer on its own, without a network or a drive: typed measurements
// and frames in (a scripted straight drive: exact VO, a level IMU at 100 Hz,
// 10 Hz fixes), modes, fix outcomes and outage transitions out.
#include "fusion/geodesy.hpp"
#include "pipeline/localizer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

namespace locaid::pipeline {
namespace {

constexpr int64_t kFrameNs = 100'000'000;  // 10 Hz frames and fixes
constexpr int64_t kImuNs = 10'000'000;     // 100 Hz IMU
constexpr double kSpeedMps = 10.0;         // straight east

// Reports the true motion between frames: 1 m forward (body x, identity
// extrinsic), with a small covariance.
class ExactOdometry : public vo::StereoOdometry {
 public:
  vo::RelativeMotion Track(const vo::StereoFrame& frame) override {
    vo::RelativeMotion m;
    m.t_ns = frame.t_ns;
    m.t_prev_ns = last_ns_.value_or(frame.t_ns);
    m.T_prev_curr.translation().x() = kSpeedMps * static_cast<double>(m.t_ns - m.t_prev_ns) * 1e-9;
    m.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 1e-6;
    m.inliers = 200;
    m.status = vo::Status::kOk;
    m.health = vo::Health::kTracking;
    last_ns_ = frame.t_ns;
    return m;
  }
  void Reset() override { last_ns_.reset(); }

 private:
  std::optional<int64_t> last_ns_;
};

// Exact until from_ns, then what a frozen camera whose repeated frames still
// differ (fresh sensor noise) gives: no motion, reported as tracked.
class StuckOdometry : public vo::StereoOdometry {
 public:
  explicit StuckOdometry(int64_t from_ns) : from_ns_(from_ns) {}
  vo::RelativeMotion Track(const vo::StereoFrame& frame) override {
    vo::RelativeMotion m = exact_.Track(frame);
    if (frame.t_ns >= from_ns_) m.T_prev_curr = Eigen::Isometry3d::Identity();
    return m;
  }
  void Reset() override { exact_.Reset(); }

 private:
  ExactOdometry exact_;
  int64_t from_ns_;
};

struct Drive {
  fusion::EnuFrame enu;
  Drive() { enu.SetOrigin(49.0, 8.4, 110.0); }
  fusion::GpsFix FixAt(int64_t t_ns, double east_offset_m = 0) const {
    fusion::GpsFix fix;
    fix.t_ns = t_ns;
    enu.ToGeodetic(Eigen::Vector3d(kSpeedMps * static_cast<double>(t_ns) * 1e-9 + east_offset_m, 0, 0), fix.lat_deg,
                   fix.lon_deg, fix.alt_m);
    fix.sigma_h_m = 1.5;
    fix.sigma_v_m = 3.0;
    return fix;
  }
  // IMU samples of (t_prev, t]: level, no rotation, gravity on z.
  static std::vector<fusion::ImuSample> ImuBetween(int64_t t_prev_ns, int64_t t_ns) {
    std::vector<fusion::ImuSample> imu;
    for (int64_t t = (t_prev_ns / kImuNs + 1) * kImuNs; t <= t_ns; t += kImuNs) {
      fusion::ImuSample s;
      s.t_ns = t;
      s.accel_mps2 = {0, 0, 9.81};
      imu.push_back(s);
    }
    return imu;
  }
};

struct Step {
  FrameResult result;
  double horizontal_error_m = 0;
};

// Runs 12 s of the drive; `fix_for(frame)` says what fix (if any) comes with
// it; with speed_reading_mps, a speed sensor reads it at 50 Hz from 2 s on.
template <typename FixFor>
std::vector<Step> Drive12s(Localizer& localizer, const Drive& drive, FixFor fix_for,
                           std::optional<double> speed_reading_mps = std::nullopt) {
  std::vector<Step> steps;
  int64_t t_prev = 0;
  for (int i = 1; i <= 120; ++i) {
    const int64_t t = i * kFrameNs;
    Measurements m;
    m.imu = Drive::ImuBetween(t_prev, t);
    for (int64_t ts = t_prev + 20'000'000; speed_reading_mps && t >= 20 * kFrameNs && ts <= t; ts += 20'000'000)
      m.speed.push_back(fusion::SpeedSample{ts, *speed_reading_mps, 0.05});
    if (std::optional<fusion::GpsFix> fix = fix_for(i, t)) m.gps.push_back(*fix);
    localizer.Fuse(m);
    Step s;
    s.result = localizer.Process(vo::StereoFrame{t, {}, {}});
    const fusion::GpsFix truth = drive.FixAt(t);
    const Eigen::Vector3d truth_enu = localizer.enu().ToEnu(truth.lat_deg, truth.lon_deg, truth.alt_m);
    s.horizontal_error_m = (s.result.pose.T_enu_body.translation() - truth_enu).head<2>().norm();
    steps.push_back(s);
    t_prev = t;
  }
  return steps;
}

TEST(Localizer, ModesFollowTheFixesThroughAnOutageAndBack) {
  const Drive drive;
  Localizer localizer(Eigen::Isometry3d::Identity(), {}, std::make_unique<ExactOdometry>());
  // No fixes for frames 50..69 (5.0 s to 6.9 s).
  const auto steps = Drive12s(localizer, drive, [&](int i, int64_t t) -> std::optional<fusion::GpsFix> {
    if (i >= 50 && i < 70) return std::nullopt;
    return drive.FixAt(t);
  });
  // Before the start-up fit has its fixes and baseline, LOST, fixes buffered.
  EXPECT_EQ(steps[0].result.pose.mode, fusion::Mode::kLost);
  ASSERT_EQ(steps[0].result.gps_feeds.size(), 1u);
  EXPECT_TRUE(steps[0].result.gps_feeds[0].update.buffered);
  EXPECT_FALSE(steps[0].result.gps_feeds[0].update.used);
  // Fused from 3 s on; every fix used and within its gate.
  for (int i = 29; i < 49; ++i) {
    const FrameResult& r = steps[static_cast<size_t>(i)].result;
    EXPECT_EQ(r.pose.mode, fusion::Mode::kGpsFused) << "frame " << i + 1;
    ASSERT_EQ(r.gps_feeds.size(), 1u);
    EXPECT_TRUE(r.gps_feeds[0].update.used);
    EXPECT_LT(r.gps_feeds[0].update.nis, r.gps_feeds[0].update.gate);
    EXPECT_TRUE(r.vo_update.used);
    EXPECT_LT(steps[static_cast<size_t>(i)].horizontal_error_m, 1.0) << "frame " << i + 1;
  }
  // In the outage VO only (after 1.5 fix periods without a fix), still on track.
  for (int i = 51; i < 69; ++i) {
    EXPECT_EQ(steps[static_cast<size_t>(i)].result.pose.mode, fusion::Mode::kVoOnly) << "frame " << i + 1;
    EXPECT_TRUE(steps[static_cast<size_t>(i)].result.gps_feeds.empty());
  }
  EXPECT_LT(steps[68].horizontal_error_m, 1.0);
  // The first fix after the outage is used, and the mode is fused again.
  EXPECT_EQ(steps[69].result.pose.mode, fusion::Mode::kGpsFused);
  ASSERT_EQ(steps[69].result.gps_feeds.size(), 1u);
  EXPECT_TRUE(steps[69].result.gps_feeds[0].update.used);
  const fusion::EkfStats& stats = localizer.ekf().stats();
  EXPECT_EQ(stats.gps_used + stats.gps_rejected, 100);
  EXPECT_EQ(stats.gps_rejected, 0);
}

TEST(Localizer, AFixFarOffIsRejectedAndSaidSoOnItsPose) {
  const Drive drive;
  Localizer localizer(Eigen::Isometry3d::Identity(), {}, std::make_unique<ExactOdometry>());
  const auto steps = Drive12s(localizer, drive, [&](int i, int64_t t) -> std::optional<fusion::GpsFix> {
    return drive.FixAt(t, i == 60 ? 40.0 : 0.0);  // one fix 40 m east of the truth at 6.0 s
  });
  const FrameResult& bad = steps[59].result;
  ASSERT_EQ(bad.gps_feeds.size(), 1u);
  const fusion::GpsUpdate& u = bad.gps_feeds[0].update;
  EXPECT_TRUE(u.rejected);
  EXPECT_FALSE(u.used);
  EXPECT_FALSE(u.reset);  // one rejection is not a run
  EXPECT_GT(u.nis, u.gate);
  EXPECT_EQ(bad.pose.mode, fusion::Mode::kGpsDegraded);
  EXPECT_LT(steps[59].horizontal_error_m, 1.0) << "the rejected fix moved the estimate";
  // Degraded while the rejection is recent (3 s), fused after.
  EXPECT_EQ(steps[70].result.pose.mode, fusion::Mode::kGpsDegraded);
  EXPECT_EQ(steps[95].result.pose.mode, fusion::Mode::kGpsFused);
  EXPECT_EQ(localizer.ekf().stats().gps_rejected, 1);
}

TEST(Localizer, VoStandingStillWhileTheImuSaysTheCarMovesIsAFrozenCameraNotAStop) {
  // GPS out and the camera stuck from 6.0 s: VO reports no motion as if
  // tracked. Believed, it would stop the car (the filter accepts a run of
  // VO it first gates) and the estimate would fall ~60 m behind.
  const Drive drive;
  Localizer localizer(Eigen::Isometry3d::Identity(), {}, std::make_unique<StuckOdometry>(60 * kFrameNs));
  const auto steps = Drive12s(localizer, drive, [&](int i, int64_t t) -> std::optional<fusion::GpsFix> {
    if (i >= 60) return std::nullopt;
    return drive.FixAt(t);
  });
  EXPECT_EQ(steps[58].result.vo.health, vo::Health::kTracking);
  for (int i = 60; i < 120; ++i) {
    const FrameResult& r = steps[static_cast<size_t>(i)].result;
    EXPECT_EQ(r.vo.health, vo::Health::kFrozen) << "frame " << i + 1;
    EXPECT_EQ(r.vo.status, vo::Status::kLost) << "frame " << i + 1;
    EXPECT_FALSE(r.vo_update.used) << "frame " << i + 1;
    EXPECT_EQ(r.pose.mode, fusion::Mode::kDeadReckoning) << "frame " << i + 1;
  }
  EXPECT_LT(steps[119].horizontal_error_m, 3.0);
  EXPECT_GT(steps[119].result.pose.v_enu_mps.norm(), 9.0);
}

TEST(Localizer, AFreshSpeedReadingDecidesWhetherVoStandingStillIsFrozen) {
  // The same stuck camera with a speed sensor: reading the true 10 m/s, the
  // frames are frozen; reading 0 (the car stopped: the sensor outranks the
  // filter's belief), VO's standstill is a measurement again.
  const Drive drive;
  const auto no_fix_after_6s = [&](int i, int64_t t) -> std::optional<fusion::GpsFix> {
    if (i >= 60) return std::nullopt;
    return drive.FixAt(t);
  };
  Localizer moving(Eigen::Isometry3d::Identity(), {}, std::make_unique<StuckOdometry>(60 * kFrameNs));
  const auto a = Drive12s(moving, drive, no_fix_after_6s, kSpeedMps);
  for (int i = 60; i < 120; ++i) EXPECT_EQ(a[static_cast<size_t>(i)].result.vo.health, vo::Health::kFrozen) << i + 1;
  EXPECT_LT(a[119].horizontal_error_m, 3.0);
  EXPECT_GT(moving.ekf().stats().speed_used, 0);

  Localizer stopped(Eigen::Isometry3d::Identity(), {}, std::make_unique<StuckOdometry>(60 * kFrameNs));
  const auto b = Drive12s(stopped, drive, no_fix_after_6s, 0.0);
  for (int i = 60; i < 120; ++i) EXPECT_EQ(b[static_cast<size_t>(i)].result.vo.health, vo::Health::kTracking) << i + 1;
}

TEST(Localizer, WithoutVoTheFilterNeverStartsAndSaysLost) {
  const Drive drive;
  LocalizerOptions options;
  options.vo_method = "none";
  Localizer localizer(StereoCamera{400, 400, 160, 48, 0.5, 320, 96}, Eigen::Isometry3d::Identity(), options);
  const auto steps = Drive12s(localizer, drive, [&](int, int64_t t) { return std::optional(drive.FixAt(t)); });
  for (const Step& s : steps) {
    EXPECT_EQ(s.result.pose.mode, fusion::Mode::kLost);
    EXPECT_EQ(s.result.vo.status, vo::Status::kLost);
  }
  EXPECT_FALSE(localizer.ekf().initialized());
}

}  // namespace
}  // namespace locaid::pipeline
