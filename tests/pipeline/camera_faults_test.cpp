// The camera fault stage (pipeline/camera_faults.hpp): each fault's effect on
// the pixels, the windows' clock (from the first frame), run-time injection,
// Stop and SetScenario, seeded repeatability.
#include "pipeline/camera_faults.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <vector>

namespace locaid::pipeline {
namespace {

using sim::CameraFaultKind;
using sim::CameraFaultWindow;

constexpr int64_t kT0 = 5'000'000'000'000;  // first frame, ns
constexpr int64_t kPeriod = 100'000'000;    // 10 Hz
// Tolerances of the pixel statistics over a 320x240 image (76,800 pixels).
constexpr double kMeanTolDn = 0.3;
constexpr double kSigmaTolFrac = 0.05;

// A textured pair, different for every frame index (a moving camera).
vo::StereoFrame TexturedFrame(int index) {
  cv::Mat left(240, 320, CV_8UC1), right(240, 320, CV_8UC1);
  cv::RNG rng(static_cast<uint64_t>(1000 + index));
  rng.fill(left, cv::RNG::UNIFORM, 40, 216);
  rng.fill(right, cv::RNG::UNIFORM, 40, 216);
  return {kT0 + index * kPeriod, left, right};
}

CameraFaultWindow Fault(CameraFaultKind kind, double start_s, double duration_s) {
  CameraFaultWindow w;
  w.kind = kind;
  w.start_s = start_s;
  w.duration_s = duration_s;
  return w;
}

sim::Scenario WithFaults(std::vector<CameraFaultWindow> faults, uint64_t seed = 1) {
  sim::Scenario s;
  s.name = "test";
  s.camera_faults = std::move(faults);
  s.seed = seed;
  return s;
}

// Mean and standard deviation of (a - b * scale) over the image.
void DifferenceStats(const cv::Mat& a, const cv::Mat& b, double scale, double* mean, double* sigma) {
  cv::Mat fa, fb;
  a.convertTo(fa, CV_64F);
  b.convertTo(fb, CV_64F, scale);
  cv::Scalar m, s;
  cv::meanStdDev(fa - fb, m, s);
  *mean = m[0];
  *sigma = s[0];
}

bool Same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// Frame 0 through a stage that holds only `fault`.
vo::StereoFrame Faulted(const CameraFaultWindow& fault) {
  CameraFaultStage stage(WithFaults({fault}));
  vo::StereoFrame f = TexturedFrame(0);
  stage.Apply(f);
  return f;
}

TEST(CameraFaults, NoFaultLeavesTheFrameUntouched) {
  CameraFaultStage stage(WithFaults({}));
  vo::StereoFrame f = TexturedFrame(0);
  const cv::Mat left = f.left, right = f.right;
  stage.Apply(f);
  EXPECT_EQ(f.left.data, left.data) << "no copy without a fault";
  EXPECT_EQ(f.right.data, right.data);
}

CameraFaultWindow Dark(double gain, double noise_dn) {
  CameraFaultWindow dark = Fault(CameraFaultKind::kDark, 0, 10);
  dark.gain = gain;
  dark.noise_dn = noise_dn;
  return dark;
}

TEST(CameraFaults, DarkScalesByTheGainAndAddsTheNoise) {
  const CameraFaultWindow dark = Dark(0.25, 3);
  CameraFaultStage stage(WithFaults({dark}));
  vo::StereoFrame f = TexturedFrame(0);
  const cv::Mat source_left = f.left;  // the source's buffer
  const vo::StereoFrame original = TexturedFrame(0);
  stage.Apply(f);
  ASSERT_EQ(f.left.type(), CV_8UC1);
  double mean = 0, sigma = 0;
  DifferenceStats(f.left, original.left, dark.gain, &mean, &sigma);
  EXPECT_NEAR(mean, 0, kMeanTolDn);
  // Noise of 3 DN plus rounding to whole numbers (uniform, 1/sqrt(12) DN).
  EXPECT_NEAR(sigma, std::hypot(3.0, 1 / std::sqrt(12.0)), 3 * kSigmaTolFrac);
  EXPECT_FALSE(Same(f.left, f.right));
  EXPECT_TRUE(Same(source_left, original.left)) << "the source's image was written";
}

TEST(CameraFaults, DarkWithoutNoiseIsTheRoundedGainAndClampsToTheRange) {
  const cv::Mat dark = Faulted(Dark(0.06, 0)).left, original = TexturedFrame(0).left;
  for (int y = 0; y < original.rows; y += 17)
    for (int x = 0; x < original.cols; x += 13)
      EXPECT_EQ(dark.at<uchar>(y, x), cvRound(original.at<uchar>(y, x) * 0.06)) << x << "," << y;
  // Noise that would go below 0 is clamped, not wrapped.
  double lo = 0, hi = 0;
  cv::minMaxLoc(Faulted(Dark(0.06, 50)).left, &lo, &hi);
  EXPECT_EQ(lo, 0);
  EXPECT_GT(hi, 60);
}

TEST(CameraFaults, NoiseAddsGaussianNoiseOfTheGivenSigma) {
  CameraFaultWindow noise = Fault(CameraFaultKind::kNoise, 0, 10);
  noise.noise_dn = 8;
  double mean = 0, sigma = 0;
  DifferenceStats(Faulted(noise).right, TexturedFrame(0).right, 1.0, &mean, &sigma);
  EXPECT_NEAR(mean, 0, kMeanTolDn);
  EXPECT_NEAR(sigma, 8, 8 * kSigmaTolFrac);
}

TEST(CameraFaults, BlurIsAGaussianBlurOfTheGivenSigma) {
  CameraFaultWindow blur = Fault(CameraFaultKind::kBlur, 0, 10);
  blur.blur_sigma_px = 2;
  const vo::StereoFrame f = Faulted(blur), original = TexturedFrame(0);
  cv::Mat expected;
  cv::GaussianBlur(original.left, expected, cv::Size(0, 0), 2);
  EXPECT_TRUE(Same(f.left, expected));
  cv::Scalar m, before, after;
  cv::meanStdDev(original.left, m, before);
  cv::meanStdDev(f.left, m, after);
  EXPECT_LT(after[0], 0.5 * before[0]) << "white texture loses most of its contrast";
}

TEST(CameraFaults, FrozenRepeatsTheLastPairBeforeItExactlyWithNewTimes) {
  // Frames 0-9 normal, 10-19 frozen, 20 on fresh.
  CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kFrozen, 1.0, 1.0)}));
  vo::StereoFrame last_good;
  for (int i = 0; i < 25; ++i) {
    vo::StereoFrame f = TexturedFrame(i);
    stage.Apply(f);
    EXPECT_EQ(f.t_ns, kT0 + i * kPeriod) << "frame " << i;
    if (i == 9) last_good = {f.t_ns, f.left.clone(), f.right.clone()};
    if (i >= 10 && i < 20) {
      EXPECT_TRUE(Same(f.left, last_good.left)) << "frame " << i;
      EXPECT_TRUE(Same(f.right, last_good.right)) << "frame " << i;
    } else {
      EXPECT_TRUE(Same(f.left, TexturedFrame(i).left)) << "frame " << i;
    }
  }
}

