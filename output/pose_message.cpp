#include "output/pose_message.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace locaid::output {
namespace {

locaid::v1::Mode ToProtoMode(fusion::Mode m) {
  switch (m) {
    case fusion::Mode::kGpsFused: return locaid::v1::MODE_GPS_FUSED;
    case fusion::Mode::kGpsDegraded: return locaid::v1::MODE_GPS_DEGRADED;
    case fusion::Mode::kVoOnly: return locaid::v1::MODE_VO_ONLY;
    case fusion::Mode::kLost: return locaid::v1::MODE_LOST;
    case fusion::Mode::kDeadReckoning: return locaid::v1::MODE_DEAD_RECKONING;
  }
  return locaid::v1::MODE_UNSPECIFIED;
}

locaid::v1::VoStatus ToProtoVo(vo::Status s) {
  switch (s) {
    case vo::Status::kOk: return locaid::v1::VO_STATUS_OK;
    case vo::Status::kDegraded: return locaid::v1::VO_STATUS_DEGRADED;
    case vo::Status::kLost: return locaid::v1::VO_STATUS_LOST;
  }
  return locaid::v1::VO_STATUS_UNSPECIFIED;
}

locaid::v1::VoHealth ToProtoHealth(vo::Health h) {
  switch (h) {
    case vo::Health::kTracking: return locaid::v1::VO_HEALTH_TRACKING;
    case vo::Health::kDark: return locaid::v1::VO_HEALTH_DARK;
    case vo::Health::kFrozen: return locaid::v1::VO_HEALTH_FROZEN;
    case vo::Health::kLost: return locaid::v1::VO_HEALTH_LOST;
    case vo::Health::kNoImages: return locaid::v1::VO_HEALTH_NO_IMAGES;
  }
  return locaid::v1::VO_HEALTH_UNSPECIFIED;
}

}  // namespace

void FillNoiseLearning(const fusion::FusedPose& p, locaid::v1::NoiseLearning* out) {
  out->clear_vo_scale();
  for (int i = 0; i < 6; ++i) out->add_vo_scale(p.vo_noise_scale[i]);
  out->set_gps_horizontal_scale(p.gps_noise_scale_h);
  out->set_gps_vertical_scale(p.gps_noise_scale_v);
  out->set_vo_learning(p.vo_noise_learning);
}

void FillPoseUpdate(const pipeline::StepResult& r, double latency_ms, locaid::v1::PoseUpdate* out) {
  const fusion::FusedPose& p = r.frame.pose;
  out->set_frame_index(r.frame_index);
  out->set_t_ns(p.t_ns);
  const Eigen::Vector3d t = p.T_enu_body.translation();
  auto* pos = out->mutable_position_enu_m();
  pos->set_x(t.x());
  pos->set_y(t.y());
  pos->set_z(t.z());
  const Eigen::Quaterniond q(p.T_enu_body.rotation());
  auto* o = out->mutable_orientation_enu_body();
  o->set_w(q.w());
  o->set_x(q.x());
  o->set_y(q.y());
  o->set_z(q.z());
  out->set_latitude_deg(p.lat_deg);
  out->set_longitude_deg(p.lon_deg);
  out->set_altitude_m(p.alt_m);
  auto* v = out->mutable_velocity_enu_mps();
  v->set_x(p.v_enu_mps.x());
  v->set_y(p.v_enu_mps.y());
  v->set_z(p.v_enu_mps.z());
  out->mutable_covariance()->Reserve(36);
  out->clear_covariance();
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) out->add_covariance(p.covariance(i, j));
  }
  out->set_mode(ToProtoMode(p.mode));
  out->set_seconds_since_gps(p.seconds_since_gps);
  out->set_vo_inliers(r.frame.vo.inliers);
  out->set_vo_status(ToProtoVo(r.frame.vo.status));
  out->set_vo_health(ToProtoHealth(r.frame.vo.health));
  out->set_speed_scale_error(p.speed_scale_error);
  out->set_speed_samples_used(static_cast<uint32_t>(std::max(0, p.speed_used)));
  out->set_gps_used(static_cast<uint32_t>(std::max(0, p.gps_used)));
  out->set_gps_rejected(static_cast<uint32_t>(std::max(0, p.gps_rejected)));
  out->set_gps_resets(static_cast<uint32_t>(std::max(0, p.gps_resets)));
  out->set_gps_outage_active(r.frame.in_outage);
  FillNoiseLearning(p, out->mutable_noise());
  out->set_processing_latency_ms(latency_ms);
  for (const pipeline::GpsFeed& f : r.frame.gps_feeds) {
    auto* g = out->add_gps_fixes();
    g->set_t_ns(f.fix.t_ns);
    g->set_latitude_deg(f.fix.lat_deg);
    g->set_longitude_deg(f.fix.lon_deg);
    g->set_altitude_m(f.fix.alt_m);
    g->set_sigma_horizontal_m(f.fix.horizontal_sigma_m());
    g->set_sigma_vertical_m(f.fix.vertical_sigma_m());
    g->set_used(f.update.used);
    g->set_rejected_vertical(f.update.rejected_vertical);
    g->set_nis(f.update.nis);
    g->set_gate(f.update.gate);
  }
  if (r.truth && r.truth->T_enu_body) {
    const Eigen::Isometry3d& T = *r.truth->T_enu_body;
    out->set_has_truth(true);
    auto* tp = out->mutable_truth_position_enu_m();
    tp->set_x(T.translation().x());
    tp->set_y(T.translation().y());
    tp->set_z(T.translation().z());
    const Eigen::Quaterniond tq(T.rotation());
    auto* to = out->mutable_truth_orientation_enu_body();
    to->set_w(tq.w());
    to->set_x(tq.x());
    to->set_y(tq.y());
    to->set_z(tq.z());
    out->set_truth_latitude_deg(r.truth->lat_deg);
    out->set_truth_longitude_deg(r.truth->lon_deg);
    out->set_truth_altitude_m(r.truth->alt_m);
    out->set_horizontal_error_m((t - T.translation()).head<2>().norm());
  }
}

}  // namespace locaid::output
