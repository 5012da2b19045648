// "default" method: KLT feature tracking against a keyframe.
//
// Track(frame) = validate -> pyramids -> track keyframe features into the left
// image (KLT seeded by a constant-velocity prediction, forward-backward check)
// -> stereo KLT left->right (seeded by the predicted disparity) -> P3P RANSAC
// -> Huber Gauss-Newton on the reprojection error in BOTH current images ->
// standstill snap -> keyframe update (bucketing with feature ageing, new FAST
// corners, row-search + KLT sub-pixel disparity).
#include "vo/odometry_common.hpp"
#include "vo/stereo_geometry.hpp"
#include "vo/stereo_odometry.hpp"
#include "vo/window_ba.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace locaid::vo {
namespace {

struct Feature {
  cv::Point2f uv;           // in the keyframe left image
  float u_right = 0;        // its stereo match in the keyframe right image
  Eigen::Vector3d p_ref;    // in the keyframe cam0 frame (stereo, or the window's estimate)
  int age = 0;              // keyframes it has survived
  int64_t id = -1;          // landmark id in the window
};

// A point of the sliding window: its position and its observations, each in
// the keyframe with that sequence number.
struct Landmark {
  struct Observation {
    int64_t keyframe = 0;
    Eigen::Vector2d uv_left;
    double u_right = 0;
  };
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  std::vector<Observation> observations;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

bool Inside(const cv::Point2f& p, const cv::Size& size, float margin) {
  return p.x >= margin && p.y >= margin && p.x < size.width - 1 - margin &&
         p.y < size.height - 1 - margin;
}

void CheckCamera(const kitti::StereoCamera& cam) {
  if (!(cam.fx > 0 && cam.fy > 0 && cam.baseline_m > 0 && cam.width > 0 && cam.height > 0))
    throw std::invalid_argument(
        "StereoCamera needs fx, fy, baseline_m, width, height > 0 (got fx " +
        std::to_string(cam.fx) + ", baseline " + std::to_string(cam.baseline_m) + ", " +
        std::to_string(cam.width) + "x" + std::to_string(cam.height) + ")");
}

class DefaultOdometry final : public StereoOdometry {
 public:
  DefaultOdometry(const kitti::StereoCamera& camera, const DefaultConfig& config)
      : cam_(camera), cfg_(config) {
    CheckCamera(cam_);
    K_ = (cv::Mat_<double>(3, 3) << cam_.fx, 0, cam_.cx, 0, cam_.fy, cam_.cy, 0, 0, 1);
  }

  RelativeMotion Track(const StereoFrame& frame) override;
  void Reset() override {
    has_ref_ = false;
    ref_features_.clear();
    ref_pyramid_.clear();
    ClearWindow();
  }

 private:
  struct Images {
    cv::Mat left, right;
    std::vector<cv::Mat> left_pyr, right_pyr;
  };

  // The current frame (at T_w_c) becomes the keyframe: kept features plus new
  // corners, which become window landmarks when the window is on.
  void MakeKeyframe(const Images& im, std::vector<Feature> kept, const Eigen::Isometry3d& T_w_c,
                    StageTimer* timer = nullptr);
  // A keyframe with fresh features only, at the last reported pose, as the
  // window's first keyframe (first frame, or after losing track).
  void Restart(const Images& im) {
    ClearWindow();
    if (WindowOn()) PushWindowKeyframe(T_w_out_);
    MakeKeyframe(im, {}, T_w_out_);
  }
  bool WindowOn() const { return cfg_.window_keyframes >= 2; }
  void ClearWindow() {
    window_.clear();
    landmarks_.clear();
  }
  // Appends a keyframe at T_w_c, dropping the oldest beyond the window size.
  void PushWindowKeyframe(const Eigen::Isometry3d& T_w_c);
  // Adds the kept features' observations in a new keyframe at T_w_c, solves the
  // window and returns the refined pose of that keyframe; outliers leave `kept`,
  // and the others take the window's point estimate.
  Eigen::Isometry3d SolveWindowWith(std::vector<Feature>& kept, const Eigen::Isometry3d& T_w_c);
  std::vector<cv::Point2f> DetectInBuckets(const cv::Mat& left, const cv::Mat* left_half,
                                           const std::vector<Feature>& kept) const;
  // Row search (SAD) for a first disparity, then KLT sub-pixel; -1 when none.
  std::vector<float> StereoDisparities(const Images& im, const std::vector<cv::Point2f>& uv,
                                       const std::vector<float>* predicted) const;
  RelativeMotion Fail(RelativeMotion out, const Images& im);

