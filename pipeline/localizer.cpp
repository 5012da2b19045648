#include "pipeline/localizer.hpp"
#include "core/stereo_camera.hpp"

#include "kitti/oxts_pose.hpp"

#include <algorithm>
#include <chrono>
#include <tuple>
#include <stdexcept>

namespace locaid::pipeline {
namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

fusion::EkfConfig EffectiveEkfConfig(const LocalizerOptions& options, const fusion::Scenario& s) {
  fusion::EkfConfig c = options.ekf;
  if (s.imu_grade == fusion::ImuGrade::kMems) {
    // The filter must know the IMU is worse than the RT3003.
    c.accel_noise_mps2_sqrt_hz = std::max(c.accel_noise_mps2_sqrt_hz, 2 * s.imu_accel_noise_mps2_sqrt_hz);
    c.gyro_noise_radps_sqrt_hz = std::max(c.gyro_noise_radps_sqrt_hz, 2 * s.imu_gyro_noise_radps_sqrt_hz);
    c.init_accel_bias_sigma_mps2 = std::max(c.init_accel_bias_sigma_mps2, 2 * s.imu_accel_bias_sigma_mps2);
    c.init_gyro_bias_sigma_radps = std::max(c.init_gyro_bias_sigma_radps, 2 * s.imu_gyro_bias_sigma_radps);
  }
  return c;
}

}  // namespace

Localizer::Localizer(const StereoCamera& camera, const Eigen::Isometry3d& T_cam0_imu,
                     fusion::Scenario scenario, LocalizerOptions options)
    : Localizer(T_cam0_imu, std::move(scenario), options,
                options.vo_method.empty() || options.vo_method == "none"
                    ? nullptr
                    : vo::MakeStereoOdometry(options.vo_method, camera)) {}

Localizer::Localizer(const Eigen::Isometry3d& T_cam0_imu, fusion::Scenario scenario, LocalizerOptions options,
                     std::unique_ptr<vo::StereoOdometry> odometry)
    : T_cam0_imu_(T_cam0_imu), options_(std::move(options)), vo_(std::move(odometry)),
      scenario_(std::move(scenario)) {
  fusion::ValidateScenario(scenario_);
  Reset();
}

Localizer::~Localizer() = default;

void Localizer::Reset() {
  if (vo_) vo_->Reset();
  ekf_ = std::make_unique<fusion::Ekf>(EffectiveEkfConfig(options_, scenario_));
  gps_ = std::make_unique<fusion::GpsScenario>(scenario_);
  imu_ = std::make_unique<fusion::ImuDegrader>(scenario_);
  std::lock_guard lock(control_mutex_);
  for (const auto& [a, b] : all_outages_) gps_->ScheduleOutage(a, b);
  gps_->SetForcedOutage(forced_);
  last_frame_ns_.reset();
}

void Localizer::ScheduleOutage(int64_t start_ns, int64_t end_ns) {
  if (end_ns <= start_ns)
    throw std::invalid_argument("ScheduleOutage: end_ns (" + std::to_string(end_ns) +
                                ") must be after start_ns (" + std::to_string(start_ns) + ")");
  std::lock_guard lock(control_mutex_);
  pending_outages_.emplace_back(start_ns, end_ns);
}
void Localizer::StartOutageNow() { std::lock_guard lock(control_mutex_); pending_forced_ = true; }
void Localizer::StopOutage() { std::lock_guard lock(control_mutex_); pending_forced_ = false; }

void Localizer::SetScenario(fusion::Scenario scenario) {
  fusion::ValidateScenario(scenario);
  std::lock_guard lock(control_mutex_);
  pending_scenario_ = std::move(scenario);
}

void Localizer::ApplyPendingControls() {
  std::lock_guard lock(control_mutex_);
  if (pending_scenario_) {
    scenario_ = std::move(*pending_scenario_);
    pending_scenario_.reset();
    const auto start = gps_->drive_start_ns();
    gps_ = std::make_unique<fusion::GpsScenario>(scenario_);
    imu_ = std::make_unique<fusion::ImuDegrader>(scenario_);
    // Keep the drive clock: scenario outages stay relative to the drive start.
    if (start) gps_->SetDriveStart(*start);
    for (const auto& [a, b] : all_outages_) gps_->ScheduleOutage(a, b);
    gps_->SetForcedOutage(forced_);
  }
  for (const auto& [a, b] : pending_outages_) {
    gps_->ScheduleOutage(a, b);
    all_outages_.emplace_back(a, b);
  }
  pending_outages_.clear();
  if (pending_forced_) {
    forced_ = *pending_forced_;
    gps_->SetForcedOutage(forced_);
    pending_forced_.reset();
  }
}


vo::RelativeMotion Localizer::TrackVo(const vo::StereoFrame& frame) {
  if (!vo_) {
    vo::RelativeMotion m;
    m.t_ns = frame.t_ns;
    m.t_prev_ns = frame.t_ns;
    m.status = vo::Status::kLost;
    return m;
  }
  return vo_->Track(frame);
}

