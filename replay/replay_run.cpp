#include "replay/replay_run.hpp"

#include "kitti/oxts_pose.hpp"

#include <algorithm>
#include <fstream>
#include <iomanip>
#include <stdexcept>

namespace locaid::pipeline {

std::optional<Eigen::Isometry3d> ReplayRun::TruthAt(int64_t t_ns) const {
  if (!gt_enu_) return std::nullopt;
  return kitti::InterpolatePose(gt_poses_, t_ns, static_cast<int64_t>(0.5e9));
}

void ReplayRun::Add(const StepResult& step) {
  const FrameResult& r = step.frame;
  const fusion::Ekf& ekf = localizer_.ekf();
  vo_ms_total_ += r.vo_ms;
  const bool vo_lost = r.vo.status == vo::Status::kLost;
  if (vo_lost) ++lost_frames_;
  if (dataset_ && !gt_enu_ && localizer_.enu().has_origin()) {
    const auto& e = localizer_.enu();
    gt_enu_.emplace(e.origin_lat_deg(), e.origin_lon_deg(), e.origin_alt_m());
    for (const auto& s : dataset_->oxts()) gt_poses_.push_back({s.t_ns, kitti::OxtsToEnuPose(s.record, *gt_enu_)});
  }
  if (!vo_lost && step.frame_index > 0) {
    const auto g0 = TruthAt(r.vo_body.t_prev_ns), g1 = TruthAt(r.vo_body.t_ns);
    if (g0 && g1)
      vo_pairs_.push_back({r.vo_body.T_prev_curr, g0->inverse() * *g1, r.vo_body.covariance,
                           ekf.VoNoise(r.vo_body.covariance, r.vo_body.T_prev_curr), r.in_outage});
  }
  vo_motion_.push_back(vo_lost ? Eigen::Isometry3d::Identity() : r.vo_body.T_prev_curr);

  ReplaySample s;
  if (!t0_ns_) t0_ns_ = dataset_ ? dataset_->time_ns(0) : step.t_ns;
  s.t_s = static_cast<double>(step.t_ns - *t0_ns_) * 1e-9;
  s.initialized = ekf.initialized();
  s.mode = r.pose.mode;
  s.in_outage = r.in_outage;
  s.p_enu_est_m = r.pose.T_enu_body.translation();
  s.P_pos_m2 = r.pose.covariance.topLeftCorner<3, 3>();
  const auto gt = TruthAt(step.t_ns);
  s.has_gt = gt.has_value();  // without ground truth: left out of the metrics
  if (gt) s.p_enu_gt_m = gt->translation();
  samples_.push_back(s);

  PlotExtras extra;
  extra.vo_health = vo::ToString(r.vo.health);
  ++vo_health_counts_[extra.vo_health];
  ++mode_counts_[fusion::ToString(r.pose.mode)];
  for (const auto& f : r.gps_feeds) {
    fixes_.push_back(f.fix);
    extra.p_enu_gps_m = f.p_enu_m;
    extra.gps_rejected = extra.gps_rejected || f.update.rejected;
    if (f.update.buffered) continue;  // before initialisation
    rejection_run_ = f.update.rejected ? rejection_run_ + 1 : 0;
    rejection_run_v_ = f.update.rejected_vertical ? rejection_run_v_ + 1 : 0;
    max_rejection_run_ = std::max(max_rejection_run_, rejection_run_);
    max_rejection_run_v_ = std::max(max_rejection_run_v_, rejection_run_v_);
  }
  // Ground truth at the time of the fix the CSV shows (the last one fed).
  if (!r.gps_feeds.empty()) {
    if (auto g = TruthAt(r.gps_feeds.back().fix.t_ns)) extra.p_enu_gt_at_gps_m = g->translation();
  }
  extras_.push_back(extra);
  if (keep_poses_) {
    poses_.push_back(r.pose);
    epochs_.push_back(r.epoch);
  }
  frame_index_.push_back(step.frame_index);
  t_ns_.push_back(step.t_ns);
  T_enu_body_.push_back(r.pose.T_enu_body);
  last_ = r;
}

void ReplayRun::ApplySmoothed(const std::vector<fusion::FusedPose>& smoothed) {
  if (smoothed.size() != samples_.size())
    throw std::logic_error("ReplayRun::ApplySmoothed: " + std::to_string(smoothed.size()) + " poses for " +
                           std::to_string(samples_.size()) + " frames");
  smoothed_samples_ = samples_;
  T_enu_body_smoothed_.clear();
  for (size_t k = 0; k < smoothed.size(); ++k) {
    smoothed_samples_[k].p_enu_est_m = smoothed[k].T_enu_body.translation();
    smoothed_samples_[k].P_pos_m2 = smoothed[k].covariance.topLeftCorner<3, 3>();
    T_enu_body_smoothed_.push_back(smoothed[k].T_enu_body);
  }
}

void ReplayRun::WriteCsv(const std::string& path) const {
  // VO-only track: the raw VO chained in ENU from the ground-truth pose of frame 0.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (dataset_ && gt_enu_ && !dataset_->oxts().empty()) {
    T = TruthAt(std::max(dataset_->time_ns(0), dataset_->oxts().front().t_ns)).value_or(Eigen::Isometry3d::Identity());
  } else if (!T_enu_body_.empty()) {
    // Without ground truth: from the first initialised fused pose.
    for (size_t k = 0; k < samples_.size(); ++k) {
      if (samples_[k].initialized) {
        T = T_enu_body_[k];
        break;
      }
    }
  }
  std::vector<PlotExtras> extras = extras_;
  for (size_t k = 0; k < extras.size(); ++k) {
    if (k > 0) T = T * vo_motion_[k];
    extras[k].p_enu_vo_m = T.translation();
  }
  WritePlotCsv(path, smoothed() ? smoothed_samples_ : samples_, extras);
}

