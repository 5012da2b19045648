// "thesis" method: the stereo VO baseline this project started from
// (docs/architecture.md, "The algorithms"; compared in docs/benchmarks.md).
//
// Track(frame) = grid-bucketed FAST on the left image -> ORB descriptors ->
// brute-force knn (k = 2) matching previous->current left with Lowe's ratio
// test and an angle filter -> depth map of the previous frame (StereoBM) ->
// rotation from the essential matrix (5-point RANSAC, left camera only) ->
// translation from PnP RANSAC on the previous frame's stereo depth.
#include "core/stereo_camera.hpp"
#include "vo/image_guard.hpp"
#include "vo/odometry_common.hpp"
#include "vo/stereo_geometry.hpp"
#include "vo/stereo_odometry.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locaid::vo {
namespace {

class ThesisOdometry final : public StereoOdometry {
 public:
  ThesisOdometry(const StereoCamera& camera, const ThesisConfig& config)
      : cam_(camera), cfg_(config) {
    if (!(cam_.fx > 0 && cam_.fy > 0 && cam_.baseline_m > 0 && cam_.width > 0 && cam_.height > 0))
      throw std::invalid_argument("StereoCamera needs fx, fy, baseline_m, width, height > 0");
    K_ = (cv::Mat_<double>(3, 3) << cam_.fx, 0, cam_.cx, 0, cam_.fy, cam_.cy, 0, 0, 1);
    orb_ = cv::ORB::create();
    bm_ = cv::StereoBM::create(cfg_.num_disparities, cfg_.block_size);
    matcher_ = cv::BFMatcher::create(cv::NORM_HAMMING);
  }

  RelativeMotion Track(const StereoFrame& frame) override;
  void Reset() override { has_prev_ = false; }

 private:
  // The previous frame's features matched into this frame's.
  struct Matches {
    std::vector<cv::DMatch> good;  // previous (query) -> current (train)
    std::vector<cv::Point2f> p_prev, p_curr;
  };
  // What PnP on the previous frame's depth gives.
  struct PnpResult {
    bool ok = false;
    cv::Mat rvec, tvec;
    std::vector<int> inliers;
    std::vector<StereoObservation> observations;  // one per 3D point PnP saw
  };

  std::vector<cv::KeyPoint> DetectGrid(const cv::Mat& left) const;
  // Brute-force knn (k = 2) from the previous frame's descriptors, Lowe's
  // ratio test and the angle filter.
  Matches MatchPrevious(const std::vector<cv::KeyPoint>& kps, const cv::Mat& desc) const;
  // Whether the median image motion is below the standstill threshold.
  bool Standstill(const Matches& m) const;
  // Rotation from the essential matrix (5-point RANSAC, left camera); false
  // when it fails.
  bool RotationFromEssential(const Matches& m, cv::Mat& R_curr_prev) const;
  // PnP RANSAC with 3D points from the previous frame's depth map.
  PnpResult TranslationFromDepth(const Matches& m) const;
  // The motion from the PnP translation and the chosen rotation; kLost when
  // it is not finite.
  RelativeMotion MotionOf(const PnpResult& pnp, bool rotation_ok, const cv::Mat& R_curr_prev,
                          int64_t t_ns) const;
  // Keeps this frame for the next one and completes `m` (times, timings; the
  // first frame is the identity).
  RelativeMotion Finish(RelativeMotion m, const StereoFrame& frame, std::vector<cv::KeyPoint> kps,
                        const cv::Mat& desc, const cv::Mat& disparity, const StageTimings& timings);

