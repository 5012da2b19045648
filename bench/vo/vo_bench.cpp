// vo_bench: VO drift and speed on one drive with ground truth, for one or all
// methods. Drift uses the devkit definition (eval/devkit.hpp: segments
// starting every 10 frames, plain mean over all segments) with the segment
// lengths given by --lengths (default 25 50 75 100 m for short drives), plus
// the final position error as % of the ground-truth path length.
//
// Error split (JSON "split"): every devkit segment's translation error, in the
// segment's first ground-truth camera frame, cut into its horizontal (camera
// x, z) and vertical (camera y) parts, each averaged like t_rel. And the
// "slant" of the motion: for blocks of 10 frames, the angle of the block's
// translation out of the camera's x-z plane, atan2(-t_y, |t_xz|); a car moves
// along its floor, so this stays near the camera's mounting pitch. The spread
// (max |slant - median|) of the ground truth next to the estimate's shows how
// much vertical motion the reference has that the camera did not see.
//
// Two diagnostics of the reference itself (raw drives):
//   --reference-floor scores the other OXTS trajectory (velocity integral when
//     the reference is the position solution, and the other way round) against
//     the reference, as if it were one more method: what an odometer as good
//     as the OXTS unit's own velocity would get (JSON "reference_floor").
//   --fit-boresight searches the constant rotation of the estimate's camera
//     frame (yaw about camera y, pitch about camera x, 0.05 deg grid within
//     +-1 deg) that minimises t_rel (JSON "boresight_fit"). A calibration
//     error between the camera and the reference's frame (camera intrinsics,
//     camera-IMU extrinsics) shows up as such a rotation. It is fitted on the
//     evaluated frames themselves: a diagnostic, never a result.
//
//   vo_bench --drive DIR [--lengths 25 50 75 100] [--reference oxts|oxts-velocity]
//            [--reference-floor] [--fit-boresight] [--out-poses PREFIX] [VO flags]
//
// VO flags (vo/apps/vo_flags.hpp, shared with locaid-vo): --method NAME|all (all
// by default), --max-frames N, --cpu-time, --window-keyframes N,
// --klt-guess full|rotation, --frame-step N (devkit segments then start every
// 10 tracked frames).
#include "kitti/dataset.hpp"
#include "eval/devkit.hpp"
#include "kitti/oxts_pose.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/raw_drive.hpp"
#include "vo/apps/vo_flags.hpp"
#include "vo/apps/drive_runner.hpp"
#include "vo/stereo_odometry.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>

