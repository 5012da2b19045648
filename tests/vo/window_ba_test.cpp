// vo/window_ba.hpp: the sliding-window stereo bundle adjustment on scenes with
// known poses and points.
#include "core/stereo_camera.hpp"
#include "vo/window_ba.hpp"

#include "tests/vo/synthetic_scene.hpp"
#include "vo/stereo_geometry.hpp"

#include <gtest/gtest.h>

#include <random>

namespace locaid::vo {
namespace {

constexpr double kExactPoseTolM = 1e-6;      // noise-free data: solved to round-off
constexpr double kExactPoseTolRad = 1e-8;
// Two runs stopped by the relative cost criterion (1e-6) on the same minimum.
constexpr double kSameMinimumTolM = 1e-4;
constexpr double kSameMinimumTolRad = 1e-6;
// 0.3 px noise, 5 frames, 300 points at 8-40 m: the least-squares minimum is
// ~1 cm / 1 mrad from the truth (yaw and lateral translation trade off).
constexpr double kNoisyPoseTolM = 0.03;
constexpr double kNoisyPoseTolRad = 3e-3;

struct Scene {
  std::vector<Eigen::Isometry3d> T_w_c;  // truth
  std::vector<Eigen::Vector3d> p_w;      // truth
  WindowProblem problem;                 // observations of the truth
};

// Five frames 1 m apart along z with a slow turn; points in front of all of
// them, each observed in every frame (left + right), with pixel noise sigma_px.
Scene MakeScene(double sigma_px, uint32_t seed) {
  const StereoCamera cam = testing::SyntheticCamera();
  Scene s;
  for (int f = 0; f < 5; ++f) {
    Vector6d d;
    d << 0.02 * f, 0.005 * f, 1.0 * f, 0.001 * f, 0.01 * f, 0.0;
    s.T_w_c.push_back(ExpSE3(d));
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-8, 8), uy(-2, 1.5), uz(8, 40);
  std::normal_distribution<double> noise(0, 1);
  while (s.p_w.size() < 300) {
    const Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
    std::vector<WindowObservation> obs;
    for (int f = 0; f < 5; ++f) {
      const Eigen::Vector3d q = s.T_w_c[static_cast<size_t>(f)].inverse() * p;
      WindowObservation o;
      o.frame = f;
      o.point = static_cast<int>(s.p_w.size());
      o.uv_left = {cam.fx * q.x() / q.z() + cam.cx + sigma_px * noise(rng),
                   cam.fy * q.y() / q.z() + cam.cy + sigma_px * noise(rng)};
      o.u_right = cam.fx * (q.x() - cam.baseline_m) / q.z() + cam.cx + sigma_px * noise(rng);
      o.has_right = true;
      if (o.uv_left.x() < 0 || o.uv_left.x() >= cam.width || o.uv_left.y() < 0 ||
          o.uv_left.y() >= cam.height)
        break;
      obs.push_back(o);
    }
    if (obs.size() < 5) continue;
    s.p_w.push_back(p);
    s.problem.observations.insert(s.problem.observations.end(), obs.begin(), obs.end());
  }
  s.problem.T_w_c = s.T_w_c;
  s.problem.p_w = s.p_w;
  return s;
}

// Moves every pose but the first and every point away from the truth.
void Perturb(WindowProblem& problem, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 1);
  for (size_t f = 1; f < problem.T_w_c.size(); ++f) {
    Vector6d d;
    d << 0.05 * n(rng), 0.05 * n(rng), 0.05 * n(rng), 0.003 * n(rng), 0.003 * n(rng),
        0.003 * n(rng);
    problem.T_w_c[f] = problem.T_w_c[f] * ExpSE3(d);
  }
  for (Eigen::Vector3d& p : problem.p_w) p += 0.1 * Eigen::Vector3d(n(rng), n(rng), n(rng));
}

void ExpectPosesNear(const WindowProblem& problem, const std::vector<Eigen::Isometry3d>& truth,
                     double tol_m, double tol_rad) {
  for (size_t f = 0; f < truth.size(); ++f) {
    const Eigen::Isometry3d err = truth[f].inverse() * problem.T_w_c[f];
    EXPECT_LT(err.translation().norm(), tol_m) << "frame " << f;
    EXPECT_LT(Eigen::AngleAxisd(err.rotation()).angle(), tol_rad) << "frame " << f;
  }
}

TEST(WindowBa, RecoversPosesAndPointsFromExactObservations) {
  Scene s = MakeScene(0.0, 1);
  Perturb(s.problem, 2);
  WindowOptions options;
  options.iterations = 10;
  const WindowResult r = SolveWindow(s.problem, testing::SyntheticCamera(), options);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.points_used, 300);
  EXPECT_LT(r.final_cost, 1e-10 * r.initial_cost);
  ExpectPosesNear(s.problem, s.T_w_c, kExactPoseTolM, kExactPoseTolRad);
  for (size_t i = 0; i < s.p_w.size(); ++i)
    EXPECT_LT((s.problem.p_w[i] - s.p_w[i]).norm(), 1e-4) << "point " << i;
  for (char o : r.outlier) EXPECT_FALSE(o);
}

