// The KITTI odometry metric against the official devkit's reported numbers
// (real files in the shared data) and against synthetic trajectories with
// known answers.
#include "eval/devkit.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/types.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>
#include <Eigen/Geometry>

namespace locaid::eval {
namespace {

namespace fs = std::filesystem;

// Required agreement with the devkit, plus the rounding of its 6-decimal
// printout ("%f") in the reference table.
constexpr double kDevkitAgreement = 1e-6;
constexpr double kTableRounding = 0.5e-6;
// The devkit computes in float: relative errors of a few 1e-7 per segment.
constexpr double kFloatTol = 1e-6;
// Identical trajectories: only the rounding of 4x4 inverses remains (~1e-16).
constexpr double kSelfTol = 1e-12;

const fs::path kOdometry = fs::path(LOCAID_SHARED_DATA) / "odometry";

struct Reference {
  std::string result_file, sequence;
  double t_err, r_err_rad_per_m;
};

// From shared/data/kitti/README.md (what evaluate_odometry printed).
const std::vector<Reference> kReferences = {
    {"00_ORB_SLAM_from_evo.txt", "00", 0.006997, 0.000044},
    {"00_SPTAM_from_evo.txt", "00", 0.014870, 0.000097},
    {"00_kitti-eval-itl_example.txt", "00", 0.012922, 0.000110},
    {"04_kitti-eval-itl_example.txt", "04", 0.033356, 0.000098},
};

TEST(EvalDevkitReference, ReproducesOfficialDevkitNumbers) {
  if (!fs::exists(kOdometry / "reference_results")) {
    GTEST_SKIP() << "shared KITTI data absent: " << kOdometry;
  }
  for (const Reference& ref : kReferences) {
    SCOPED_TRACE(ref.result_file);
    const auto gt = kitti::ReadKittiPoses(kOdometry / "poses" / (ref.sequence + ".txt"));
    const auto est = kitti::ReadKittiPoses(kOdometry / "reference_results" / ref.result_file);
    const DevkitResult r = EvaluateDevkit(gt, est);
    ASSERT_TRUE(r.t_err.has_value());
    ASSERT_TRUE(r.r_err_rad_per_m.has_value());
    EXPECT_NEAR(*r.t_err, ref.t_err, kDevkitAgreement + kTableRounding);
    EXPECT_NEAR(*r.r_err_rad_per_m, ref.r_err_rad_per_m, kDevkitAgreement + kTableRounding);
    // Stricter: the devkit's own "%f %f" printout of stats.txt is reproduced.
    char printed[64], expected[64];
    std::snprintf(printed, sizeof(printed), "%f %f", *r.t_err, *r.r_err_rad_per_m);
    std::snprintf(expected, sizeof(expected), "%f %f", ref.t_err, ref.r_err_rad_per_m);
    EXPECT_STREQ(printed, expected);
  }
}

TEST(EvalDevkitReference, GroundTruthAgainstItselfIsZero) {
  if (!fs::exists(kOdometry / "poses")) GTEST_SKIP() << "shared KITTI data absent: " << kOdometry;
  for (const char* seq : {"00", "04"}) {
    const auto gt = kitti::ReadKittiPoses(kOdometry / "poses" / (std::string(seq) + ".txt"));
    const DevkitResult r = EvaluateDevkit(gt, gt);
    ASSERT_FALSE(r.segments.empty()) << seq;
    EXPECT_NEAR(*r.t_err, 0.0, kSelfTol) << seq;
    EXPECT_NEAR(*r.r_err_rad_per_m, 0.0, kSelfTol) << seq;
  }
}

// Straight drive along +z (camera forward) with `step_m` between frames.
std::vector<Eigen::Isometry3d> StraightLine(size_t frames, double step_m) {
  std::vector<Eigen::Isometry3d> poses(frames, Eigen::Isometry3d::Identity());
  for (size_t i = 0; i < frames; ++i) poses[i].translation() = Eigen::Vector3d(0, 0, step_m * i);
  return poses;
}

TEST(EvalDevkit, DistancesAndLastFrameUseStrictExcess) {
  const auto poses = StraightLine(11, 0.5);  // 0.5 m is exact in float
  const std::vector<float> dist = TrajectoryDistances(poses);
  ASSERT_EQ(dist.size(), 11u);
  EXPECT_EQ(dist[10], 5.0f);
  EXPECT_EQ(LastFrameFromSegmentLength(dist, 0, 2.0f), 5);  // dist 2.5 > 2.0; 2.0 is not
  EXPECT_EQ(LastFrameFromSegmentLength(dist, 4, 2.0f), 9);
  EXPECT_EQ(LastFrameFromSegmentLength(dist, 6, 2.0f), -1);  // would need dist > 5.0
  EXPECT_EQ(LastFrameFromSegmentLength(dist, 11, 2.0f), -1);
}

TEST(EvalDevkit, RotationAndTranslationErrorOfKnownPoseError) {
  Eigen::Isometry3d E = Eigen::Isometry3d::Identity();
  E.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  E.translation() = Eigen::Vector3d(3, 4, 12);
  EXPECT_NEAR(RotationError(E.matrix()), 0.3, kFloatTol);
  EXPECT_NEAR(TranslationError(E.matrix()), 13.0, kFloatTol * 13);
  // Clamped: a trace slightly above 3 is angle 0, not NaN.
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity() * 1.0000001;
  EXPECT_EQ(RotationError(M), 0.0f);
}

// A constant scale error s on a straight line: every segment's error is
// s * (actual segment length); the devkit divides by the nominal length L and
// the actual length is L + one step (the first frame strictly beyond L).
TEST(EvalDevkit, ConstantScaleErrorOnStraightLine) {
  constexpr double kStepM = 1.0;
  constexpr double kScale = 0.01;
  const auto gt = StraightLine(1001, kStepM);  // 1 km
  auto est = gt;
  for (auto& T : est) T.translation() *= 1.0 + kScale;

  const DevkitConfig config;
  const DevkitResult r = EvaluateDevkit(gt, est, config);
  double expected_sum = 0;
  size_t expected_count = 0;
  for (const LengthAverage& l : r.per_length) {
    const double L = l.length_m;
    const int first_frames = static_cast<int>((1000 - L - kStepM) / config.step_frames) + 1;
    EXPECT_EQ(l.segments, first_frames) << L;
    const double expected = kScale * (L + kStepM) / L;
    ASSERT_TRUE(l.t_err.has_value()) << L;
    EXPECT_NEAR(*l.t_err, expected, kFloatTol * expected) << L;
    EXPECT_NEAR(*l.r_err_rad_per_m, 0.0, kFloatTol) << L;
    expected_sum += expected * first_frames;
    expected_count += static_cast<size_t>(first_frames);
  }
  ASSERT_EQ(r.segments.size(), expected_count);
  EXPECT_NEAR(*r.t_err, expected_sum / expected_count, kFloatTol * 0.01);
  for (const SegmentError& e : r.segments) {
    EXPECT_EQ(e.last_frame - e.first_frame, static_cast<int>(e.length_m / kStepM) + 1);
    EXPECT_NEAR(e.speed_mps, e.length_m / (0.1 * (e.last_frame - e.first_frame + 1)), 1e-3);
  }
}

// Orientation drifting in yaw at k rad per metre (positions exact): the
// rotation error of a segment is k * (its actual length).
TEST(EvalDevkit, YawDriftGivesKnownRotationError) {
  constexpr double kStepM = 1.0;
  constexpr double kDriftRadPerM = 5e-4;
  const auto gt = StraightLine(1001, kStepM);
  auto est = gt;
  for (size_t i = 0; i < est.size(); ++i) {
    est[i].linear() = Eigen::AngleAxisd(kDriftRadPerM * kStepM * i, Eigen::Vector3d::UnitY()).toRotationMatrix();
  }
  const DevkitResult r = EvaluateDevkit(gt, est);
  ASSERT_FALSE(r.segments.empty());
  for (const SegmentError& e : r.segments) {
    const double expected = kDriftRadPerM * (e.length_m + kStepM) / e.length_m;
    EXPECT_NEAR(e.r_err_rad_per_m, expected, kFloatTol * expected + 1e-7) << e.first_frame << " " << e.length_m;
  }
}

TEST(EvalDevkit, ShortTrajectoryHasNoSegments) {
  const auto gt = StraightLine(100, 1.0);  // 99 m
  const DevkitResult r = EvaluateDevkit(gt, gt);
  EXPECT_TRUE(r.segments.empty());
  EXPECT_FALSE(r.t_err.has_value());
  EXPECT_FALSE(r.r_err_rad_per_m.has_value());
  ASSERT_EQ(r.per_length.size(), 8u);
  EXPECT_EQ(r.per_length[0].segments, 0);
  EXPECT_FALSE(r.per_length[0].t_err.has_value());
}

TEST(EvalDevkit, SizeMismatchThrows) {
  const auto gt = StraightLine(10, 1.0);
  const auto est = StraightLine(9, 1.0);
  try {
    EvaluateDevkit(gt, est);
    FAIL() << "no exception";
  } catch (const kitti::Error& e) {
    EXPECT_NE(std::string(e.what()).find("ground truth has 10 poses, estimate has 9"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace locaid::eval
