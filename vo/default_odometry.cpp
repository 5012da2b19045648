// "default" method: KLT feature tracking against a keyframe. Track reads as
// the algorithm; each stage is a method below (keyframe stages in
// default_keyframe.cpp, the list in default_odometry.hpp).
#include "vo/default_odometry.hpp"
#include "core/stereo_camera.hpp"
#include "vo/image_guard.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locaid::vo {
namespace detail {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

void CheckCamera(const StereoCamera& cam) {
  if (!(cam.fx > 0 && cam.fy > 0 && cam.baseline_m > 0 && cam.width > 0 && cam.height > 0))
    throw std::invalid_argument(
        "StereoCamera needs fx, fy, baseline_m, width, height > 0 (got fx " +
        std::to_string(cam.fx) + ", baseline " + std::to_string(cam.baseline_m) + ", " +
        std::to_string(cam.width) + "x" + std::to_string(cam.height) + ")");
}


}  // namespace

DefaultOdometry::DefaultOdometry(const StereoCamera& camera, const DefaultConfig& config)
    : cam_(camera), cfg_(config) {
  CheckCamera(cam_);
  K_ = (cv::Mat_<double>(3, 3) << cam_.fx, 0, cam_.cx, 0, cam_.fy, cam_.cy, 0, 0, 1);
}

RelativeMotion DefaultOdometry::Track(const StereoFrame& frame) {
  // Missing or unusable: identity, keyframe kept so tracking resumes after it.
  if (!FrameUsable(frame, cam_, cfg_.min_image_stddev)) return NoMotion(frame.t_ns, Status::kLost);
  RelativeMotion out;
  out.t_ns = frame.t_ns;
  StageTimer timer(out.timings, cfg_.timing_clock);
  const Images im = BuildPyramids(frame);
  timer.Stop("pyramid");
  if (!has_ref_) {
    StartAtOrigin(im, out, timer);
    return out;
  }

  const Eigen::Isometry3d T_ref_pred = PredictKeyframeToCurrent(frame.t_ns);
  const Tracks tracks = TrackKeyframeFeatures(im, T_ref_pred);
  timer.Stop("track");
  const std::vector<float> disparity = TrackedDisparities(im, tracks);
  timer.Stop("stereo");
  const std::optional<PoseRefinement> refined = EstimateMotion(tracks, disparity, T_ref_pred);
  if (!refined) return Fail(out, im);
  timer.Stop("motion");
  if (!refined->ok || refined->inliers < cfg_.min_inliers_degraded) return Fail(out, im);

  Inliers inliers = KeepInliers(tracks, disparity, *refined);
  const Eigen::Isometry3d T_ref_curr = SnapStandstill(*refined, inliers.median_flow_px);
  const Eigen::Isometry3d T_w_curr = UpdateKeyframe(im, std::move(inliers), T_w_ref_ * T_ref_curr, timer);
  Report(*refined, T_w_curr, frame.t_ns, out, timer);
  return out;
}

DefaultOdometry::Images DefaultOdometry::BuildPyramids(const StereoFrame& frame) const {
  Images im;
  im.left = ToGrey(frame.left);
  im.right = ToGrey(frame.right);
  const cv::Size win(cfg_.klt_window_px, cfg_.klt_window_px);
  cv::buildOpticalFlowPyramid(im.left, im.left_pyr, win, cfg_.klt_levels);
  cv::buildOpticalFlowPyramid(im.right, im.right_pyr, win, 1, false);
  return im;
}

void DefaultOdometry::StartAtOrigin(const Images& im, RelativeMotion& out, StageTimer& timer) {
  T_w_out_ = Eigen::Isometry3d::Identity();
  Restart(im);
  prev_t_ns_ = out.t_ns;
  timer.Stop("keyframe");
  out.status = ref_features_.size() >= static_cast<size_t>(cfg_.min_inliers_degraded) ? Status::kOk
                                                                                       : Status::kDegraded;
  out.inliers = static_cast<int>(ref_features_.size());
  out.covariance = Matrix6d::Identity() * 1e-12;  // the first frame defines the origin
  out.t_prev_ns = out.t_ns;
  out.total_ms = SumTimings(out.timings);
}

Eigen::Isometry3d DefaultOdometry::PredictKeyframeToCurrent(int64_t t_ns) const {
  double scale = 1.0;
  if (velocity_dt_ns_ > 0 && t_ns > prev_t_ns_)
    scale = std::clamp(static_cast<double>(t_ns - prev_t_ns_) / velocity_dt_ns_, 0.0, 5.0);
  const Eigen::Isometry3d T_ref_prev = T_w_ref_.inverse() * T_w_out_;
  return T_ref_prev * ScaleMotion(velocity_, scale);
}

