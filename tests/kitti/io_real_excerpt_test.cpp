// Reads the real KITTI excerpts in LOCAID_SHARED_DATA (KITTI, CC BY-NC-SA 3.0;
// see data/kitti/README.md). Skipped when the data is absent.
#include "core/stereo_camera.hpp"
#include "error_of.hpp"
#include "kitti/dataset.hpp"
#include "kitti/odometry_sequence.hpp"
#include "kitti/raw_drive.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include <filesystem>
#include <string>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;

const fs::path kShared = LOCAID_SHARED_DATA;
const fs::path kDrive = kShared / "raw/2011_09_26/2011_09_26_drive_unknown_extract";
const fs::path kSeq00 = kShared / "odometry/sequences/00";

// The kitti::Error of loading frame i, or "(no error)".
std::string LoadError(const StereoDataset& ds, size_t i) {
  return test_support::ErrorOf<Error>([&] { ds.Load(i); });
}

class RealExtractDrive : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (fs::is_directory(kDrive)) ds_ = OpenDataset(kDrive).release();
  }
  static void TearDownTestSuite() {
    delete ds_;
    ds_ = nullptr;
  }
  void SetUp() override {
    if (ds_ == nullptr) GTEST_SKIP() << "real KITTI excerpt absent: " << kDrive;
  }
  static StereoDataset* ds_;
};
StereoDataset* RealExtractDrive::ds_ = nullptr;