TEST(WindowBa, NoisyObservationsWithOutliersReachTheSameMinimumFromAPerturbedStart) {
  Scene s = MakeScene(0.3, 3);
  // Every 20th observation is 15 px off.
  for (size_t i = 0; i < s.problem.observations.size(); i += 20)
    s.problem.observations[i].uv_left += Eigen::Vector2d(15, -6);
  WindowProblem from_truth = s.problem;
  WindowOptions options;
  options.iterations = 20;
  const WindowResult t = SolveWindow(from_truth, testing::SyntheticCamera(), options);
  Perturb(s.problem, 4);
  const WindowResult r = SolveWindow(s.problem, testing::SyntheticCamera(), options);
  ASSERT_TRUE(t.ok);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_NEAR(r.final_cost, t.final_cost, 1e-6 * t.final_cost);
  ExpectPosesNear(s.problem, from_truth.T_w_c, kSameMinimumTolM, kSameMinimumTolRad);
  // The minimum itself is within the noise of the truth.
  ExpectPosesNear(s.problem, s.T_w_c, kNoisyPoseTolM, kNoisyPoseTolRad);
  int flagged = 0, wrong = 0;
  for (size_t i = 0; i < r.outlier.size(); ++i) {
    const bool planted = i % 20 == 0;
    flagged += planted && r.outlier[i];
    wrong += !planted && r.outlier[i];
  }
  const int planted = static_cast<int>((r.outlier.size() + 19) / 20);
  EXPECT_EQ(flagged, planted);
  EXPECT_LT(wrong, static_cast<int>(r.outlier.size()) / 100);
}

TEST(WindowBa, TheHeldFrameAndSingleFramePointsDoNotMove) {
  Scene s = MakeScene(0.3, 5);
  Perturb(s.problem, 6);
  // One extra point seen only by frame 2.
  const Eigen::Vector3d lonely(1, 0.5, 20);
  s.problem.p_w.push_back(lonely);
  WindowObservation o;
  o.frame = 2;
  o.point = static_cast<int>(s.problem.p_w.size()) - 1;
  o.uv_left = {600, 200};
  o.u_right = 580;
  o.has_right = true;
  s.problem.observations.push_back(o);
  s.problem.fixed_frames = 2;
  const std::vector<Eigen::Isometry3d> before = s.problem.T_w_c;
  const WindowResult r = SolveWindow(s.problem, testing::SyntheticCamera());
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.points_used, 300);
  EXPECT_TRUE(s.problem.T_w_c[0].isApprox(before[0]));
  EXPECT_TRUE(s.problem.T_w_c[1].isApprox(before[1]));
  EXPECT_FALSE(s.problem.T_w_c[2].isApprox(before[2]));
  EXPECT_EQ(s.problem.p_w.back(), lonely);
}

TEST(WindowBa, MalformedProblemIsRejectedUnchanged) {
  Scene s = MakeScene(0.0, 7);
  Perturb(s.problem, 8);
  s.problem.observations[3].frame = 9;  // no such frame
  const WindowProblem before = s.problem;
  const WindowResult r = SolveWindow(s.problem, testing::SyntheticCamera());
  EXPECT_FALSE(r.ok);
  for (size_t f = 0; f < before.T_w_c.size(); ++f)
    EXPECT_TRUE(s.problem.T_w_c[f].isApprox(before.T_w_c[f]));
  EXPECT_EQ(s.problem.p_w, before.p_w);
}

TEST(WindowBa, PointsBehindTheCameraAreOutliersNotCrashes) {
  Scene s = MakeScene(0.0, 9);
  s.problem.p_w[0] = Eigen::Vector3d(0, 0, -5);  // behind every frame
  const WindowResult r = SolveWindow(s.problem, testing::SyntheticCamera());
  ASSERT_TRUE(r.ok);
  for (size_t i = 0; i < r.outlier.size(); ++i) {
    if (s.problem.observations[i].point == 0) {
      EXPECT_TRUE(r.outlier[i]) << "observation " << i;
    }
  }
  ExpectPosesNear(s.problem, s.T_w_c, kExactPoseTolM, kExactPoseTolRad);
}

}  // namespace
}  // namespace locaid::vo
