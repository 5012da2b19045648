// build/bin/locaid-vo as a program: a short rendered drive with and without
// the sliding window, at a lower frame rate, and option errors.
#include "kitti/pose_io.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kBinDir = LOCAID_BIN_DIR;
constexpr int kFrames = 12;
// Devkit-free sanity bound: the end position error over the ~11 m rendered
// drive, for both the default estimate and the windowed one (10x margin).
constexpr double kEndErrorFracTol = 0.01;  // both runs measured ~0.1 %

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// The drive folder locaid-synth wrote under `out` (empty if none).
fs::path DriveIn(const fs::path& out) {
  fs::path drive;
  for (const auto& e : fs::directory_iterator(out))
    if (e.is_directory()) drive = e.path();
  return drive;
}

// Distance between two TUM poses' positions.
double Gap(const locaid::kitti::StampedPose& a, const locaid::kitti::StampedPose& b) {
  return (a.T_world_cam.translation() - b.T_world_cam.translation()).norm();
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Result {
  int status = -1;
  std::string out, err;
};

class VoAppTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<locaid::test_support::ScopedTempDir>("vo_app");
    root_ = *dir_;
    if (!fs::exists(kBinDir / "locaid-vo") || !fs::exists(kBinDir / "locaid-synth")) return;
    const std::string cmd = Quote((kBinDir / "locaid-synth").string()) + " -q --out " +
                            Quote((root_ / "synth").string()) + " --frames " + std::to_string(kFrames) +
                            " --seed 3 >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0) return;
    drive_ = DriveIn(root_ / "synth");
  }
  static void TearDownTestSuite() { dir_.reset(); }

  void SetUp() override {
    ASSERT_TRUE(fs::exists(kBinDir / "locaid-vo")) << "locaid-vo not built (a dependency of vo_tests)";
    ASSERT_FALSE(drive_.empty()) << "locaid-synth did not render a drive under " << root_;
  }

  static Result Run(const std::string& args) {
    const fs::path out = root_ / "stdout.txt", err = root_ / "stderr.txt";
    const std::string cmd = Quote((kBinDir / "locaid-vo").string()) + " " + args + " >" +
                            Quote(out.string()) + " 2>" + Quote(err.string());
    const int raw = std::system(cmd.c_str());
    Result r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = Slurp(out);
    r.err = Slurp(err);
    return r;
  }

  static inline std::unique_ptr<locaid::test_support::ScopedTempDir> dir_;
  static inline fs::path root_, drive_;
};

TEST_F(VoAppTest, WindowedAndDefaultRunsTrackTheRenderedDrive) {
  const auto gt = locaid::kitti::ReadTumPoses(drive_ / "ground_truth_cam0.tum");
  ASSERT_FALSE(gt.empty());
  const double distance = gt.back().T_world_cam.translation().norm();  // the ground truth starts at the origin
  ASSERT_GT(distance, 5.0);
  for (const std::string extra : {"", " --window-keyframes 5"}) {
    const fs::path tum = root_ / "est.tum";
    const Result r = Run("--drive " + Quote(drive_.string()) + " --out-tum " + Quote(tum.string()) +
                         " --json" + extra);
    ASSERT_EQ(r.status, 0) << extra << ": " << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("frames").get<int>(), kFrames) << extra;
    EXPECT_EQ(j.at("failed_frames").get<int>(), 0) << extra;
    const auto est = locaid::kitti::ReadTumPoses(tum);
    ASSERT_EQ(est.size(), static_cast<size_t>(kFrames)) << extra;
    const double err = Gap(est.back(), gt.back());
    std::cout << "[ vo app   ]" << extra << ": end error " << err << " m over " << distance << " m\n";
    EXPECT_LT(err / distance, kEndErrorFracTol) << extra << ": end error " << err << " m over " << distance << " m";
  }
}

