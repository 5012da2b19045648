// build/bin/locaid-vo as a program: a short rendered drive with and without
// the sliding window, at a lower frame rate, and option errors.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
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
    if (!fs::exists(kBinDir / "locaid-vo") || !fs::exists(kBinDir / "locaid-synth")) return;
    // One folder per process: CTest runs the tests of this suite in parallel.
    root_ = fs::path(::testing::TempDir()) / ("vo_app_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    const std::string cmd = Quote((kBinDir / "locaid-synth").string()) + " -q --out " +
                            Quote((root_ / "synth").string()) + " --frames " + std::to_string(kFrames) +
                            " --seed 3 >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0) return;
    for (const auto& e : fs::directory_iterator(root_ / "synth"))
      if (e.is_directory()) drive_ = e.path();
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  void SetUp() override {
    if (!fs::exists(kBinDir / "locaid-vo")) GTEST_SKIP() << "locaid-vo not built";
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

  // Last TUM position of `file` (timestamp tx ty tz qx qy qz qw per line).
  static std::array<double, 3> LastPosition(const fs::path& file, int* lines) {
    std::ifstream in(file);
    std::array<double, 3> p{};
    *lines = 0;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream ss(line);
      double t = 0;
      ss >> t >> p[0] >> p[1] >> p[2];
      ++*lines;
    }
    return p;
  }

  static inline fs::path root_, drive_;
};

TEST_F(VoAppTest, WindowedAndDefaultRunsTrackTheRenderedDrive) {
  int gt_lines = 0;
  const auto gt = LastPosition(drive_ / "ground_truth_cam0.tum", &gt_lines);
  const double distance = std::hypot(gt[0], gt[1], gt[2]);
  ASSERT_GT(distance, 5.0);
  for (const std::string extra : {"", " --window-keyframes 5"}) {
    const fs::path tum = root_ / "est.tum";
    const Result r = Run("--drive " + Quote(drive_.string()) + " --out-tum " + Quote(tum.string()) +
                         " --json" + extra);
    ASSERT_EQ(r.status, 0) << extra << ": " << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("frames").get<int>(), kFrames) << extra;
    EXPECT_EQ(j.at("failed_frames").get<int>(), 0) << extra;
    int lines = 0;
    const auto est = LastPosition(tum, &lines);
    EXPECT_EQ(lines, kFrames) << extra;
    const double err = std::hypot(est[0] - gt[0], est[1] - gt[1], est[2] - gt[2]);
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
  fs::path drive;
  for (const auto& e : fs::directory_iterator(out))
    if (e.is_directory()) drive = e.path();
  ASSERT_FALSE(drive.empty());
  int gt_lines = 0;
  const auto gt = LastPosition(drive / "ground_truth_cam0.tum", &gt_lines);
  const double distance = std::hypot(gt[0], gt[1], gt[2]);
  ASSERT_GT(distance, 90.0) << "the drive should cover >= 2.5 m per frame";
  const fs::path tum = root_ / "motorway.tum";
  const Result r = Run("--drive " + Quote(drive.string()) + " --out-tum " + Quote(tum.string()) + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("frames").get<int>(), kMotorwayFrames);
  EXPECT_EQ(j.at("failed_frames").get<int>(), 0);
  int lines = 0;
  const auto est = LastPosition(tum, &lines);
  EXPECT_EQ(lines, kMotorwayFrames);
  const double err = std::hypot(est[0] - gt[0], est[1] - gt[1], est[2] - gt[2]);
  std::cout << "[ vo app   ] motorway: end error " << err << " m over " << distance << " m\n";
  EXPECT_LT(err / distance, kMotorwayEndErrorFracTol) << "end error " << err << " m over " << distance << " m";
}

// --frame-step 3: frames 0, 3, 6, 9 only (a 3.3 Hz camera), each pose at its
// own frame's time and on the ground truth of that frame.
TEST_F(VoAppTest, FrameStepTracksEveryNthFrameAtItsOwnTime) {
  constexpr int kStep = 3;
  std::vector<std::array<double, 4>> gt;  // t, x, y, z per frame
  {
    std::ifstream in(drive_ / "ground_truth_cam0.tum");
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream ss(line);
      std::array<double, 4> row{};
      ss >> row[0] >> row[1] >> row[2] >> row[3];
      gt.push_back(row);
    }
  }
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
  std::ifstream in(tum);
  int k = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    double t = 0, x = 0, y = 0, z = 0;
    ss >> t >> x >> y >> z;
    ASSERT_LT(k * kStep, kFrames);
    const auto& g = gt[static_cast<size_t>(k * kStep)];
    EXPECT_NEAR(t, g[0], 1e-6) << "pose " << k;
    // The estimate starts at the identity like the ground truth file; both
    // are in the first frame's camera axes.
    const double travelled = std::hypot(g[1], g[2], g[3]);
    EXPECT_LT(std::hypot(x - g[1], y - g[2], z - g[3]), 0.02 + kEndErrorFracTol * travelled) << "pose " << k;
    ++k;
  }
  EXPECT_EQ(k, visited);
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