  kitti::StereoCamera cam_;
  DefaultConfig cfg_;
  cv::Mat K_;
  bool has_ref_ = false;
  std::vector<cv::Mat> ref_pyramid_;
  std::vector<Feature> ref_features_;
  // Poses in the odometry frame (first frame = origin): the keyframe's and
  // the last reported one's; T_prev_curr is reported between the latter and
  // the current pose, so window corrections of past keyframes are carried on.
  Eigen::Isometry3d T_w_ref_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_w_out_ = Eigen::Isometry3d::Identity();
  struct WindowKeyframe {
    int64_t seq = 0;
    Eigen::Isometry3d T_w_c = Eigen::Isometry3d::Identity();
  };
  std::deque<WindowKeyframe> window_;
  std::unordered_map<int64_t, Landmark> landmarks_;
  int64_t next_keyframe_seq_ = 0;
  int64_t next_landmark_id_ = 0;
  Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();  // last T_prev_curr
  int64_t velocity_dt_ns_ = 0;
  int64_t prev_t_ns_ = 0;
};

std::vector<cv::Point2f> DefaultOdometry::DetectInBuckets(const cv::Mat& left,
                                                          const cv::Mat* left_half,
                                                          const std::vector<Feature>& kept) const {
  const float cell_w = static_cast<float>(cam_.width) / cfg_.grid_cols;
  const float cell_h = static_cast<float>(cam_.height) / cfg_.grid_rows;
  const auto cell_of = [&](const cv::Point2f& p) {
    const int cx = std::clamp(static_cast<int>(p.x / cell_w), 0, cfg_.grid_cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y / cell_h), 0, cfg_.grid_rows - 1);
    return cy * cfg_.grid_cols + cx;
  };
  std::vector<int> count(static_cast<size_t>(cfg_.grid_cols * cfg_.grid_rows), 0);
  cv::Mat free_mask(left.size(), CV_8UC1, cv::Scalar(255));
  for (const Feature& f : kept) {
    ++count[static_cast<size_t>(cell_of(f.uv))];
    cv::circle(free_mask, f.uv, cfg_.min_feature_distance_px, cv::Scalar(0), -1);
  }
  std::vector<cv::KeyPoint> corners;
  if (cfg_.detect_half_resolution && left_half && !left_half->empty()) {
    cv::FAST(*left_half, corners, cfg_.fast_threshold, true);
    for (cv::KeyPoint& kp : corners) kp.pt *= 2.0f;
  } else {
    cv::FAST(left, corners, cfg_.fast_threshold, true);
  }
  std::sort(corners.begin(), corners.end(),
            [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  const float margin = static_cast<float>(cfg_.klt_window_px);
  std::vector<cv::Point2f> added;
  for (const cv::KeyPoint& kp : corners) {
    if (!Inside(kp.pt, left.size(), margin)) continue;
    const int cell = cell_of(kp.pt);
    if (count[static_cast<size_t>(cell)] >= cfg_.max_features_per_cell) continue;
    if (!free_mask.at<uchar>(cvRound(kp.pt.y), cvRound(kp.pt.x))) continue;
    ++count[static_cast<size_t>(cell)];
    cv::circle(free_mask, kp.pt, cfg_.min_feature_distance_px, cv::Scalar(0), -1);
    added.push_back(kp.pt);
  }
  return added;
}

std::vector<float> DefaultOdometry::StereoDisparities(const Images& im,
                                                      const std::vector<cv::Point2f>& uv,
                                                      const std::vector<float>* predicted) const {
  std::vector<float> disparity(uv.size(), -1.f);
  if (uv.empty()) return disparity;
  std::vector<cv::Point2f> right(uv.size());
  const int h = cfg_.stereo_search_half_patch;
  const int max_d = static_cast<int>(cfg_.max_disparity_px);
  // New corners: SAD row search on pyramid level 1 (half resolution), with a
  // uniqueness test; tracked ones: the predicted disparity.
  const cv::Mat& left1 = im.left_pyr[2];    // level 1 (left pyramid holds derivatives)
  const cv::Mat& right1 = im.right_pyr[1];  // level 1
  std::vector<int> cost;
  for (size_t i = 0; i < uv.size(); ++i) {
    right[i] = uv[i];
    if (predicted && (*predicted)[i] > 0) {
      right[i] = {uv[i].x - (*predicted)[i], uv[i].y};
      continue;
    }
    const int u = cvRound(uv[i].x * 0.5f), v = cvRound(uv[i].y * 0.5f);
    if (u - h < 0 || v - h < 0 || u + h >= left1.cols || v + h >= left1.rows) continue;
    const int d_hi = std::min(max_d / 2, u - h);
    cost.assign(static_cast<size_t>(d_hi + 1), 0);
    for (int d = 0; d <= d_hi; ++d) {
      int sad = 0;
      for (int dy = -h; dy <= h; ++dy) {
        const uchar* l = left1.ptr<uchar>(v + dy) + (u - h);
        const uchar* r = right1.ptr<uchar>(v + dy) + (u - d - h);
        for (int dx = 0; dx <= 2 * h; ++dx) sad += std::abs(l[dx] - r[dx]);
      }
      cost[static_cast<size_t>(d)] = sad;
    }
    const auto best_it = std::min_element(cost.begin(), cost.end());
    const int best_d = static_cast<int>(best_it - cost.begin());
    int second = std::numeric_limits<int>::max();
    for (int d = 0; d <= d_hi; ++d)
      if (std::abs(d - best_d) > 1) second = std::min(second, cost[static_cast<size_t>(d)]);
    if (static_cast<double>(second) < cfg_.stereo_uniqueness * *best_it) continue;
    right[i] = {uv[i].x - 2.0f * static_cast<float>(best_d), uv[i].y};
  }
  std::vector<uchar> status;
  std::vector<float> err;
  const cv::Size win(cfg_.klt_window_px, cfg_.klt_window_px);
  cv::calcOpticalFlowPyrLK(im.left_pyr, im.right_pyr, uv, right, status, err, win,
                           predicted ? cfg_.stereo_klt_levels_tracked : 1,
                           cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.01),
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  for (size_t i = 0; i < uv.size(); ++i) {
    if (!status[i]) continue;
    const float d = uv[i].x - right[i].x;
    if (std::abs(right[i].y - uv[i].y) > cfg_.stereo_max_dy_px) continue;
    if (d < cfg_.min_disparity_px || d > cfg_.max_disparity_px) continue;
    disparity[i] = d;
  }
  return disparity;
}

void DefaultOdometry::MakeKeyframe(const Images& im, std::vector<Feature> kept,
                                   const Eigen::Isometry3d& T_w_c, StageTimer* timer) {
  // Bucketing with ageing: keep the oldest features of each cell.
  std::stable_sort(kept.begin(), kept.end(),
                   [](const Feature& a, const Feature& b) { return a.age > b.age; });
  const float cell_w = static_cast<float>(cam_.width) / cfg_.grid_cols;
  const float cell_h = static_cast<float>(cam_.height) / cfg_.grid_rows;
  std::vector<int> count(static_cast<size_t>(cfg_.grid_cols * cfg_.grid_rows), 0);
  std::vector<Feature> features;
  for (Feature& f : kept) {
    const int cx = std::clamp(static_cast<int>(f.uv.x / cell_w), 0, cfg_.grid_cols - 1);
    const int cy = std::clamp(static_cast<int>(f.uv.y / cell_h), 0, cfg_.grid_rows - 1);
    int& c = count[static_cast<size_t>(cy * cfg_.grid_cols + cx)];
    if (c >= cfg_.max_features_per_cell) continue;
    ++c;
    ++f.age;
    features.push_back(f);
  }
  const std::vector<cv::Point2f> added = DetectInBuckets(im.left, &im.left_pyr[2], features);
  if (timer) timer->Stop("detect");
  const std::vector<float> disparity = StereoDisparities(im, added, nullptr);
  for (size_t i = 0; i < added.size(); ++i) {
    if (disparity[i] <= 0) continue;
    Feature f;
    f.uv = added[i];
    f.u_right = added[i].x - disparity[i];
    f.p_ref = TriangulateStereo(cam_, added[i].x, added[i].y, f.u_right);
    f.id = next_landmark_id_++;
    if (WindowOn() && !window_.empty()) {
      Landmark& lm = landmarks_[f.id];
      lm.p_w = T_w_c * f.p_ref;
      lm.observations.push_back({window_.back().seq, {f.uv.x, f.uv.y}, f.u_right});
    }
    features.push_back(f);
  }
  ref_features_ = std::move(features);
  ref_pyramid_ = im.left_pyr;
  T_w_ref_ = T_w_c;
  has_ref_ = true;
}

void DefaultOdometry::PushWindowKeyframe(const Eigen::Isometry3d& T_w_c) {
  window_.push_back({next_keyframe_seq_++, T_w_c});
  if (static_cast<int>(window_.size()) <= cfg_.window_keyframes) return;
  window_.pop_front();
  const int64_t first = window_.front().seq;
  for (auto it = landmarks_.begin(); it != landmarks_.end();) {
    auto& obs = it->second.observations;
    obs.erase(std::remove_if(obs.begin(), obs.end(),
                             [first](const Landmark::Observation& o) { return o.keyframe < first; }),
              obs.end());
    it = obs.empty() ? landmarks_.erase(it) : std::next(it);
  }
}

Eigen::Isometry3d DefaultOdometry::SolveWindowWith(std::vector<Feature>& kept,
                                                   const Eigen::Isometry3d& T_w_c) {
  PushWindowKeyframe(T_w_c);
  const int64_t seq = window_.back().seq;
  for (const Feature& f : kept) {
    const auto it = landmarks_.find(f.id);
    if (it == landmarks_.end()) continue;  // its first keyframe left the window: not tracked on
    it->second.observations.push_back({seq, {f.uv.x, f.uv.y}, f.u_right});
  }
  WindowProblem problem;
  const int64_t first = window_.front().seq;
  for (const WindowKeyframe& k : window_) problem.T_w_c.push_back(k.T_w_c);
  std::vector<int64_t> ids;
  ids.reserve(landmarks_.size());
  for (const auto& [id, lm] : landmarks_) {
    const int point = static_cast<int>(problem.p_w.size());
    problem.p_w.push_back(lm.p_w);
    ids.push_back(id);
    for (const Landmark::Observation& o : lm.observations) {
      WindowObservation w;
      w.frame = static_cast<int>(o.keyframe - first);
      w.point = point;
      w.uv_left = o.uv_left;
      w.u_right = o.u_right;
      w.has_right = true;
      problem.observations.push_back(w);
    }
  }
  WindowOptions options;
  options.iterations = cfg_.window_iterations;
  options.huber_px = cfg_.huber_px;
  options.outlier_px = cfg_.outlier_px;
  const WindowResult result = SolveWindow(problem, cam_, options);
  if (!result.ok) return T_w_c;
  // Write back; an outlier observation is dropped, and a point whose newest
  // observation is an outlier is no longer tracked.
  for (size_t k = 0; k < window_.size(); ++k) window_[k].T_w_c = problem.T_w_c[k];
  size_t i = 0;
  std::unordered_map<int64_t, char> newest_outlier;
  for (size_t point = 0; point < ids.size(); ++point) {
    Landmark& lm = landmarks_[ids[point]];
    lm.p_w = problem.p_w[point];
    std::vector<Landmark::Observation> good;
    for (const Landmark::Observation& o : lm.observations) {
      if (!result.outlier[i]) good.push_back(o);
      else if (o.keyframe == seq) newest_outlier[ids[point]] = 1;
      ++i;
    }
    lm.observations = std::move(good);
  }
  const Eigen::Isometry3d T_w_curr = window_.back().T_w_c;
  const Eigen::Isometry3d T_curr_w = T_w_curr.inverse();
  std::vector<Feature> inliers;
  for (Feature& f : kept) {
    const auto it = landmarks_.find(f.id);
    if (it == landmarks_.end() || newest_outlier.count(f.id)) continue;
    if (it->second.observations.size() >= 2) f.p_ref = T_curr_w * it->second.p_w;
    inliers.push_back(f);
  }
  kept = std::move(inliers);
  return T_w_curr;
}

RelativeMotion DefaultOdometry::Fail(RelativeMotion out, const Images& im) {
  // Re-initialise on this frame so tracking resumes on the next one.
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

RelativeMotion DefaultOdometry::Track(const StereoFrame& frame) {
  // Missing or unusable: identity, keyframe kept so tracking resumes after it.
  if (!FrameUsable(frame, cam_, cfg_.min_image_stddev)) return NoMotion(frame.t_ns, Status::kLost);
  RelativeMotion out;
  out.t_ns = frame.t_ns;
  StageTimer timer(out.timings, cfg_.timing_clock);
  Images im;
  im.left = ToGrey(frame.left);
  im.right = ToGrey(frame.right);
  const cv::Size win(cfg_.klt_window_px, cfg_.klt_window_px);
  cv::buildOpticalFlowPyramid(im.left, im.left_pyr, win, cfg_.klt_levels);
  cv::buildOpticalFlowPyramid(im.right, im.right_pyr, win, 1, false);
  timer.Stop("pyramid");

  if (!has_ref_) {
    T_w_out_ = Eigen::Isometry3d::Identity();
    Restart(im);
    prev_t_ns_ = frame.t_ns;
    timer.Stop("keyframe");
    out.status = ref_features_.size() >= static_cast<size_t>(cfg_.min_inliers_degraded)
                     ? Status::kOk
                     : Status::kDegraded;
    out.inliers = static_cast<int>(ref_features_.size());
    out.covariance = Matrix6d::Identity() * 1e-12;  // the first frame defines the origin
    out.t_prev_ns = frame.t_ns;
    out.total_ms = SumTimings(out.timings);
    return out;
  }

  // 1. Predict and track keyframe features into the current left image.
  double scale = 1.0;
  if (velocity_dt_ns_ > 0 && frame.t_ns > prev_t_ns_)
    scale = std::clamp(static_cast<double>(frame.t_ns - prev_t_ns_) / velocity_dt_ns_, 0.0, 5.0);
  const Eigen::Isometry3d T_ref_prev = T_w_ref_.inverse() * T_w_out_;
  const Eigen::Isometry3d T_ref_pred = T_ref_prev * ScaleMotion(velocity_, scale);
  const Eigen::Isometry3d T_pred_ref = T_ref_pred.inverse();
  std::vector<cv::Point2f> ref_uv, curr_uv;
  std::vector<float> pred_disp;
  ref_uv.reserve(ref_features_.size());
  for (const Feature& f : ref_features_) {
    ref_uv.push_back(f.uv);
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
    pred_disp.push_back(disp);
  }
  std::vector<uchar> status;
  std::vector<float> err;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.01);
  if (!ref_uv.empty())
    cv::calcOpticalFlowPyrLK(ref_pyramid_, im.left_pyr, ref_uv, curr_uv, status, err, win,
                             cfg_.klt_levels, criteria, cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<size_t> idx;  // features tracked into curr
  std::vector<cv::Point2f> tracked, back;
  for (size_t i = 0; i < ref_uv.size(); ++i)
    if (status[i] && Inside(curr_uv[i], im.left.size(), 2.f)) {
      idx.push_back(i);
      tracked.push_back(curr_uv[i]);
      back.push_back(ref_uv[i]);
    }
  if (cfg_.max_forward_backward_px > 0 && !tracked.empty()) {
    std::vector<uchar> st2;
    cv::calcOpticalFlowPyrLK(im.left_pyr, ref_pyramid_, tracked, back, st2, err, win, 1, criteria,
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    size_t k = 0;
    for (size_t j = 0; j < tracked.size(); ++j) {
      const cv::Point2f d = back[j] - ref_uv[idx[j]];
      if (!st2[j] || d.dot(d) > cfg_.max_forward_backward_px * cfg_.max_forward_backward_px)
        continue;
      idx[k] = idx[j];
      tracked[k] = tracked[j];
      ++k;
    }
    idx.resize(k);
    tracked.resize(k);
  }
  timer.Stop("track");

  // 2. Stereo on the tracked features (seeded by the predicted disparity).
  std::vector<float> seeds(idx.size());
  for (size_t j = 0; j < idx.size(); ++j) seeds[j] = pred_disp[idx[j]];
  const std::vector<float> disparity = StereoDisparities(im, tracked, &seeds);
  timer.Stop("stereo");

  // 3. Motion: P3P RANSAC on the left image, then Gauss-Newton on both images.
  std::vector<StereoObservation> obs(idx.size());
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (size_t j = 0; j < idx.size(); ++j) {
    const Feature& f = ref_features_[idx[j]];
    obs[j].p_ref = f.p_ref;
    obs[j].uv_left = {tracked[j].x, tracked[j].y};
    obs[j].has_right = disparity[j] > 0;
    obs[j].u_right = tracked[j].x - disparity[j];
    if (cfg_.symmetric_residuals && obs[j].has_right) {
      // Reverse term: the current stereo point seen in the keyframe's images.
      obs[j].has_reverse = true;
      obs[j].p_curr = TriangulateStereo(cam_, tracked[j].x, tracked[j].y, obs[j].u_right);
      obs[j].uv_ref_left = {f.uv.x, f.uv.y};
      obs[j].u_ref_right = f.u_right;
    }
    object.emplace_back(static_cast<float>(f.p_ref.x()), static_cast<float>(f.p_ref.y()),
                        static_cast<float>(f.p_ref.z()));
    image.push_back(tracked[j]);
  }
  if (static_cast<int>(obs.size()) < cfg_.min_inliers_degraded) return Fail(out, im);
  Eigen::Isometry3d T_init = T_ref_pred;
  {
    cv::Mat rvec, tvec;
    std::vector<int> ransac_inliers;
    bool found = false;
    try {
      found = cv::solvePnPRansac(object, image, K_, cv::noArray(), rvec, tvec, false,
                                 cfg_.ransac_iterations,
                                 static_cast<float>(cfg_.ransac_threshold_px), 0.99,
                                 ransac_inliers, cv::SOLVEPNP_P3P);
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
  }
  RefineOptions ro;
  ro.huber_px = cfg_.huber_px;
  ro.outlier_px = cfg_.outlier_px;
  const PoseRefinement refined = RefineStereoPose(obs, cam_, T_init, ro);
  timer.Stop("motion");
  if (!refined.ok || refined.inliers < cfg_.min_inliers_degraded) return Fail(out, im);

  // 4. Standstill: sub-pixel median flow and an insignificant motion -> identity.
  std::vector<double> flow;
  std::vector<Feature> kept;
  for (size_t j = 0; j < idx.size(); ++j) {
    if (!refined.inlier[j]) continue;
    flow.push_back(cv::norm(tracked[j] - ref_uv[idx[j]]));
    if (disparity[j] > 0) {
      Feature f = ref_features_[idx[j]];
      f.uv = tracked[j];
      f.u_right = tracked[j].x - disparity[j];
      f.p_ref = TriangulateStereo(cam_, tracked[j].x, tracked[j].y, f.u_right);
      kept.push_back(f);
    }
  }
  const double median_flow = Median(flow);
  Eigen::Isometry3d T_ref_curr = refined.T_ref_curr;
  const double t_sigma = std::sqrt(refined.covariance.topLeftCorner<3, 3>().trace());
  if (median_flow < cfg_.standstill_flow_px && T_ref_curr.translation().norm() < 3 * t_sigma)
    T_ref_curr = Eigen::Isometry3d::Identity();

  // 5. Keyframe: moved enough (or losing features) -> this frame becomes the
  // reference, after the window refined it.
  Eigen::Isometry3d T_w_curr = T_w_ref_ * T_ref_curr;
  const bool few = kept.size() < ref_features_.size() / 2;
  if (median_flow > cfg_.keyframe_flow_px || few) {
    if (WindowOn()) {
      T_w_curr = SolveWindowWith(kept, T_w_curr);
      timer.Stop("window");
    }
    MakeKeyframe(im, std::move(kept), T_w_curr, &timer);
  }

  out.T_prev_curr = T_w_out_.inverse() * T_w_curr;
  out.t_prev_ns = prev_t_ns_;
  T_w_out_ = T_w_curr;
  out.covariance = refined.covariance;
  out.inliers = refined.inliers;
  out.status = refined.inliers >= cfg_.min_inliers_ok ? Status::kOk : Status::kDegraded;
  if (frame.t_ns > prev_t_ns_) {
    velocity_ = out.T_prev_curr;
    velocity_dt_ns_ = frame.t_ns - prev_t_ns_;
  }
  prev_t_ns_ = frame.t_ns;
  timer.Stop("keyframe");
  out.total_ms = SumTimings(out.timings);
  return out;
}

}  // namespace

std::unique_ptr<StereoOdometry> MakeDefaultOdometry(const kitti::StereoCamera& camera,
                                                    const DefaultConfig& config) {
  return std::make_unique<DefaultOdometry>(camera, config);
}

}  // namespace locaid::vo