void ReplayRun::WriteTum(const std::string& path) const {
  std::ofstream tum(path);
  if (!tum) throw std::runtime_error(path + ": cannot write");
  tum << std::fixed << std::setprecision(6);
  for (size_t k = 0; k < samples_.size(); ++k) {
    if (!samples_[k].initialized) continue;  // a pose without ground truth is still written
    const Eigen::Isometry3d& T = smoothed() ? T_enu_body_smoothed_[k] : T_enu_body_[k];
    const Eigen::Quaterniond q(T.linear());
    const double t_s = dataset_ ? dataset_->tum_time_s(static_cast<size_t>(frame_index_[k]))
                                : static_cast<double>(t_ns_[k]) * 1e-9;
    tum << t_s << ' ' << T.translation().x() << ' '
        << T.translation().y() << ' ' << T.translation().z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' '
        << q.w() << '\n';
  }
  if (!tum.flush()) throw std::runtime_error(path + ": write failed");
}

void ReplayRun::WriteFixes(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << "t_ns,lat_deg,lon_deg,alt_m,sigma_h_m,sigma_v_m\n" << std::setprecision(12);
  for (const auto& f : fixes_) {
    out << f.t_ns << ',' << f.lat_deg << ',' << f.lon_deg << ',' << f.alt_m << ',' << f.horizontal_sigma_m() << ','
        << f.vertical_sigma_m() << '\n';
  }
  if (!out.flush()) throw std::runtime_error(path + ": write failed");
}