TEST_F(RealExtractDrive, LayoutFramesAndDefects) {
  EXPECT_EQ(ds_->kind(), "raw_extract");
  EXPECT_EQ(ds_->size(), 200u);
  const DatasetReport& r = ds_->report();
  EXPECT_EQ(r.missing_left, std::vector<int>{23});
  EXPECT_EQ(r.missing_right, std::vector<int>{22});
  EXPECT_FALSE(ds_->has_stereo(22));
  EXPECT_FALSE(ds_->has_stereo(23));
  EXPECT_TRUE(ds_->has_stereo(21));
  EXPECT_TRUE(ds_->has_stereo(24));
  EXPECT_EQ(r.oxts_records, 671);
  EXPECT_EQ(r.oxts_expected, 4129 - 3 + 1);
  EXPECT_TRUE(r.oxts_timestamps_estimated);
  for (const auto& n : r.notes) std::printf("  note: %s\n", n.c_str());
  // First timestamp line: 2011-09-26 14:05:35.500923136.
  EXPECT_EQ(ds_->time_ns(0) % 1'000'000'000LL, 500'923'136);
  EXPECT_DOUBLE_EQ(ds_->tum_time_s(0), 0.0);
  EXPECT_NEAR(ds_->tum_time_s(1), 0.102019328, 1e-12);
}

TEST_F(RealExtractDrive, CameraModelFromRectifiedCalib) {
  const StereoCamera& c = ds_->camera();
  EXPECT_DOUBLE_EQ(c.fx, 7.215377e+02);
  EXPECT_DOUBLE_EQ(c.cy, 1.728540e+02);
  EXPECT_NEAR(c.baseline_m, 3.875744e+02 / 7.215377e+02, 1e-12);
  EXPECT_EQ(c.width, 1242);
  EXPECT_EQ(c.height, 375);
}

TEST_F(RealExtractDrive, LoadRectifiesAndNamesMissingFiles) {
  const StereoImages im = ds_->Load(0);
  EXPECT_EQ(im.left.cols, 1242);
  EXPECT_EQ(im.left.rows, 375);
  EXPECT_EQ(im.left.type(), CV_8UC1);
  EXPECT_EQ(im.right.size(), im.left.size());
  EXPECT_EQ(im.right.type(), CV_8UC1);
  // Rectified images have content in the middle (not a black remap).
  EXPECT_GT(cv::mean(im.left(cv::Rect(500, 150, 200, 100)))[0], 5.0);
  const std::string e23 = LoadError(*ds_, 23);
  EXPECT_NE(e23.find("image_00/data/0000000023.png"), std::string::npos) << e23;
  EXPECT_NE(e23.find("missing"), std::string::npos) << e23;
  const std::string e22 = LoadError(*ds_, 22);
  EXPECT_NE(e22.find("image_01/data/0000000022.png"), std::string::npos) << e22;
}

// Median |row offset| of left corners matched in the right image by template
// matching in a band of +-kBand rows and 0..kMaxDisp px disparity.
double MedianRowOffset(const cv::Mat& left, const cv::Mat& right, int* matched) {
  constexpr int kHalf = 10, kBand = 8, kMaxDisp = 160;
  constexpr double kMinScore = 0.9;
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(left, corners, 300, 0.01, 15);
  std::vector<double> dys;
  for (const auto& c : corners) {
    const int x = static_cast<int>(c.x), y = static_cast<int>(c.y);
    const cv::Rect patch(x - kHalf, y - kHalf, 2 * kHalf + 1, 2 * kHalf + 1);
    const cv::Rect search(x - kHalf - kMaxDisp, y - kHalf - kBand, 2 * kHalf + 1 + kMaxDisp,
                          2 * kHalf + 1 + 2 * kBand);
    const cv::Rect img(0, 0, left.cols, left.rows);
    if ((patch & img) != patch || (search & img) != search) continue;
    cv::Mat score;
    cv::matchTemplate(right(search), left(patch), score, cv::TM_CCOEFF_NORMED);
    double best;
    cv::Point at;
    cv::minMaxLoc(score, nullptr, &best, nullptr, &at);
    if (best < kMinScore) continue;
    dys.push_back(std::abs(at.y - kBand));
  }
  *matched = static_cast<int>(dys.size());
  if (dys.empty()) return 1e9;
  std::nth_element(dys.begin(), dys.begin() + dys.size() / 2, dys.end());
  return dys[dys.size() / 2];
}

TEST_F(RealExtractDrive, RectifiedRowsAreEpipolar) {
  const StereoImages im = ds_->Load(0);
  int n_rect = 0, n_raw = 0;
  const double dy_rect = MedianRowOffset(im.left, im.right, &n_rect);
  const cv::Mat raw_l = cv::imread((kDrive / "image_00/data/0000000000.png").string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat raw_r = cv::imread((kDrive / "image_01/data/0000000000.png").string(), cv::IMREAD_GRAYSCALE);
  const double dy_raw = MedianRowOffset(raw_l, raw_r, &n_raw);
  std::printf("  median |dy|: rectified %.1f px (%d matches), raw %.1f px (%d matches)\n", dy_rect,
              n_rect, dy_raw, n_raw);
  EXPECT_GT(n_rect, 30);
  EXPECT_LE(dy_rect, 0.0 + 1e-9);  // integer search: the median row offset is 0
}

TEST_F(RealExtractDrive, OxtsSortedWithEstimatedTimes) {
  const auto& o = ds_->oxts();
  ASSERT_EQ(o.size(), 671u);
  EXPECT_EQ(o.front().index, 3);
  EXPECT_EQ(o.back().index, 4129);
  EXPECT_EQ(o.front().t_ns, ds_->time_ns(0) + 100'000'000 + 3 * 10'000'000);
  for (size_t k = 1; k < o.size(); ++k) EXPECT_LT(o[k - 1].t_ns, o[k].t_ns);
  // Specific force at z includes gravity (~9.8 m/s^2).
  EXPECT_NEAR(o.front().record.az_mps2, 9.8, 0.5);
}

TEST_F(RealExtractDrive, GroundTruthInsideOxtsSpanAndPlausibleLength) {
  const auto& o = ds_->oxts();
  int with_gt = 0, first = -1;
  double length_m = 0;
  std::optional<Eigen::Vector3d> prev;
  for (size_t i = 0; i < ds_->size(); ++i) {
    const auto gt = ds_->ground_truth(i);
    const bool inside = ds_->time_ns(i) >= o.front().t_ns && ds_->time_ns(i) <= o.back().t_ns;
    if (!inside) {
      EXPECT_FALSE(gt.has_value()) << "frame " << i;
    }
    if (!gt) continue;
    ++with_gt;
    if (first < 0) {
      first = static_cast<int>(i);
      EXPECT_TRUE(gt->isApprox(Eigen::Isometry3d::Identity(), 1e-12));
    }
    if (prev) length_m += (gt->translation() - *prev).norm();
    prev = gt->translation();
  }
  const double duration_s = ds_->tum_time_s(ds_->size() - 1) - ds_->tum_time_s(first);
  std::printf("  GT: %d of %zu frames, first %d, path length %.2f m over %.2f s (%.2f m/s)\n",
              with_gt, ds_->size(), first, length_m, duration_s, length_m / duration_s);
  EXPECT_GT(with_gt, 150);
  EXPECT_LE(first, 5);  // OXTS record 3 is ~0.13 s after image 0
  EXPECT_GT(length_m, 100.0);
  EXPECT_LT(length_m, 250.0);
  // Cross-check against the OXTS forward speed over the same span (independent
  // of positions, so it also checks the estimated OXTS time base).
  double vf_sum = 0;
  int vf_n = 0;
  const int64_t t_first = ds_->time_ns(first), t_last = ds_->time_ns(ds_->size() - 1);
  for (const OxtsSample& s : o) {
    if (s.t_ns < t_first || s.t_ns > t_last) continue;
    vf_sum += s.record.vf_mps;
    ++vf_n;
  }
  ASSERT_GT(vf_n, 0);
  const double vf_mean = vf_sum / vf_n;
  std::printf("  mean OXTS vf over the same span %.2f m/s (%d records)\n", vf_mean, vf_n);
  constexpr double kSpeedTolMps = 0.5;  // OXTS records are unevenly spread in time
  EXPECT_NEAR(length_m / duration_s, vf_mean, kSpeedTolMps);
  // Camera looks forward: z of cam0 ~ direction of travel over the drive.
  const Eigen::Vector3d last = ds_->ground_truth(ds_->size() - 1)->translation();
  EXPECT_GT(last.z(), 0.5 * last.norm());
}

TEST(RealOdometry, Sequence00WithoutImages) {
  if (!fs::is_directory(kSeq00)) GTEST_SKIP() << "odometry excerpt absent: " << kSeq00;
  const auto ds = OpenDataset(kSeq00);
  EXPECT_EQ(ds->kind(), "odometry");
  ASSERT_EQ(ds->size(), 4541u);
  EXPECT_EQ(ds->report().missing_left.size(), 4541u);
  EXPECT_FALSE(ds->has_stereo(0));
  EXPECT_DOUBLE_EQ(ds->tum_time_s(1), 1.037359e-01);
  EXPECT_EQ(ds->time_ns(1), 103'735'900);
  EXPECT_NEAR(ds->camera().baseline_m, 0.5372, 1e-4);
  EXPECT_DOUBLE_EQ(ds->camera().fx, 7.188560000000e+02);
  EXPECT_TRUE(ds->oxts().empty());
  const auto gt0 = ds->ground_truth(0);
  const auto gtN = ds->ground_truth(4540);
  ASSERT_TRUE(gt0 && gtN);
  EXPECT_TRUE(gt0->isApprox(Eigen::Isometry3d::Identity(), 1e-5));
  EXPECT_GT(gtN->translation().norm(), 0.0);
  const std::string err = LoadError(*ds, 0);
  EXPECT_NE(err.find("image_0/000000.png"), std::string::npos) << err;
  bool noted = false;
  for (const auto& n : ds->report().notes) noted |= n.find("image_0/ absent") != std::string::npos;
  EXPECT_TRUE(noted);
  // Tr (cam0 <- velo) of sequence 00 stands in for T_cam0_imu.
  EXPECT_NEAR(ds->T_cam0_imu().translation().z(), -2.921968648686e-01, 1e-12);
}

}  // namespace
}  // namespace locaid::kitti
