// The "default" method's keyframe stages: new corners in buckets, their
// stereo disparities, the keyframe update and the sliding window
// (vo/default_odometry.hpp lists every stage of Track).
#include "vo/default_odometry.hpp"
#include "vo/window_ba.hpp"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace locaid::vo::detail {

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
                           kKltCriteria,
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

}  // namespace locaid::vo::detail