namespace {

using locaid::eval::SegmentError;

struct SplitError {
  double horizontal = 0, vertical = 0;  // mean over segments, fraction of the length
};

// Mean horizontal / vertical error of the segments (devkit pose error).
SplitError SplitSegmentErrors(const std::vector<Eigen::Isometry3d>& gt, const std::vector<Eigen::Isometry3d>& est,
                              const std::vector<SegmentError>& segments, float length_m = 0) {
  SplitError out;
  int n = 0;
  for (const SegmentError& seg : segments) {
    if (length_m > 0 && seg.length_m != length_m) continue;
    const Eigen::Isometry3d d_gt = gt[seg.first_frame].inverse() * gt[seg.last_frame];
    const Eigen::Isometry3d d_est = est[seg.first_frame].inverse() * est[seg.last_frame];
    // End-position difference in the segment's start camera frame (the devkit
    // error has the same norm, expressed in the estimate's end frame).
    const Eigen::Vector3d e = d_gt.translation() - d_est.translation();
    out.horizontal += std::hypot(e.x(), e.z()) / seg.length_m;
    out.vertical += std::abs(e.y()) / seg.length_m;
    ++n;
  }
  if (n > 0) {
    out.horizontal /= n;
    out.vertical /= n;
  }
  return out;
}

struct Slant {
  double median_deg = 0, max_dev_deg = 0;
};

// Angle of each 10-frame block's motion out of the camera x-z plane (moving
// blocks only: > 2 m).
Slant MotionSlant(const std::vector<Eigen::Isometry3d>& poses) {
  std::vector<double> deg;
  for (size_t i = 0; i + 10 < poses.size(); i += 10) {
    const Eigen::Vector3d t = (poses[i].inverse() * poses[i + 10]).translation();
    if (t.norm() < 2.0) continue;
    deg.push_back(std::atan2(-t.y(), std::hypot(t.x(), t.z())) * 180 / M_PI);
  }
  Slant s;
  if (deg.empty()) return s;
  std::vector<double> sorted = deg;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  s.median_deg = sorted[sorted.size() / 2];
  for (double d : deg) s.max_dev_deg = std::max(s.max_dev_deg, std::abs(d - s.median_deg));
  return s;
}

// Ground truth per frame: the dataset's, or (raw drives, "oxts-velocity")
// OXTS with positions from its integrated velocity.
std::vector<std::optional<Eigen::Isometry3d>> ReferencePoses(const locaid::kitti::StereoDataset& dataset,
                                                              const std::string& reference) {
  std::vector<std::optional<Eigen::Isometry3d>> out(dataset.size());
  if (reference == "oxts") {
    for (size_t i = 0; i < dataset.size(); ++i) out[i] = dataset.ground_truth(i);
    return out;
  }
  if (dataset.oxts().empty())
    throw std::runtime_error("--reference " + reference + " needs a raw drive with OXTS records");
  std::vector<int64_t> t_ns(dataset.size());
  for (size_t i = 0; i < dataset.size(); ++i) t_ns[i] = dataset.time_ns(i);
  // Same gap limit as the dataset's own ground truth (OpenDataset's defaults).
  return locaid::kitti::ComputeOxtsGroundTruth(locaid::kitti::IntegrateOxtsVelocity(dataset.oxts()), t_ns,
                                               dataset.T_cam0_imu(), locaid::kitti::RawDriveOptions{}.max_gt_gap_s)
      .T_world_cam;
}

// Frames with ground truth (raw drives: OXTS may start after frame 0), both
// trajectories re-anchored at the first of them; one contiguous stretch.
void AnchoredPairs(const std::vector<std::optional<Eigen::Isometry3d>>& reference,
                   const std::vector<Eigen::Isometry3d>& estimate, std::vector<Eigen::Isometry3d>* gt,
                   std::vector<Eigen::Isometry3d>* est) {
  gt->clear();
  est->clear();
  for (size_t i = 0; i < estimate.size() && i < reference.size(); ++i) {
    const auto& g = reference[i];
    if (!g) {
      if (!gt->empty()) break;
      continue;
    }
    gt->push_back(*g);
    est->push_back(estimate[i]);
  }
  if (gt->empty()) return;
  const Eigen::Isometry3d gt0_inv = gt->front().inverse(), est0_inv = est->front().inverse();
  for (size_t i = 0; i < gt->size(); ++i) {
    (*gt)[i] = gt0_inv * (*gt)[i];
    (*est)[i] = est0_inv * (*est)[i];
  }
}

struct BoresightFit {
  double yaw_deg = 0, pitch_deg = 0, t_rel_pct = 0, r_rel_deg_per_100m = 0;
};

// Every pose conjugated by R (relative motions R d R^T): the estimate seen
// from a camera frame rotated by R.
std::vector<Eigen::Isometry3d> RotateFrame(const std::vector<Eigen::Isometry3d>& poses, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  std::vector<Eigen::Isometry3d> out;
  out.reserve(poses.size());
  for (const Eigen::Isometry3d& p : poses) out.push_back(T * p * T.inverse());
  return out;
}

std::optional<BoresightFit> FitBoresight(const std::vector<Eigen::Isometry3d>& gt,
                                         const std::vector<Eigen::Isometry3d>& est,
                                         const locaid::eval::DevkitConfig& dc) {
  std::optional<BoresightFit> best;
  constexpr int kSteps = 20;  // +-1 deg in 0.05 deg steps
  for (int iy = -kSteps; iy <= kSteps; ++iy) {
    for (int ip = -kSteps; ip <= kSteps; ++ip) {
      const double yaw = static_cast<double>(iy) / kSteps, pitch = static_cast<double>(ip) / kSteps;
      const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw * M_PI / 180, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(pitch * M_PI / 180, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix();
      const auto r = locaid::eval::EvaluateDevkit(gt, RotateFrame(est, R), dc);
      if (!r.t_err || !r.r_err_rad_per_m) return std::nullopt;
      if (!best || *r.t_err * 100 < best->t_rel_pct)
        best = BoresightFit{yaw, pitch, *r.t_err * 100, *r.r_err_rad_per_m * 180 / M_PI * 100};
    }
  }
  return best;
}

// Drift of `est` against `gt` (anchored pairs, devkit result `r`): path
// length, devkit t_rel / r_rel overall and per length, final error.
nlohmann::json DriftJson(const std::vector<Eigen::Isometry3d>& gt, const std::vector<Eigen::Isometry3d>& est,
                         const locaid::eval::DevkitResult& r) {
  double length = 0;
  for (size_t i = 1; i < gt.size(); ++i) length += (gt[i].translation() - gt[i - 1].translation()).norm();
  const double final_err = (est.back().translation() - gt.back().translation()).norm();
  nlohmann::json j;
  j["evaluated_frames"] = gt.size();
  j["length_m"] = length;
  j["segments"] = r.segments.size();
  if (r.t_err) j["t_rel_pct"] = *r.t_err * 100;
  if (r.r_err_rad_per_m) j["r_rel_deg_per_100m"] = *r.r_err_rad_per_m * 180 / M_PI * 100;
  for (const auto& pl : r.per_length)
    if (pl.t_err) j["t_rel_pct_by_length"][std::to_string(static_cast<int>(pl.length_m))] = *pl.t_err * 100;
  j["final_error_m"] = final_err;
  j["final_error_pct"] = 100 * final_err / length;
  return j;
}

// Median of the OXTS records' own position accuracy field (raw drives).
std::optional<double> MedianOxtsPositionAccuracy(const locaid::kitti::StereoDataset& dataset) {
  std::vector<double> acc;
  for (const auto& s : dataset.oxts()) acc.push_back(s.record.pos_accuracy_m);
  if (acc.empty()) return std::nullopt;
  std::nth_element(acc.begin(), acc.begin() + static_cast<long>(acc.size() / 2), acc.end());
  return acc[acc.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  using namespace locaid;
  CLI::App app{"VO drift and timing benchmark"};
  std::string drive;
  std::vector<float> lengths = {25, 50, 75, 100};
  vo::VoFlags flags;
  flags.method = "all";
  app.add_option("--drive", drive, "drive folder with ground truth")->required();
  std::vector<std::string> choices = vo::StereoOdometryMethods();
  choices.push_back("all");
  vo::AddVoFlags(app, flags, choices);
  app.add_option("--lengths", lengths, "devkit segment lengths in metres");
  std::string reference = "oxts";
  app.add_option("--reference", reference,
                 "raw drives: ground truth from the OXTS position solution (oxts, the devkit's) or from "
                 "the integral of the OXTS velocity (oxts-velocity, a diagnostic of the position "
                 "solution's steps)")
      ->check(CLI::IsMember({"oxts", "oxts-velocity"}))
      ->capture_default_str();
  std::string out_poses;
  app.add_option("--out-poses", out_poses,
                 "write the evaluated frames as KITTI pose files PREFIX_gt.txt and PREFIX_<method>.txt "
                 "(both anchored at the first frame with ground truth)");
  bool reference_floor = false, fit_boresight = false;
  app.add_flag("--reference-floor", reference_floor,
               "raw drives: also score the other OXTS trajectory (velocity integral or position solution) "
               "against the reference, as one more entry (method \"reference_floor\")");
  app.add_flag("--fit-boresight", fit_boresight,
               "per method: the constant camera-frame rotation (yaw, pitch within +-1 deg) that minimises "
               "t_rel, fitted on the evaluated frames (a calibration diagnostic, not a result)");
  CLI11_PARSE(app, argc, argv);
  std::vector<std::string> run_methods = vo::StereoOdometryMethods();
  if (flags.method != "all") run_methods = {flags.method};
  if (const std::string problem = vo::VoFlagsProblem(flags, run_methods); !problem.empty()) {
    std::cerr << "vo_bench: " << problem << "\n";
    return 2;
  }
  cv::setNumThreads(1);
  try {
    const auto dataset = kitti::OpenDataset(drive);
    if (reference_floor && dataset->oxts().empty())
      throw std::runtime_error("--reference-floor needs a raw drive with OXTS records");
    const std::vector<std::optional<Eigen::Isometry3d>> reference_poses = ReferencePoses(*dataset, reference);
    const std::optional<double> oxts_pos_accuracy_m = MedianOxtsPositionAccuracy(*dataset);
    nlohmann::json out = nlohmann::json::array();
    for (const std::string& m : run_methods) {
      const vo::DriveRun run = vo::RunOnDataset(*dataset, vo::MakeDriveRunConfig(flags, m));
      std::vector<std::optional<Eigen::Isometry3d>> reference_visited;  // one per run.frames entry
      for (const vo::FrameResult& f : run.frames) reference_visited.push_back(reference_poses[f.index]);
      std::vector<Eigen::Isometry3d> gt, est;
      AnchoredPairs(reference_visited, vo::PosesPerFrame(run), &gt, &est);
      if (gt.size() < 2) throw std::runtime_error("no ground truth in " + drive);
      if (!out_poses.empty()) {
        kitti::WriteKittiPoses(out_poses + "_gt.txt", gt);
        kitti::WriteKittiPoses(out_poses + "_" + m + ".txt", est);
      }
      eval::DevkitConfig dc;
      dc.lengths_m = lengths;
      const eval::DevkitResult r = eval::EvaluateDevkit(gt, est, dc);
      const vo::TimingSummary s = vo::Summarize(run);
      nlohmann::json j = DriftJson(gt, est, r);
      j["method"] = m;
      if (m == "default" && flags.window_keyframes >= 0) j["window_keyframes"] = flags.window_keyframes;
      if (m == "default" && !flags.klt_guess.empty()) j["klt_guess"] = flags.klt_guess;
      if (flags.frame_step > 1) j["frame_step"] = flags.frame_step;
      j["drive"] = drive;
      j["reference"] = reference;
      if (oxts_pos_accuracy_m) j["oxts_pos_accuracy_median_m"] = *oxts_pos_accuracy_m;
      vo::AddRunSummaryJson(j, s, flags);
      j["missing_frames"] = s.missing_frames;
      const SplitError split = SplitSegmentErrors(gt, est, r.segments);
      j["split"]["t_rel_horizontal_pct"] = split.horizontal * 100;
      j["split"]["t_rel_vertical_pct"] = split.vertical * 100;
      for (const auto& pl : r.per_length) {
        if (!pl.t_err) continue;
        const SplitError sl = SplitSegmentErrors(gt, est, r.segments, pl.length_m);
        const std::string key = std::to_string(static_cast<int>(pl.length_m));
        j["split"]["horizontal_pct_by_length"][key] = sl.horizontal * 100;
        j["split"]["vertical_pct_by_length"][key] = sl.vertical * 100;
      }
      const Slant slant_gt = MotionSlant(gt), slant_est = MotionSlant(est);
      j["split"]["slant_10_frames_gt_deg"] = {{"median", slant_gt.median_deg}, {"max_dev", slant_gt.max_dev_deg}};
      j["split"]["slant_10_frames_est_deg"] = {{"median", slant_est.median_deg}, {"max_dev", slant_est.max_dev_deg}};
      if (fit_boresight) {
        if (const std::optional<BoresightFit> b = FitBoresight(gt, est, dc))
          j["boresight_fit"] = {{"yaw_deg", b->yaw_deg},
                                {"pitch_deg", b->pitch_deg},
                                {"t_rel_pct", b->t_rel_pct},
                                {"r_rel_deg_per_100m", b->r_rel_deg_per_100m}};
      }
      std::fprintf(stderr, "%s: t_rel %.3f %%, final %.3f %%, %.2f ms median (cpu %.2f)\n",
                   m.c_str(), r.t_err ? *r.t_err * 100 : -1.0, j["final_error_pct"].get<double>(),
                   s.ms_per_frame_median, s.cpu_ms_per_frame_median);
      out.push_back(j);
    }
    if (reference_floor) {
      const std::string other = reference == "oxts" ? "oxts-velocity" : "oxts";
      const std::vector<std::optional<Eigen::Isometry3d>> other_poses = ReferencePoses(*dataset, other);
      // The same frames the methods were evaluated on (every frame_step-th).
      std::vector<std::optional<Eigen::Isometry3d>> ref_both;
      std::vector<Eigen::Isometry3d> scored;
      size_t n = dataset->size();
      if (flags.max_frames > 0) n = std::min(n, flags.max_frames);
      for (size_t i = 0; i < n; i += flags.frame_step) {
        const bool both = reference_poses[i] && other_poses[i];
        ref_both.push_back(both ? reference_poses[i] : std::nullopt);
        scored.push_back(both ? *other_poses[i] : Eigen::Isometry3d::Identity());
      }
      std::vector<Eigen::Isometry3d> gt, est;
      AnchoredPairs(ref_both, scored, &gt, &est);
      if (gt.size() < 2) throw std::runtime_error("--reference-floor: no frame has both OXTS trajectories");
      eval::DevkitConfig dc;
      dc.lengths_m = lengths;
      const eval::DevkitResult r = eval::EvaluateDevkit(gt, est, dc);
      nlohmann::json j = DriftJson(gt, est, r);
      j["method"] = "reference_floor";
      j["scored"] = other;
      j["reference"] = reference;
      std::fprintf(stderr, "reference floor (%s against %s): t_rel %.3f %%\n", other.c_str(), reference.c_str(),
                   r.t_err ? *r.t_err * 100 : -1.0);
      out.push_back(j);
    }
    std::cout << out.dump(2) << std::endl;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vo_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
