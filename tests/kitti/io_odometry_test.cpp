// A tiny odometry sequence written into a temp dir and read back.
#include "kitti/calib.hpp"
#include "kitti/dataset.hpp"
#include "kitti/odometry_sequence.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;
using test_support::ScopedTempDir;

// root/sequences/07 (returned) with `frames` stereo frames, root/poses/07.txt
// with `poses` poses.
fs::path WriteSequence(const fs::path& root, int frames, int poses) {
  const fs::path seq = root / "sequences/07";
  fs::create_directories(seq / "image_0");
  fs::create_directories(seq / "image_1");
  fs::create_directories(root / "poses");
  OdometryCalib c;
  for (int i = 0; i < 4; ++i) c.P[i] << 700, 0, 30, -350.0 * i, 0, 700, 20, 0, 0, 0, 1, 0;
  WriteOdometryCalib(seq / "calib.txt", c);
  std::ofstream times(seq / "times.txt");
  cv::RNG rng(7);
  for (int i = 0; i < frames; ++i) {
    times << 0.1 * i << "\n";
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    for (const char* cam : {"image_0", "image_1"}) {
      cv::Mat img(40, 64, CV_8UC1);
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      cv::imwrite((seq / cam / name).string(), img);
    }
  }
  std::ofstream p(root / "poses/07.txt");
  for (int i = 0; i < poses; ++i) p << "1 0 0 0 0 1 0 0 0 0 1 " << 0.8 * i << "\n";
  return seq;
}

TEST(IoOdometry, SequenceWithImagesAndPoses) {
  const ScopedTempDir dir("io_odometry");
  const fs::path seq = WriteSequence(dir, 5, 5);
  fs::remove(seq / "image_1/000003.png");
  const auto ds = OpenDataset(seq);
  EXPECT_EQ(ds->kind(), "odometry");
  ASSERT_EQ(ds->size(), 5u);
  EXPECT_EQ(ds->camera().width, 64);
  EXPECT_EQ(ds->camera().height, 40);
  EXPECT_DOUBLE_EQ(ds->camera().baseline_m, 0.5);
  EXPECT_TRUE(ds->report().missing_left.empty());
  EXPECT_EQ(ds->report().missing_right, std::vector<int>{3});
  EXPECT_EQ(ds->time_ns(2), 200'000'000);
  EXPECT_DOUBLE_EQ(ds->tum_time_s(4), 0.4);
  const StereoImages im = ds->Load(4);
  EXPECT_EQ(im.left.type(), CV_8UC1);
  EXPECT_EQ(im.right.size(), cv::Size(64, 40));
  try {
    ds->Load(3);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image_1/000003.png"), std::string::npos) << e.what();
  }
  ASSERT_TRUE(ds->ground_truth(4).has_value());
  EXPECT_DOUBLE_EQ(ds->ground_truth(4)->translation().z(), 3.2);
}

TEST(IoOdometry, FewerPosesThanFramesIsNoted) {
  const ScopedTempDir dir("io_odometry");
  const fs::path seq = WriteSequence(dir, 4, 2);
  const OdometrySequence ds(seq);
  EXPECT_TRUE(ds.has_ground_truth());
  EXPECT_TRUE(ds.ground_truth(1).has_value());
  EXPECT_FALSE(ds.ground_truth(2).has_value());
  bool noted = false;
  for (const auto& n : ds.report().notes) noted |= n.find("2 poses for 4 frames") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(IoOdometry, BadCalibNamesFileAndKey) {
  const ScopedTempDir dir("io_odometry");
  const fs::path seq = WriteSequence(dir, 2, 2);
  std::ofstream(seq / "calib.txt", std::ios::trunc) << "P0: 1 2 3\n";
  try {
    OpenDataset(seq);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (seq / "calib.txt").string() +
                                         ":1: key 'P0': 3 numbers, expected 12");
  }
}

}  // namespace
}  // namespace locaid::kitti
