#include "pipeline/localizer.hpp"

#include <algorithm>
#include <chrono>
#include <limits>
#include <utility>

namespace locaid::pipeline {
namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// VO slower than kVoStillMps while the car surely moves faster than
// kMovingMps (fusion::Ekf::SurelyMovingFasterThan): a frozen camera whose
// repeated frames still differ (fresh sensor noise, a re-encoded buffer), so
// the image guard's same-content check cannot see it.
constexpr double kVoStillMps = 0.2;
constexpr double kMovingMps = 1.5;

}  // namespace

fusion::EkfConfig EkfConfigForScenario(fusion::EkfConfig c, const sim::Scenario& s) {
  if (s.imu_grade == sim::ImuGrade::kMems) {
    c.imu.accel_noise_mps2_sqrt_hz = std::max(c.imu.accel_noise_mps2_sqrt_hz, 2 * s.imu_accel_noise_mps2_sqrt_hz);
    c.imu.gyro_noise_radps_sqrt_hz = std::max(c.imu.gyro_noise_radps_sqrt_hz, 2 * s.imu_gyro_noise_radps_sqrt_hz);
    c.startup.accel_bias_sigma_mps2 = std::max(c.startup.accel_bias_sigma_mps2, 2 * s.imu_accel_bias_sigma_mps2);
    c.startup.gyro_bias_sigma_radps = std::max(c.startup.gyro_bias_sigma_radps, 2 * s.imu_gyro_bias_sigma_radps);
  }
  return c;
}

Localizer::Localizer(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu, LocalizerOptions options)
    : Localizer(T_cam0_imu, options,
                options.vo_method.empty() || options.vo_method == "none"
                    ? nullptr
                    : vo::MakeStereoOdometry(options.vo_method, camera)) {}

Localizer::Localizer(const Eigen::Isometry3d& T_cam0_imu, LocalizerOptions options,
                     std::unique_ptr<vo::StereoOdometry> odometry)
    : T_cam0_imu_(T_cam0_imu), vo_(std::move(odometry)), ekf_(options.ekf) {}

Localizer::~Localizer() = default;

void Localizer::Fuse(const Measurements& m) {
  // One time line; at equal times IMU first, then the fix, then the speed.
  const auto t0 = std::chrono::steady_clock::now();
  constexpr int64_t kEnd = std::numeric_limits<int64_t>::max();
  size_t i = 0, g = 0, v = 0;
  while (i < m.imu.size() || g < m.gps.size() || v < m.speed.size()) {
    const int64_t ti = i < m.imu.size() ? m.imu[i].t_ns : kEnd;
    const int64_t tg = g < m.gps.size() ? m.gps[g].t_ns : kEnd;
    const int64_t tv = v < m.speed.size() ? m.speed[v].t_ns : kEnd;
    if (ti <= tg && ti <= tv) {
      ekf_.PropagateImu(m.imu[i++]);  // the filter's process model decides whether IMU is used
    } else if (tg <= tv) {
      FeedGps(m.gps[g++]);
    } else {
      ekf_.UpdateSpeed(m.speed[v++]);
    }
  }
  fusion_ms_ += MsSince(t0);
}

void Localizer::FeedGps(const fusion::GpsFix& fix) {
  GpsFeed feed{fix, Eigen::Vector3d::Zero(), ekf_.UpdateGps(fix)};
  if (ekf_.enu().has_origin()) feed.p_enu_m = ekf_.enu().ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m);
  feeds_.push_back(std::move(feed));
}

vo::RelativeMotion Localizer::TrackVo(const vo::StereoFrame& frame) {
  // A tick without images (a live camera that is down) never reaches VO:
  // its state stays at the last frame, so tracking resumes from there.
  if (vo_ && !frame.no_images) return vo_->Track(frame);
  vo::RelativeMotion m;
  m.t_ns = frame.t_ns;
  m.t_prev_ns = frame.t_ns;
  m.status = vo::Status::kLost;
  if (frame.no_images) m.health = vo::Health::kNoImages;
  return m;
}

bool Localizer::VoContradictsVehicle(const vo::RelativeMotion& m) const {
  if (m.status == vo::Status::kLost || m.t_ns <= m.t_prev_ns) return false;
  const double dt_s = static_cast<double>(m.t_ns - m.t_prev_ns) * 1e-9;
  return m.T_prev_curr.translation().norm() / dt_s < kVoStillMps && ekf_.SurelyMovingFasterThan(m.t_ns, kMovingMps);
}

FrameResult Localizer::Process(const vo::StereoFrame& frame) {
  FrameResult r;
  const auto t_vo = std::chrono::steady_clock::now();
  r.vo = TrackVo(frame);
  r.vo_ms = MsSince(t_vo);
  if (VoContradictsVehicle(r.vo)) {
    r.vo.status = vo::Status::kLost;  // never a standstill: the filter dead-reckons instead
    r.vo.health = vo::Health::kFrozen;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const int64_t t_ns = r.vo.t_ns;
  // VO: cam0 motion -> body motion (the filter works in body axes), from the
  // VO's own reference frame (older than the last frame after missing frames).
  const bool vo_ok = r.vo.status != vo::Status::kLost && last_frame_ns_.has_value();
  r.vo_body = fusion::CameraMotionToBody(r.vo.T_prev_curr, r.vo.covariance, T_cam0_imu_);
  r.vo_body.t_prev_ns = vo_ok ? r.vo.t_prev_ns : last_frame_ns_.value_or(t_ns);
  r.vo_body.t_ns = t_ns;
  r.vo_update = ekf_.ProcessVo(r.vo_body, vo_ok);
  r.pose = ekf_.Output(t_ns, r.vo.status != vo::Status::kLost);
  r.epoch = ekf_.MarkEpoch();
  r.gps_feeds = std::exchange(feeds_, {});
  last_frame_ns_ = t_ns;
  r.fusion_ms = std::exchange(fusion_ms_, 0) + MsSince(t0);
  return r;
}

}  // namespace locaid::pipeline
