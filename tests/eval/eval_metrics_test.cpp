// ATE, RPE, SE(3) alignment, timestamp association and file matching.
#include "eval/associate.hpp"
#include "error_of.hpp"
#include "eval/evaluate.hpp"
#include "eval/trajectory_metrics.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/types.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>
#include <Eigen/Geometry>

namespace locaid::eval {
namespace {

namespace fs = std::filesystem;

constexpr double kExactTol = 1e-9;  // double arithmetic on O(100 m) values

Eigen::Isometry3d Pose(const Eigen::Vector3d& axis, double angle_rad, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// A wiggly 3D drive with fixed seed: 200 frames, ~1 m apart, turning.
std::vector<Eigen::Isometry3d> Drive(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::vector<Eigen::Isometry3d> poses;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 200; ++i) {
    poses.push_back(T);
    T = T * Pose(Eigen::Vector3d(noise(rng), 1, noise(rng)), 0.02 + noise(rng),
                 Eigen::Vector3d(noise(rng), noise(rng), 1.0));
  }
  return poses;
}

std::string ErrorOf(const std::function<void()>& f) { return locaid::test_support::ErrorOf<kitti::Error>(f); }

TEST(EvalStats, KnownValues) {
  const ErrorStats s = ComputeStats({3, 1, 4, 2});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4));
  EXPECT_DOUBLE_EQ(ComputeStats({5, 1, 3}).median, 3);
  EXPECT_EQ(ComputeStats({}).count, 0u);
}

TEST(EvalRotationAngle, SmallAndLargeAngles) {
  for (double angle : {0.0, 1e-9, 1e-4, 0.5, 3.0, M_PI}) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
    EXPECT_NEAR(RotationAngleRad(R), angle, 1e-12 + 1e-9 * angle) << angle;
  }
}

TEST(EvalAlign, RecoversKnownTransform) {
  const auto gt = Drive(3);
  const Eigen::Isometry3d T_gt_est = Pose(Eigen::Vector3d(0.3, -1, 2), 1.1, Eigen::Vector3d(10, -20, 5));
  std::vector<Eigen::Vector3d> src, dst;
  for (const auto& T : gt) {
    dst.push_back(T.translation());
    src.push_back(T_gt_est.inverse() * T.translation());
  }
  const Eigen::Isometry3d T = AlignSe3(src, dst);
  EXPECT_TRUE(T.matrix().isApprox(T_gt_est.matrix(), kExactTol)) << T.matrix();
  EXPECT_NE(ErrorOf([] { AlignSe3({}, {}); }), "(no error)");
}

TEST(EvalAte, AlignedIsZeroForRigidlyMovedTrajectoryUnalignedIsTheOffset) {
  const auto gt = Drive(5);
  const Eigen::Isometry3d T_est_gt = Pose(Eigen::Vector3d::UnitZ(), 0.7, Eigen::Vector3d(3, 4, 0));
  std::vector<Eigen::Isometry3d> est;
  for (const auto& T : gt) est.push_back(T_est_gt * T);
  const AteResult aligned = ComputeAte(gt, est, Alignment::kSe3);
  EXPECT_LT(aligned.trans_m.rmse, kExactTol);
  EXPECT_TRUE(aligned.T_gtworld_estworld.matrix().isApprox(T_est_gt.inverse().matrix(), kExactTol));

  // A pure offset of (3, 4, 0): every unaligned error is exactly 5 m.
  std::vector<Eigen::Isometry3d> shifted = gt;
  for (auto& T : shifted) T.translation() += Eigen::Vector3d(3, 4, 0);
  const AteResult none = ComputeAte(gt, shifted, Alignment::kNone);
  EXPECT_NEAR(none.trans_m.rmse, 5.0, kExactTol);
  EXPECT_NEAR(none.trans_m.max, 5.0, kExactTol);
  EXPECT_LT(ComputeAte(gt, shifted, Alignment::kSe3).trans_m.rmse, kExactTol);
}

TEST(EvalRpe, ConstantPerFrameErrors) {
  // gt: 1 m per frame along z. est: 1.1 m per frame and 0.01 rad extra yaw per frame.
  std::vector<Eigen::Isometry3d> gt, est;
  Eigen::Isometry3d Tg = Eigen::Isometry3d::Identity(), Te = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d step_gt = Pose(Eigen::Vector3d::UnitY(), 0.0, Eigen::Vector3d(0, 0, 1.0));
  const Eigen::Isometry3d step_est = Pose(Eigen::Vector3d::UnitY(), 0.01, Eigen::Vector3d(0, 0, 1.1));
  for (int i = 0; i < 50; ++i) {
    gt.push_back(Tg);
    est.push_back(Te);
    Tg = Tg * step_gt;
    Te = Te * step_est;
  }
  const RpeResult r = ComputeRpe(gt, est);
  EXPECT_EQ(r.trans_m.count, 49u);
  EXPECT_NEAR(r.trans_m.rmse, 0.1, kExactTol);
  EXPECT_NEAR(r.trans_m.max, 0.1, kExactTol);
  EXPECT_NEAR(r.rot_deg.median, 0.01 * 180 / M_PI, kExactTol);
  const RpeResult zero = ComputeRpe(gt, gt);
  EXPECT_EQ(zero.trans_m.max, 0.0);
  EXPECT_EQ(zero.rot_deg.max, 0.0);
}