FrameResult Localizer::Process(const vo::StereoFrame& frame,
                               std::span<const kitti::OxtsSample> oxts) {
  const auto t0 = std::chrono::steady_clock::now();
  vo::RelativeMotion motion = TrackVo(frame);
  const double vo_ms = MsSince(t0);
  SensorBatch batch;
  batch.oxts.assign(oxts.begin(), oxts.end());
  FrameResult r = Fuse(motion, batch);
  r.vo_ms = vo_ms;
  return r;
}

FrameResult Localizer::FuseSensors(const SensorBatch& batch) {
  const auto t0 = std::chrono::steady_clock::now();
  ApplyPendingControls();
  FrameResult r;
  FeedSensors(batch, r);
  r.fusion_ms = MsSince(t0);
  return r;
}

void Localizer::FeedGps(const fusion::GpsFix& fix, FrameResult& r) {
  GpsFeed feed;
  feed.fix = fix;
  const int rejected_before = ekf_->gps_rejected();
  const int rejected_v_before = ekf_->gps_rejected_vertical();
  feed.accepted = ekf_->UpdateGps(fix);
  feed.rejected = ekf_->gps_rejected() > rejected_before;
  feed.rejected_vertical = ekf_->gps_rejected_vertical() > rejected_v_before;
  if (ekf_->initialized()) {
    feed.nis = ekf_->last_gps_nis();
    feed.gate = ekf_->gps_gate();
  }
  if (ekf_->enu().has_origin()) feed.p_enu_m = ekf_->enu().ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m);
  r.gps_feeds.push_back(feed);
}

void Localizer::FeedSensors(const SensorBatch& batch, FrameResult& r) {
  if (batch.receiver_has_fix) receiver_has_fix_ = *batch.receiver_has_fix;
  // One time line over the three lists; at equal times IMU comes first, so a
  // fix is compared with the state propagated to its time.
  enum Kind { kOxts, kImu, kGps };
  std::vector<std::tuple<int64_t, int, size_t>> events;
  events.reserve(batch.oxts.size() + batch.imu.size() + batch.gps.size());
  for (size_t i = 0; i < batch.oxts.size(); ++i) events.emplace_back(batch.oxts[i].t_ns, kOxts, i);
  for (size_t i = 0; i < batch.imu.size(); ++i) events.emplace_back(batch.imu[i].t_ns, kImu, i);
  for (size_t i = 0; i < batch.gps.size(); ++i) events.emplace_back(batch.gps[i].t_ns, kGps, i);
  std::stable_sort(events.begin(), events.end());
  for (const auto& [t_ns, kind, i] : events) {
    if (kind == kOxts) {
      const kitti::OxtsSample& s = batch.oxts[i];
      fusion::ImuSample imu;
      imu.t_ns = s.t_ns;
      imu.accel_mps2 = {s.record.ax_mps2, s.record.ay_mps2, s.record.az_mps2};
      imu.gyro_radps = {s.record.wx_radps, s.record.wy_radps, s.record.wz_radps};
      ekf_->PropagateImu(imu_->Apply(imu));  // the filter's process model decides whether IMU is used
      // The true attitude places a simulated antenna (Scenario::gps_antenna_body_m).
      const Eigen::Matrix3d R_enu_imu =
          kitti::OxtsAttitude(s.record.roll_rad, s.record.pitch_rad, s.record.yaw_rad);
      if (auto fix = gps_->Apply(s.t_ns, s.record.lat_deg, s.record.lon_deg, s.record.alt_m, &R_enu_imu))
        FeedGps(*fix, r);
    } else if (kind == kImu) {
      ekf_->PropagateImu(batch.imu[i]);
    } else if (!gps_->InOutage(t_ns)) {
      FeedGps(batch.gps[i], r);
    }
  }
}

FrameResult Localizer::Fuse(const vo::RelativeMotion& vo_cam, const SensorBatch& batch) {
  const auto t0 = std::chrono::steady_clock::now();
  ApplyPendingControls();
  FrameResult r;
  r.vo = vo_cam;
  const int64_t t_ns = vo_cam.t_ns;
  // Without OXTS the scenario's drive clock starts at the first frame.
  if (!gps_->drive_start_ns() && batch.oxts.empty()) gps_->SetDriveStart(t_ns);
  FeedSensors(batch, r);
  // VO: cam0 motion -> body motion (the filter works in body axes).
  const bool vo_ok = vo_cam.status != vo::Status::kLost && last_frame_ns_.has_value();
  const Eigen::Isometry3d T_cam_body = T_cam0_imu_;
  r.vo_body = fusion::CameraMotionToBody(vo_cam.T_prev_curr, vo_cam.covariance, T_cam_body);
  // The motion starts at the VO's own reference frame (older than the last
  // frame after missing frames).
  r.vo_body.t_prev_ns = vo_ok ? vo_cam.t_prev_ns : last_frame_ns_.value_or(t_ns);
  r.vo_body.t_ns = t_ns;
  ekf_->ProcessVo(r.vo_body, vo_ok);
  r.pose = ekf_->Output(t_ns, vo_cam.status != vo::Status::kLost);
  r.in_outage = gps_->InOutage(t_ns) || !receiver_has_fix_;
  last_frame_ns_ = t_ns;
  r.fusion_ms = MsSince(t0);
  return r;
}

}  // namespace locaid::pipeline