// Motorway speed: 25-30 m/s, so 2.5-3 m and up to ~100 px of image motion
// between frames. Rendered with anisotropic filtering (the road as a lens
// sees it); measured end error 0.15 % over 100 m, bound 10x that.
TEST_F(VoAppTest, MotorwaySpeedDriveIsTrackedWithoutFailedFrames) {
  constexpr int kMotorwayFrames = 40;
  constexpr double kMotorwayEndErrorFracTol = 0.015;
  const fs::path out = root_ / "motorway";
  const std::string synth = Quote((kBinDir / "locaid-synth").string()) + " -q --out " + Quote(out.string()) +
                            " --frames " + std::to_string(kMotorwayFrames) +
                            " --seed 5 --speed-min 25 --speed-max 30 --radius-min 300 --radius-max 1500"
                            " --anisotropic >/dev/null 2>&1";
  ASSERT_EQ(std::system(synth.c_str()), 0) << synth;
  const fs::path drive = DriveIn(out);
  ASSERT_FALSE(drive.empty());
  const auto gt = locaid::kitti::ReadTumPoses(drive / "ground_truth_cam0.tum");
  ASSERT_FALSE(gt.empty());
  const double distance = gt.back().T_world_cam.translation().norm();
  ASSERT_GT(distance, 90.0) << "the drive should cover >= 2.5 m per frame";
  const fs::path tum = root_ / "motorway.tum";
  const Result r = Run("--drive " + Quote(drive.string()) + " --out-tum " + Quote(tum.string()) + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("frames").get<int>(), kMotorwayFrames);
  EXPECT_EQ(j.at("failed_frames").get<int>(), 0);
  const auto est = locaid::kitti::ReadTumPoses(tum);
  ASSERT_EQ(est.size(), static_cast<size_t>(kMotorwayFrames));
  const double err = Gap(est.back(), gt.back());
  std::cout << "[ vo app   ] motorway: end error " << err << " m over " << distance << " m\n";
  EXPECT_LT(err / distance, kMotorwayEndErrorFracTol) << "end error " << err << " m over " << distance << " m";
}

// --frame-step 3: frames 0, 3, 6, 9 only (a 3.3 Hz camera), each pose at its
// own frame's time and on the ground truth of that frame.
TEST_F(VoAppTest, FrameStepTracksEveryNthFrameAtItsOwnTime) {
  constexpr int kStep = 3;
  const auto gt = locaid::kitti::ReadTumPoses(drive_ / "ground_truth_cam0.tum");
  ASSERT_EQ(gt.size(), static_cast<size_t>(kFrames));
  const fs::path tum = root_ / "step.tum";
  const Result r = Run("--drive " + Quote(drive_.string()) + " --out-tum " + Quote(tum.string()) +
                       " --json --frame-step " + std::to_string(kStep));
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const int visited = (kFrames + kStep - 1) / kStep;
  EXPECT_EQ(j.at("frames").get<int>(), visited);
  EXPECT_EQ(j.at("frame_step").get<int>(), kStep);
  EXPECT_EQ(j.at("failed_frames").get<int>(), 0);
  const auto est = locaid::kitti::ReadTumPoses(tum);
  ASSERT_EQ(est.size(), static_cast<size_t>(visited));
  for (size_t k = 0; k < est.size(); ++k) {
    const auto& g = gt[k * kStep];
    EXPECT_NEAR(est[k].t_s, g.t_s, 1e-6) << "pose " << k;
    // The estimate starts at the identity like the ground truth file; both
    // are in the first frame's camera axes.
    const double travelled = g.T_world_cam.translation().norm();
    EXPECT_LT(Gap(est[k], g), 0.02 + kEndErrorFracTol * travelled) << "pose " << k;
  }
  const Result zero = Run("--drive " + Quote(drive_.string()) + " --out-tum " + Quote(tum.string()) +
                          " --frame-step 0");
  EXPECT_NE(zero.status, 0);
  EXPECT_NE(zero.err.find("--frame-step"), std::string::npos) << zero.err;
}

TEST_F(VoAppTest, WindowOptionIsRejectedForTheBaselineAndOutOfRange) {
  const std::string base = "--drive " + Quote(drive_.string()) + " --out-tum " + Quote((root_ / "x.tum").string());
  const Result thesis = Run(base + " --method thesis --window-keyframes 3");
  EXPECT_EQ(thesis.status, 2);
  EXPECT_NE(thesis.err.find("--window-keyframes applies to --method default only"), std::string::npos)
      << thesis.err;
  const Result range = Run(base + " --window-keyframes 99");
  EXPECT_NE(range.status, 0);
  EXPECT_NE(range.err.find("--window-keyframes"), std::string::npos) << range.err;
}

}  // namespace
