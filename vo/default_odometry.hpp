// The "default" method (internal to vo/; users call MakeDefaultOdometry):
// KLT feature tracking against a keyframe.
//
// Track(frame), one named stage each (default_odometry.cpp):
//   BuildPyramids -> PredictKeyframeToCurrent (constant velocity)
//   -> TrackKeyframeFeatures (KLT seeded by the prediction, forward-backward check)
//   -> TrackedDisparities (stereo KLT seeded by the predicted disparity)
//   -> EstimateMotion (P3P RANSAC, then Huber Gauss-Newton on the reprojection
//      error in BOTH current images) -> KeepInliers -> SnapStandstill
//   -> UpdateKeyframe (sliding window when on; bucketing with feature ageing,
//      new FAST corners, row-search + KLT sub-pixel disparity) -> Report.
// The keyframe stages (detection, stereo disparities, window) are in
// default_keyframe.cpp.
#pragma once

#include "core/stereo_camera.hpp"
#include "vo/odometry_common.hpp"
#include "vo/stereo_geometry.hpp"
#include "vo/stereo_odometry.hpp"

#include <opencv2/core.hpp>

#include <deque>
#include <optional>
#include <unordered_map>
#include <vector>

namespace locaid::vo::detail {

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

// Stop rule of every KLT call (temporal, forward-backward and stereo).
inline const cv::TermCriteria kKltCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.01);

inline bool Inside(const cv::Point2f& p, const cv::Size& size, float margin) {
  return p.x >= margin && p.y >= margin && p.x < size.width - 1 - margin &&
         p.y < size.height - 1 - margin;
}

class DefaultOdometry final : public StereoOdometry {
 public:
  DefaultOdometry(const StereoCamera& camera, const DefaultConfig& config);

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
  // Keyframe features followed into the current left image.
  struct Tracks {
    std::vector<cv::Point2f> ref_uv;          // every keyframe feature, in the keyframe
    std::vector<float> predicted_disparity;   // per keyframe feature; -1: none
    std::vector<size_t> idx;                  // the keyframe feature of each track
    std::vector<cv::Point2f> uv;              // where it is in the current left image
  };
  // The tracked features that survived the motion estimate, at the current frame.
  struct Inliers {
    std::vector<Feature> kept;  // with a stereo match, triangulated in the current frame
    double median_flow_px = 0;  // since the keyframe
  };

  // ---- Track's stages (default_odometry.cpp)
  Images BuildPyramids(const StereoFrame& frame) const;
  // The first frame (or the first after Reset) becomes the keyframe and the origin.
  void StartAtOrigin(const Images& im, RelativeMotion& out, StageTimer& timer);
  // Keyframe -> current frame under the constant-velocity model.
  Eigen::Isometry3d PredictKeyframeToCurrent(int64_t t_ns) const;
  Tracks TrackKeyframeFeatures(const Images& im, const Eigen::Isometry3d& T_ref_pred) const;
  std::vector<float> TrackedDisparities(const Images& im, const Tracks& tracks) const;
  // P3P RANSAC on the left image, then Gauss-Newton on both images; nullopt
  // when there are too few tracks to try.
  std::optional<PoseRefinement> EstimateMotion(const Tracks& tracks, const std::vector<float>& disparity,
                                               const Eigen::Isometry3d& T_ref_pred) const;
  Inliers KeepInliers(const Tracks& tracks, const std::vector<float>& disparity,
                      const PoseRefinement& refined) const;
  // Sub-pixel median flow and a motion insignificant at 3 sigma -> identity.
  Eigen::Isometry3d SnapStandstill(const PoseRefinement& refined, double median_flow_px) const;
  // Moved enough (or losing features) -> this frame becomes the keyframe, after
  // the window refined it; returns the current pose in the odometry frame.
  Eigen::Isometry3d UpdateKeyframe(const Images& im, Inliers inliers, Eigen::Isometry3d T_w_curr,
                                   StageTimer& timer);
  // Fills `out` with the motion since the last reported pose and moves the
  // velocity model on.
  void Report(const PoseRefinement& refined, const Eigen::Isometry3d& T_w_curr, int64_t t_ns,
              RelativeMotion& out, StageTimer& timer);
  // LOST: re-initialises on this frame so tracking resumes on the next one
  // (`out` keeps the timings so far).
  RelativeMotion Fail(RelativeMotion out, const Images& im);

  // ---- Keyframe and window (default_keyframe.cpp)
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

  StereoCamera cam_;
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

}  // namespace locaid::vo::detail