TEST(CameraFaults, DropAndOneSidedFaultsGiveEmptyImages) {
  CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kDrop, 0.1, 0.1), Fault(CameraFaultKind::kLeftOnly, 0.2, 0.1),
                                     Fault(CameraFaultKind::kRightOnly, 0.3, 0.1)}));
  std::vector<std::pair<bool, bool>> present;  // left, right
  for (int i = 0; i < 5; ++i) {
    vo::StereoFrame f = TexturedFrame(i);
    stage.Apply(f);
    present.emplace_back(!f.left.empty(), !f.right.empty());
  }
  const std::vector<std::pair<bool, bool>> expected = {{true, true}, {false, false}, {true, false}, {false, true},
                                                       {true, true}};
  EXPECT_EQ(present, expected);
}

TEST(CameraFaults, SameSeedSameImagesOtherSeedOtherNoise) {
  const auto run = [](uint64_t seed) {
    CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kDark, 0, 10)}, seed));
    std::vector<cv::Mat> out;
    for (int i = 0; i < 3; ++i) {
      vo::StereoFrame f = TexturedFrame(i);
      stage.Apply(f);
      out.push_back(f.left);
    }
    return out;
  };
  const auto a = run(7), b = run(7), c = run(8);
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_TRUE(Same(a[i], b[i])) << "frame " << i;
    EXPECT_FALSE(Same(a[i], c[i])) << "frame " << i;
  }
}