nlohmann::json ReplayRun::Summary(const ReplayMetrics& metrics, double wall_s) const {
  const fusion::Ekf& ekf = localizer_.ekf();
  const double frames = static_cast<double>(samples_.size());
  nlohmann::json j;
  j["frames"] = samples_.size();
  j["rmse_gps_m"] = metrics.rmse_gps_m;
  j["nees_mean"] = metrics.nees_mean;
  j["nees_bound_99"] = metrics.nees_bound_99;
  j["nees_mean_after_30s"] = metrics.nees_frames_after_30s ? nlohmann::json(metrics.nees_mean_after_30s)
                                                           : nlohmann::json(nullptr);
  j["nees_bound_99_after_30s"] = metrics.nees_bound_99_after_30s;
  j["max_vertical_error_m"] = metrics.max_vertical_error_m;
  j["frames_per_s"] = frames / wall_s;
  j["vo_ms_mean"] = vo_ms_total_ / std::max(1.0, frames);
  j["vo_lost_frames"] = lost_frames_;
  j["vo_rejected_by_gate"] = ekf.stats().vo_rejected;
  j["gps_used"] = last_.pose.gps_used;
  j["gps_rejected"] = last_.pose.gps_rejected;
  j["gps_rejected_vertical"] = ekf.stats().gps_rejected_vertical;
  j["gps_resets"] = last_.pose.gps_resets;
  const auto& vo_scale = ekf.vo_noise_scale();
  j["noise"] = {{"vo_scale", std::vector<double>(vo_scale.data(), vo_scale.data() + 6)},
                {"gps_scale_horizontal", ekf.gps_noise_scale_horizontal()},
                {"gps_scale_vertical", ekf.gps_noise_scale_vertical()}};
  j["max_gps_rejection_run"] = max_rejection_run_;
  j["max_gps_rejection_run_vertical"] = max_rejection_run_v_;
  const auto vo_err = ComputeVoErrorStats(vo_pairs_);
  auto vec6 = [](const Eigen::Matrix<double, 6, 1>& v) { return std::vector<double>(v.data(), v.data() + 6); };
  j["vo_error"] = {{"frames", vo_err.frames},
                   {"rms_error_t_m_r_rad", vec6(vo_err.rms_error)},
                   {"rms_reported_sigma", vec6(vo_err.rms_sigma)},
                   {"nees6_mean_reported_cov", vo_err.nees_mean},
                   {"nees6_median_reported_cov", vo_err.nees_median},
                   {"rms_model_sigma", vec6(vo_err.rms_model_sigma)},
                   {"nees6_mean_model", vo_err.nees_mean_model},
                   {"nees6_median_model", vo_err.nees_median_model},
                   {"nees6_mean_model_gps_good", vo_err.nees_mean_model_gps_good},
                   {"frames_in_outage", vo_err.frames_in_outage},
                   {"nees6_mean_model_in_outage", vo_err.frames_in_outage > 0
                                                      ? nlohmann::json(vo_err.nees_mean_model_in_outage)
                                                      : nlohmann::json(nullptr)}};
  const fusion::EkfStats& st = ekf.stats();
  j["vehicle"] = {{"speed_used", st.speed_used},
                  {"speed_rejected", st.speed_rejected},
                  {"speed_scale_error", ekf.speed_scale_error()},
                  {"zupt_updates", st.zupt_updates},
                  {"nhc_updates", st.nhc_updates},
                  {"constraints", !ekf.config().vehicle.constraints        ? "off"
                                  : ekf.config().vehicle.constraints_need_speed ? "auto"
                                                                                : "on"}};
  j["modes"] = mode_counts_;
  j["vo_health"] = vo_health_counts_;
  j["outages"] = OutagesJson(metrics.outages);
  if (smoothed()) {
    const ReplayMetrics sm = SmoothedMetrics();
    j["smoothed"] = {{"rmse_gps_m", sm.rmse_gps_m},
                     {"nees_mean", sm.nees_mean},
                     {"nees_bound_99", sm.nees_bound_99},
                     {"max_vertical_error_m", sm.max_vertical_error_m},
                     {"outages", OutagesJson(sm.outages)}};
  }
  return j;
}

nlohmann::json OutagesJson(const std::vector<OutageStats>& outages) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& o : outages) {
    out.push_back({{"start_s", o.start_s}, {"duration_s", o.duration_s}, {"distance_m", o.distance_m},
                   {"end_error_m", o.end_error_m}, {"end_error_pct", o.end_error_pct},
                   {"max_error_m", o.max_error_m}, {"rmse_m", o.rmse_m}, {"reconverge_s", o.reconverge_s},
                   {"max_jump_m", o.max_jump_m}, {"start_error_m", o.start_error_m},
                   {"added_error_m", o.added_error_m}, {"added_error_pct", o.added_error_pct}});
  }
  return out;
}

}  // namespace locaid::pipeline