DefaultOdometry::Tracks DefaultOdometry::TrackKeyframeFeatures(const Images& im,
                                                               const Eigen::Isometry3d& T_ref_pred) const {
  const Eigen::Isometry3d T_pred_ref = T_ref_pred.inverse();
  Tracks t;
  std::vector<cv::Point2f> curr_uv;
  t.ref_uv.reserve(ref_features_.size());
  for (const Feature& f : ref_features_) {
    t.ref_uv.push_back(f.uv);
    const Eigen::Vector3d q = T_pred_ref * f.p_ref;
    cv::Point2f guess = f.uv;
    float disp = -1;
    if (q.z() > 0.5) {
      // KLT start: the predicted point, or only the predicted rotation of it.
      const Eigen::Vector3d g = cfg_.klt_guess_translation ? q : Eigen::Vector3d(T_pred_ref.linear() * f.p_ref);
      if (g.z() > 0.5) {
        const cv::Point2f proj(static_cast<float>(cam_.fx * g.x() / g.z() + cam_.cx),
                               static_cast<float>(cam_.fy * g.y() / g.z() + cam_.cy));
        if (Inside(proj, im.left.size(), 0)) guess = proj;
      }
      disp = static_cast<float>(cam_.fx * cam_.baseline_m / q.z());
    }
    curr_uv.push_back(guess);
    t.predicted_disparity.push_back(disp);
  }
  const cv::Size win(cfg_.klt_window_px, cfg_.klt_window_px);
  std::vector<uchar> status;
  std::vector<float> err;
  if (!t.ref_uv.empty())
    cv::calcOpticalFlowPyrLK(ref_pyramid_, im.left_pyr, t.ref_uv, curr_uv, status, err, win, cfg_.klt_levels,
                             kKltCriteria, cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> back;
  for (size_t i = 0; i < t.ref_uv.size(); ++i)
    if (status[i] && Inside(curr_uv[i], im.left.size(), 2.f)) {
      t.idx.push_back(i);
      t.uv.push_back(curr_uv[i]);
      back.push_back(t.ref_uv[i]);
    }
  if (cfg_.max_forward_backward_px <= 0 || t.uv.empty()) return t;
  // Forward-backward check: tracked back into the keyframe, it must land where it started.
  std::vector<uchar> st2;
  cv::calcOpticalFlowPyrLK(im.left_pyr, ref_pyramid_, t.uv, back, st2, err, win, 1, kKltCriteria,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  size_t k = 0;
  for (size_t j = 0; j < t.uv.size(); ++j) {
    const cv::Point2f d = back[j] - t.ref_uv[t.idx[j]];
    if (!st2[j] || d.dot(d) > cfg_.max_forward_backward_px * cfg_.max_forward_backward_px) continue;
    t.idx[k] = t.idx[j];
    t.uv[k] = t.uv[j];
    ++k;
  }
  t.idx.resize(k);
  t.uv.resize(k);
  return t;
}

std::vector<float> DefaultOdometry::TrackedDisparities(const Images& im, const Tracks& tracks) const {
  std::vector<float> seeds(tracks.idx.size());
  for (size_t j = 0; j < tracks.idx.size(); ++j) seeds[j] = tracks.predicted_disparity[tracks.idx[j]];
  return StereoDisparities(im, tracks.uv, &seeds);
}

std::optional<PoseRefinement> DefaultOdometry::EstimateMotion(const Tracks& tracks,
                                                              const std::vector<float>& disparity,
                                                              const Eigen::Isometry3d& T_ref_pred) const {
  std::vector<StereoObservation> obs(tracks.idx.size());
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (size_t j = 0; j < tracks.idx.size(); ++j) {
    const Feature& f = ref_features_[tracks.idx[j]];
    const cv::Point2f& uv = tracks.uv[j];
    obs[j].p_ref = f.p_ref;
    obs[j].uv_left = {uv.x, uv.y};
    obs[j].has_right = disparity[j] > 0;
    obs[j].u_right = uv.x - disparity[j];
    if (cfg_.symmetric_residuals && obs[j].has_right) {
      // Reverse term: the current stereo point seen in the keyframe's images.
      obs[j].has_reverse = true;
      obs[j].p_curr = TriangulateStereo(cam_, uv.x, uv.y, obs[j].u_right);
      obs[j].uv_ref_left = {f.uv.x, f.uv.y};
      obs[j].u_ref_right = f.u_right;
    }
    object.emplace_back(static_cast<float>(f.p_ref.x()), static_cast<float>(f.p_ref.y()),
                        static_cast<float>(f.p_ref.z()));
    image.push_back(uv);
  }
  if (static_cast<int>(obs.size()) < cfg_.min_inliers_degraded) return std::nullopt;
  // RANSAC start; the prediction when it finds nothing.
  Eigen::Isometry3d T_init = T_ref_pred;
  cv::Mat rvec, tvec;
  std::vector<int> ransac_inliers;
  bool found = false;
  try {
    found = cv::solvePnPRansac(object, image, K_, cv::noArray(), rvec, tvec, false, cfg_.ransac_iterations,
                               static_cast<float>(cfg_.ransac_threshold_px), 0.99, ransac_inliers,
                               cv::SOLVEPNP_P3P);
  } catch (const cv::Exception&) {
    found = false;
  }
  if (found && static_cast<int>(ransac_inliers.size()) >= cfg_.min_inliers_degraded) {
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Eigen::Isometry3d T_curr_ref = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T_curr_ref.linear()(r, c) = R.at<double>(r, c);
      T_curr_ref.translation()(r) = tvec.at<double>(r);
    }
    if (IsFinite(T_curr_ref)) T_init = T_curr_ref.inverse();
  }
  RefineOptions ro;
  ro.huber_px = cfg_.huber_px;
  ro.outlier_px = cfg_.outlier_px;
  return RefineStereoPose(obs, cam_, T_init, ro);
}

DefaultOdometry::Inliers DefaultOdometry::KeepInliers(const Tracks& tracks, const std::vector<float>& disparity,
                                                      const PoseRefinement& refined) const {
  Inliers out;
  std::vector<double> flow;
  for (size_t j = 0; j < tracks.idx.size(); ++j) {
    if (!refined.inlier[j]) continue;
    const cv::Point2f& uv = tracks.uv[j];
    flow.push_back(cv::norm(uv - tracks.ref_uv[tracks.idx[j]]));
    if (disparity[j] > 0) {
      Feature f = ref_features_[tracks.idx[j]];
      f.uv = uv;
      f.u_right = uv.x - disparity[j];
      f.p_ref = TriangulateStereo(cam_, uv.x, uv.y, f.u_right);
      out.kept.push_back(f);
    }
  }
  out.median_flow_px = Median(flow);
  return out;
}

Eigen::Isometry3d DefaultOdometry::SnapStandstill(const PoseRefinement& refined, double median_flow_px) const {
  const double t_sigma = std::sqrt(refined.covariance.topLeftCorner<3, 3>().trace());
  if (median_flow_px < cfg_.standstill_flow_px && refined.T_ref_curr.translation().norm() < 3 * t_sigma)
    return Eigen::Isometry3d::Identity();
  return refined.T_ref_curr;
}

Eigen::Isometry3d DefaultOdometry::UpdateKeyframe(const Images& im, Inliers inliers, Eigen::Isometry3d T_w_curr,
                                                  StageTimer& timer) {
  const bool moved = inliers.median_flow_px > cfg_.keyframe_flow_px;
  const bool few = inliers.kept.size() < ref_features_.size() / 2;
  if (!moved && !few) return T_w_curr;
  if (WindowOn()) {
    T_w_curr = SolveWindowWith(inliers.kept, T_w_curr);
    timer.Stop("window");
  }
  MakeKeyframe(im, std::move(inliers.kept), T_w_curr, &timer);
  return T_w_curr;
}

void DefaultOdometry::Report(const PoseRefinement& refined, const Eigen::Isometry3d& T_w_curr, int64_t t_ns,
                             RelativeMotion& out, StageTimer& timer) {
  out.T_prev_curr = T_w_out_.inverse() * T_w_curr;
  out.t_prev_ns = prev_t_ns_;
  T_w_out_ = T_w_curr;
  out.covariance = refined.covariance;
  out.inliers = refined.inliers;
  out.status = refined.inliers >= cfg_.min_inliers_ok ? Status::kOk : Status::kDegraded;
  if (t_ns > prev_t_ns_) {
    velocity_ = out.T_prev_curr;
    velocity_dt_ns_ = t_ns - prev_t_ns_;
  }
  prev_t_ns_ = t_ns;
  timer.Stop("keyframe");
  out.total_ms = SumTimings(out.timings);
}

RelativeMotion DefaultOdometry::Fail(RelativeMotion out, const Images& im) {
  const StageTimings timings = out.timings;
  const int64_t t_ns = out.t_ns;
  out = NoMotion(t_ns, Status::kLost);
  out.timings = timings;
  StageTimer timer(out.timings, cfg_.timing_clock);
  Restart(im);
  velocity_ = Eigen::Isometry3d::Identity();
  velocity_dt_ns_ = 0;
  prev_t_ns_ = t_ns;
  timer.Stop("keyframe");
  out.total_ms = SumTimings(out.timings);
  return out;
}

}  // namespace detail

std::unique_ptr<StereoOdometry> MakeDefaultOdometry(const StereoCamera& camera,
                                                    const DefaultConfig& config) {
  ImageGuardConfig guard;
  guard.min_image_stddev = config.min_image_stddev;
  guard.min_dark_snr = config.min_dark_snr;
  return std::make_unique<GuardedOdometry>(std::make_unique<detail::DefaultOdometry>(camera, config), guard);
}

}  // namespace locaid::vo