// Which of frames 0..n-1 a drop fault emptied.
std::vector<int> DroppedFrames(CameraFaultStage& stage, int n, int64_t first_ns = kT0,
                               const std::function<void(int)>& before = nullptr) {
  std::vector<int> dropped;
  for (int i = 0; i < n; ++i) {
    if (before) before(i);
    vo::StereoFrame f = TexturedFrame(i);
    f.t_ns = first_ns + i * kPeriod;
    stage.Apply(f);
    if (f.left.empty()) dropped.push_back(i);
  }
  return dropped;
}

TEST(CameraFaults, WindowsCountFromTheFirstFrameStartInclusiveEndExclusive) {
  // [0.5, 0.8) s: frames 5, 6, 7, whatever the absolute time of the first frame.
  for (int64_t first : {int64_t{0}, kT0, int64_t{123'456'789}}) {
    CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kDrop, 0.5, 0.3)}));
    EXPECT_EQ(DroppedFrames(stage, 12, first), (std::vector<int>{5, 6, 7})) << "first frame at " << first;
  }
}

TEST(CameraFaults, InjectedFaultsStartNowForADurationOrUntilStop) {
  CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kDrop, 2.0, 0.2)}));  // frames 20, 21
  stage.AddWindow(Fault(CameraFaultKind::kDrop, 0.1, 0.1));  // before the first frame: frame 1
  const auto dropped = DroppedFrames(stage, 30, kT0, [&stage](int i) {
    if (i == 5) stage.StartNow(Fault(CameraFaultKind::kDrop, 0, 0), 0.3);  // frames 5, 6, 7
    if (i == 10) stage.StartNow(Fault(CameraFaultKind::kDrop, 0, 0), 0);   // from 10 until Stop
    if (i == 14) stage.Stop();                                             // 14 on: fresh, but 20, 21
  });
  EXPECT_EQ(dropped, (std::vector<int>{1, 5, 6, 7, 10, 11, 12, 13, 20, 21}));
}

TEST(CameraFaults, SetScenarioKeepsTheClockAndTheInjectedFaults) {
  CameraFaultStage stage(WithFaults({Fault(CameraFaultKind::kDrop, 0.2, 0.1)}));
  const auto dropped = DroppedFrames(stage, 12, kT0, [&stage](int i) {
    if (i == 3) stage.Inject(CameraFaultAction::kWindow, Fault(CameraFaultKind::kDrop, 1.0, 0.1));
    if (i == 4) stage.SetScenario(WithFaults({Fault(CameraFaultKind::kDrop, 0.6, 0.1)}));
  });
  EXPECT_EQ(dropped, (std::vector<int>{2, 6, 10}));
}

TEST(CameraFaults, OutOfRangeValuesAreRefusedNamingTheField) {
  sim::Scenario s = WithFaults({Fault(CameraFaultKind::kDark, 0, 10)});
  s.camera_faults[0].gain = 1.5;
  try {
    CameraFaultStage stage(s);
    ADD_FAILURE() << "gain 1.5 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("field camera[0].gain: must be in (0, 1], got 1.5"), std::string::npos)
        << e.what();
  }
  CameraFaultStage stage(WithFaults({}));
  CameraFaultWindow bad = Fault(CameraFaultKind::kNoise, 0, 1);
  bad.noise_dn = std::nan("");
  EXPECT_THROW(stage.AddWindow(bad), std::invalid_argument);
  EXPECT_THROW(stage.AddWindow(Fault(CameraFaultKind::kDrop, -1, 1)), std::invalid_argument);
  EXPECT_THROW(stage.AddWindow(Fault(CameraFaultKind::kDrop, 0, 0)), std::invalid_argument);
  EXPECT_THROW(stage.StartNow(Fault(CameraFaultKind::kDrop, 0, 0), -1), std::invalid_argument);
  CameraFaultWindow blur = Fault(CameraFaultKind::kBlur, 0, 1);
  blur.blur_sigma_px = 51;
  EXPECT_THROW(stage.StartNow(blur, 1), std::invalid_argument);
}

}  // namespace
}  // namespace locaid::pipeline