  StereoCamera cam_;
  ThesisConfig cfg_;
  cv::Mat K_;
  cv::Ptr<cv::ORB> orb_;
  cv::Ptr<cv::StereoBM> bm_;
  cv::Ptr<cv::BFMatcher> matcher_;
  bool has_prev_ = false;
  int64_t prev_t_ns_ = 0;  // time of the frame the next motion starts from
  std::vector<cv::KeyPoint> prev_kps_;
  cv::Mat prev_desc_, prev_disparity_;  // disparity CV_16S, fixed point x16
};

std::vector<cv::KeyPoint> ThesisOdometry::DetectGrid(const cv::Mat& left) const {
  std::vector<cv::KeyPoint> out;
  const int cell = cfg_.grid_cell_px;
  for (int y = 0; y < left.rows; y += cell) {
    for (int x = 0; x < left.cols; x += cell) {
      const cv::Rect roi(x, y, std::min(cell, left.cols - x), std::min(cell, left.rows - y));
      std::vector<cv::KeyPoint> kps;
      cv::FAST(left(roi), kps, cfg_.fast_threshold, true);
      cv::KeyPointsFilter::retainBest(kps, cfg_.max_features_per_cell);
      for (cv::KeyPoint& kp : kps) {
        kp.pt += cv::Point2f(static_cast<float>(x), static_cast<float>(y));
        kp.size = 31;
        out.push_back(kp);
      }
    }
  }
  return out;
}

RelativeMotion ThesisOdometry::Track(const StereoFrame& frame) {
  if (!FrameUsable(frame, cam_, cfg_.min_image_stddev)) return NoMotion(frame.t_ns, Status::kLost);
  RelativeMotion out;
  out.t_ns = frame.t_ns;
  StageTimer timer(out.timings, cfg_.timing_clock);
  const cv::Mat left = ToGrey(frame.left), right = ToGrey(frame.right);

  std::vector<cv::KeyPoint> kps = DetectGrid(left);
  cv::Mat desc;
  orb_->compute(left, kps, desc);  // drops keypoints too close to the border
  timer.Stop("detect_describe");

  const Matches matches = MatchPrevious(kps, desc);
  timer.Stop("match");

  cv::Mat disparity;
  bm_->compute(left, right, disparity);
  timer.Stop("depth");

  const auto finish = [&](RelativeMotion m) {
    return Finish(std::move(m), frame, std::move(kps), desc, disparity, out.timings);
  };
  if (!has_prev_) return finish(out);
  if (static_cast<int>(matches.good.size()) < cfg_.min_inliers_degraded)
    return finish(NoMotion(frame.t_ns, Status::kLost));

  // Guard (not in the thesis): no image motion -> the essential matrix is
  // undefined; report identity.
  if (Standstill(matches)) {
    RelativeMotion still;
    still.status = Status::kOk;
    still.inliers = static_cast<int>(matches.good.size());
    still.covariance = Matrix6d::Identity() * 1e-6;
    timer.Stop("rotation");
    timer.Stop("translation");
    return finish(still);
  }

  cv::Mat R_curr_prev;
  const bool rotation_ok = RotationFromEssential(matches, R_curr_prev);
  timer.Stop("rotation");
  const PnpResult pnp = TranslationFromDepth(matches);
  timer.Stop("translation");
  if (!pnp.ok || static_cast<int>(pnp.inliers.size()) < cfg_.min_inliers_degraded)
    return finish(NoMotion(frame.t_ns, Status::kLost));
  return finish(MotionOf(pnp, rotation_ok, R_curr_prev, frame.t_ns));
}

ThesisOdometry::Matches ThesisOdometry::MatchPrevious(const std::vector<cv::KeyPoint>& kps,
                                                      const cv::Mat& desc) const {
  Matches out;
  if (has_prev_ && !prev_desc_.empty() && !desc.empty()) {
    std::vector<std::vector<cv::DMatch>> knn;
    matcher_->knnMatch(prev_desc_, desc, knn, 2);
    for (const auto& m : knn) {
      if (m.size() < 2 || m[0].distance >= cfg_.ratio * m[1].distance) continue;
      float dangle = std::abs(prev_kps_[static_cast<size_t>(m[0].queryIdx)].angle -
                              kps[static_cast<size_t>(m[0].trainIdx)].angle);
      dangle = std::min(dangle, 360.f - dangle);
      if (dangle > cfg_.max_angle_deg) continue;
      out.good.push_back(m[0]);
    }
  }
  for (const cv::DMatch& m : out.good) {
    out.p_prev.push_back(prev_kps_[static_cast<size_t>(m.queryIdx)].pt);
    out.p_curr.push_back(kps[static_cast<size_t>(m.trainIdx)].pt);
  }
  return out;
}

bool ThesisOdometry::Standstill(const Matches& m) const {
  std::vector<double> flow;
  for (size_t i = 0; i < m.p_prev.size(); ++i) flow.push_back(cv::norm(m.p_curr[i] - m.p_prev[i]));
  std::nth_element(flow.begin(), flow.begin() + static_cast<std::ptrdiff_t>(flow.size() / 2),
                   flow.end());
  return flow[flow.size() / 2] < cfg_.standstill_flow_px;
}

bool ThesisOdometry::RotationFromEssential(const Matches& m, cv::Mat& R_curr_prev) const {
  try {
    cv::Mat mask;
    const cv::Mat E = cv::findEssentialMat(m.p_prev, m.p_curr, K_, cv::RANSAC, 0.999,
                                           cfg_.essential_threshold_px, mask);
    if (E.rows != 3 || E.cols != 3) return false;
    cv::Mat t_unit;
    const int n = cv::recoverPose(E, m.p_prev, m.p_curr, K_, R_curr_prev, t_unit, mask);
    return n >= cfg_.min_inliers_degraded;
  } catch (const cv::Exception&) {
    return false;
  }
}

ThesisOdometry::PnpResult ThesisOdometry::TranslationFromDepth(const Matches& m) const {
  PnpResult out;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (size_t i = 0; i < m.p_prev.size(); ++i) {
    const int u = cvRound(m.p_prev[i].x), v = cvRound(m.p_prev[i].y);
    if (u < 0 || v < 0 || u >= prev_disparity_.cols || v >= prev_disparity_.rows) continue;
    const double d = prev_disparity_.at<int16_t>(v, u) / 16.0;
    if (d <= 1.0) continue;
    const Eigen::Vector3d p = TriangulateStereo(cam_, m.p_prev[i].x, m.p_prev[i].y, m.p_prev[i].x - d);
    object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z()));
    image.push_back(m.p_curr[i]);
    StereoObservation ob;
    ob.p_ref = p;
    ob.uv_left = {m.p_curr[i].x, m.p_curr[i].y};
    out.observations.push_back(ob);
  }
  if (static_cast<int>(object.size()) >= cfg_.min_inliers_degraded) {
    try {
      out.ok = cv::solvePnPRansac(object, image, K_, cv::noArray(), out.rvec, out.tvec, false,
                                  cfg_.pnp_iterations, static_cast<float>(cfg_.pnp_threshold_px),
                                  0.99, out.inliers);
    } catch (const cv::Exception&) {
      out.ok = false;
    }
  }
  return out;
}