TEST(EvalEvaluate, CombinesAllMetrics) {
  const auto gt = Drive(9);
  const EvalReport r = Evaluate(gt, gt);
  EXPECT_EQ(r.frames, gt.size());
  EXPECT_NEAR(r.length_m, PathLengthM(gt), 0.0);
  EXPECT_GT(r.length_m, 190.0);
  EXPECT_FALSE(r.devkit.segments.empty());
  EXPECT_LT(*r.devkit.t_err, kExactTol);
  EXPECT_LT(r.ate.trans_m.rmse, kExactTol);
  EXPECT_NE(ErrorOf([&] { Evaluate(gt, {}); }), "(no error)");
}

TEST(EvalAssociate, MissingJitteredAndDuplicateStamps) {
  // gt at 10 Hz; est jittered by a few ms, missing some, plus strays.
  std::vector<double> t_gt;
  for (int i = 0; i < 10; ++i) t_gt.push_back(100.0 + 0.1 * i);
  const std::vector<double> t_est = {
      100.003,  // -> gt 0
      100.098,  // -> gt 1
      // gt 2 missing in est
      100.305,  // -> gt 3
      100.31,   // closer stamp for gt 3 is taken above; 0.01 away is second best -> unmatched
      100.45,   // 0.05 from gt 4 and 5: beyond max_dt -> unmatched
      100.719,  // -> gt 7 (0.019 <= 0.02)
      100.825,  // 0.025 from gt 8 -> unmatched
      100.9,    // -> gt 9 exactly
  };
  const auto pairs = AssociateByTime(t_gt, t_est, 0.02);
  const std::vector<std::pair<size_t, size_t>> expected = {{0, 0}, {1, 1}, {3, 2}, {7, 5}, {9, 7}};
  ASSERT_EQ(pairs.size(), expected.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    EXPECT_EQ(pairs[k].gt, expected[k].first) << k;
    EXPECT_EQ(pairs[k].est, expected[k].second) << k;
  }
  // The closest pair wins even if it comes later in the est list.
  const auto p2 = AssociateByTime({1.0}, {1.015, 1.001}, 0.02);
  ASSERT_EQ(p2.size(), 1u);
  EXPECT_EQ(p2[0].est, 1u);
  EXPECT_TRUE(AssociateByTime({}, {1.0}, 0.02).empty());
  EXPECT_NE(ErrorOf([] { AssociateByTime({1.0}, {1.0}, -1.0); }), "(no error)");
}

class EvalMatchTest : public ::testing::Test {
 protected:
  const locaid::test_support::ScopedTempDir dir_{"eval_match"};
};

TEST_F(EvalMatchTest, TumByTimeKittiByLine) {
  const auto poses = Drive(1);
  std::vector<kitti::StampedPose> gt, est;
  for (size_t i = 0; i < poses.size(); ++i) {
    gt.push_back({50.0 + 0.1 * i, poses[i]});
    if (i % 3 != 0) est.push_back({50.0 + 0.1 * i + 0.004, poses[i]});  // 2 of 3 frames
  }
  kitti::WriteTumPoses(dir_ / "gt.tum", gt);
  kitti::WriteTumPoses(dir_ / "est.tum", est);
  const MatchedPoses m = LoadMatchedPoses(dir_ / "gt.tum", dir_ / "est.tum", 0.02);
  EXPECT_EQ(m.format, kitti::PoseFormat::kTum);
  EXPECT_EQ(m.gt_count, poses.size());
  EXPECT_EQ(m.est_count, est.size());
  ASSERT_EQ(m.gt.size(), est.size());
  for (size_t k = 0; k < m.gt.size(); ++k) {
    EXPECT_TRUE(m.gt[k].isApprox(m.est[k], 1e-12)) << k;
  }
  // Tolerance smaller than the 4 ms offset: nothing matches.
  const std::string e = ErrorOf([&] { LoadMatchedPoses(dir_ / "gt.tum", dir_ / "est.tum", 0.001); });
  EXPECT_NE(e.find("only 0 matched poses"), std::string::npos) << e;

  std::vector<Eigen::Isometry3d> k_est(poses.begin(), poses.end() - 1);
  kitti::WriteKittiPoses(dir_ / "gt.txt", poses);
  kitti::WriteKittiPoses(dir_ / "est.txt", k_est);
  const std::string e2 = ErrorOf([&] { LoadMatchedPoses(dir_ / "gt.txt", dir_ / "est.txt", 0.02); });
  EXPECT_NE(e2.find("has 200 poses but estimate " + (dir_ / "est.txt").string() + " has 199"),
            std::string::npos)
      << e2;
  const std::string e3 = ErrorOf([&] { LoadMatchedPoses(dir_ / "gt.txt", dir_ / "est.tum", 0.02); });
  EXPECT_NE(e3.find("is KITTI but estimate"), std::string::npos) << e3;

  kitti::WriteKittiPoses(dir_ / "est.txt", poses);
  const MatchedPoses mk = LoadMatchedPoses(dir_ / "gt.txt", dir_ / "est.txt", 0.02);
  EXPECT_EQ(mk.format, kitti::PoseFormat::kKitti);
  EXPECT_EQ(mk.gt.size(), poses.size());
  EXPECT_EQ(mk.t_s[5], 5.0);
}

}  // namespace
}  // namespace locaid::eval