RelativeMotion ThesisOdometry::MotionOf(const PnpResult& pnp, bool rotation_ok, const cv::Mat& R_curr_prev,
                                        int64_t t_ns) const {
  cv::Mat R_pnp;
  cv::Rodrigues(pnp.rvec, R_pnp);
  const cv::Mat& R = rotation_ok ? R_curr_prev : R_pnp;
  Eigen::Isometry3d T_curr_prev = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T_curr_prev.linear()(r, c) = R.at<double>(r, c);
    T_curr_prev.translation()(r) = pnp.tvec.at<double>(r);
  }
  if (!IsFinite(T_curr_prev)) return NoMotion(t_ns, Status::kLost);
  RelativeMotion m;
  m.T_prev_curr = T_curr_prev.inverse();
  std::vector<StereoObservation> inlier_obs;
  for (int i : pnp.inliers) inlier_obs.push_back(pnp.observations[static_cast<size_t>(i)]);
  m.covariance = PoseCovariance(inlier_obs, cam_, m.T_prev_curr);
  m.inliers = static_cast<int>(pnp.inliers.size());
  m.status = (rotation_ok && m.inliers >= cfg_.min_inliers_ok) ? Status::kOk : Status::kDegraded;
  return m;
}

RelativeMotion ThesisOdometry::Finish(RelativeMotion m, const StereoFrame& frame, std::vector<cv::KeyPoint> kps,
                                      const cv::Mat& desc, const cv::Mat& disparity,
                                      const StageTimings& timings) {
  prev_kps_ = std::move(kps);
  prev_desc_ = desc;
  prev_disparity_ = disparity;
  const bool first = !has_prev_;
  has_prev_ = true;
  if (first) {
    m.status = Status::kOk;
    m.T_prev_curr = Eigen::Isometry3d::Identity();
    m.covariance = Matrix6d::Identity() * 1e-12;
  }
  m.timings = timings;
  m.t_ns = frame.t_ns;
  m.t_prev_ns = m.status == Status::kLost || first ? frame.t_ns : prev_t_ns_;
  prev_t_ns_ = frame.t_ns;
  m.total_ms = SumTimings(m.timings);
  return m;
}

}  // namespace

std::unique_ptr<StereoOdometry> MakeThesisOdometry(const StereoCamera& camera,
                                                   const ThesisConfig& config) {
  ImageGuardConfig guard;
  guard.min_image_stddev = config.min_image_stddev;
  guard.min_dark_snr = config.min_dark_snr;
  return std::make_unique<GuardedOdometry>(std::make_unique<ThesisOdometry>(camera, config), guard);
}

}  // namespace locaid::vo
