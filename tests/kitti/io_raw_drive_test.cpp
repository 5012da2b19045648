// Tiny raw drives written into a temp dir with the kitti writers, read back
// through OpenDataset.
#include "error_of.hpp"
#include "kitti/calib.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts.hpp"
#include "kitti/raw_drive.hpp"
#include "kitti/timestamps.hpp"
#include "temp_dir.hpp"

#include <GeographicLib/LocalCartesian.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;
using test_support::ScopedTempDir;

constexpr int kFrames = 6;
constexpr int64_t kT0 = 1317045935500923136LL;  // 2011-09-26 14:05:35.500923136
constexpr int64_t kFramePeriodNs = 100'000'000;
constexpr double kSpeedMps = 10.0;
constexpr double kLat0 = 49.0, kLon0 = 8.4, kAlt0 = 110.0;
constexpr double kPoseTol = 1e-6;  // m / rad; LocalCartesian round trip is ~1e-9

std::string Name(int i, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%010d.%s", i, ext);
  return buf;
}

CamToCamCalib SmallCalib(cv::Size raw, cv::Size rect) {
  CamToCamCalib c;
  c.calib_time = "test";
  for (int i = 0; i < 4; ++i) {
    CameraCalib& cam = c.cams[i];
    cam.S << raw.width, raw.height;
    cam.S_rect << rect.width, rect.height;
    cam.K << 50, 0, rect.width / 2.0, 0, 50, rect.height / 2.0, 0, 0, 1;
    cam.D.setZero();
    cam.R.setIdentity();
    cam.T << -0.5 * i, 0, 0;
    cam.R_rect.setIdentity();
    cam.P_rect << 50, 0, rect.width / 2.0, -25.0 * i, 0, 50, rect.height / 2.0, 0, 0, 0, 1, 0;
  }
  return c;
}

struct DriveSpec {
  std::string name = "2011_09_26_drive_0001_sync";
  cv::Size raw{80, 60}, rect{80, 60};
  bool oxts_timestamps = false;
  int oxts_per_frame = 1;  // 10 for extract-like 100 Hz
};

// Writes root/2011_09_26/<name>/ with kFrames stereo frames of seeded noise and OXTS of a
// car driving east at kSpeedMps, heading east (yaw 0).
fs::path WriteDrive(const fs::path& root, const DriveSpec& spec) {
  const fs::path date = root / "2011_09_26";
  const fs::path drive = date / spec.name;
  for (const char* d : {"image_00/data", "image_01/data", "oxts/data"})
    fs::create_directories(drive / d);

  WriteCamToCam(date / "calib_cam_to_cam.txt", SmallCalib(spec.raw, spec.rect));
  RigidCalib velo_to_cam, imu_to_velo;
  velo_to_cam.T_to_from.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // cam <- velo axes
  velo_to_cam.T_to_from.translation() << -0.004, -0.076, -0.27;
  imu_to_velo.T_to_from.translation() << -0.81, 0.32, -0.80;
  WriteVeloToCam(date / "calib_velo_to_cam.txt", velo_to_cam);
  WriteImuToVelo(date / "calib_imu_to_velo.txt", imu_to_velo);

  std::vector<int64_t> t;
  cv::RNG rng(42);
  for (int i = 0; i < kFrames; ++i) {
    t.push_back(kT0 + i * kFramePeriodNs);
    for (const char* cam : {"image_00", "image_01"}) {
      cv::Mat img(spec.raw, CV_8UC1);
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      cv::imwrite((drive / cam / "data" / Name(i, "png")).string(), img);
    }
  }
  WriteTimestampsFile(drive / "image_00/timestamps.txt", t);
  WriteTimestampsFile(drive / "image_01/timestamps.txt", t);

  const GeographicLib::LocalCartesian enu(kLat0, kLon0, kAlt0);
  std::vector<int64_t> oxts_t;
  const int n_oxts = kFrames * spec.oxts_per_frame;
  for (int k = 0; k < n_oxts; ++k) {
    const double t_s = k * 0.1 / spec.oxts_per_frame;
    OxtsRecord r;
    enu.Reverse(kSpeedMps * t_s, 0, 0, r.lat_deg, r.lon_deg, r.alt_m);
    r.ve_mps = kSpeedMps;
    r.az_mps2 = 9.81;
    r.navstat = 4;
    r.numsats = 9;
    std::ofstream(drive / "oxts/data" / Name(k, "txt")) << WriteOxtsLine(r) << "\n";
    oxts_t.push_back(kT0 + static_cast<int64_t>(std::llround(t_s * 1e9)));
  }
  if (spec.oxts_timestamps) WriteTimestampsFile(drive / "oxts/timestamps.txt", oxts_t);
  return drive;
}

// The kitti::Error of loading frame i, or "(no error)".
std::string LoadError(const StereoDataset& ds, size_t i) {
  return test_support::ErrorOf<Error>([&] { ds.Load(i); });
}

bool HasNote(const StereoDataset& ds, const std::string& text) {
  for (const auto& n : ds.report().notes)
    if (n.find(text) != std::string::npos) return true;
  return false;
}

TEST(IoRawDrive, SyncDriveReadsBackImagesTimesAndGroundTruth) {
  const ScopedTempDir dir("io_raw");
  const fs::path drive = WriteDrive(dir, {});
  // One left image stored as 3-channel BGR: Load converts it to gray.
  cv::Mat color(60, 80, CV_8UC3, cv::Scalar(10, 100, 200));
  cv::imwrite((drive / "image_00/data" / Name(1, "png")).string(), color);

  const auto ds = OpenDataset(drive);
  EXPECT_EQ(ds->kind(), "raw_sync");
  ASSERT_EQ(ds->size(), static_cast<size_t>(kFrames));
  EXPECT_TRUE(ds->report().missing_left.empty());
  EXPECT_EQ(ds->camera().width, 80);
  EXPECT_DOUBLE_EQ(ds->camera().baseline_m, 0.5);
  EXPECT_EQ(ds->time_ns(2), kT0 + 2 * kFramePeriodNs);
  EXPECT_DOUBLE_EQ(ds->tum_time_s(3), 0.3);

  const StereoImages im0 = ds->Load(0);
  const cv::Mat want0 = cv::imread((drive / "image_00/data" / Name(0, "png")).string(),
                                   cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(cv::norm(im0.left, want0, cv::NORM_INF), 0.0);  // sync: loaded as is
  const StereoImages im1 = ds->Load(1);
  EXPECT_EQ(im1.left.type(), CV_8UC1);
  cv::Mat gray;
  cv::cvtColor(color, gray, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(im1.left, gray, cv::NORM_INF), 0.0);

  // OXTS at image times (no oxts/timestamps.txt), flagged as estimated.
  EXPECT_TRUE(ds->report().oxts_timestamps_estimated);
  EXPECT_EQ(ds->report().oxts_records, kFrames);
  EXPECT_EQ(ds->report().oxts_expected, kFrames);
  ASSERT_EQ(ds->oxts().size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(ds->oxts()[4].t_ns, ds->time_ns(4));
  EXPECT_EQ(ds->oxts()[4].record.numsats, 9);

  // Driving straight along the IMU x axis: cam0 moves by R_cam0_imu * (d, 0, 0).
  for (int i = 0; i < kFrames; ++i) {
    const auto gt = ds->ground_truth(i);
    ASSERT_TRUE(gt.has_value()) << i;
    const Eigen::Vector3d want =
        ds->T_cam0_imu().linear() * Eigen::Vector3d(kSpeedMps * 0.1 * i, 0, 0);
    EXPECT_LT((gt->translation() - want).norm(), kPoseTol) << i;
    EXPECT_LT((gt->linear() - Eigen::Matrix3d::Identity()).norm(), kPoseTol) << i;
    EXPECT_GT(gt->translation().z(), 0.99 * gt->translation().norm() - kPoseTol);  // forward
  }
}

TEST(IoRawDrive, MissingAndCorruptImagesAreReportedAndNamed) {
  const ScopedTempDir dir("io_raw");
  const fs::path drive = WriteDrive(dir, {});
  fs::remove(drive / "image_01/data" / Name(3, "png"));
  const fs::path corrupt = drive / "image_00/data" / Name(4, "png");
  std::ofstream(corrupt, std::ios::binary | std::ios::trunc) << "\x89PNG garbage bytes, not an image";

  const auto ds = OpenDataset(drive);
  EXPECT_TRUE(ds->report().missing_left.empty());
  EXPECT_EQ(ds->report().missing_right, std::vector<int>{3});
  EXPECT_FALSE(ds->has_stereo(3));
  EXPECT_TRUE(ds->has_stereo(4));  // present, only decoding fails
  const std::string e3 = LoadError(*ds, 3);
  EXPECT_NE(e3.find((drive / "image_01/data" / Name(3, "png")).string()), std::string::npos) << e3;
  const std::string e4 = LoadError(*ds, 4);
  EXPECT_NE(e4.find(corrupt.string() + ": cannot decode"), std::string::npos) << e4;
  EXPECT_NE(LoadError(*ds, kFrames).find("out of range"), std::string::npos);
  EXPECT_NO_THROW(ds->Load(5));
  // A wrong-size image is refused, naming the file.
  cv::imwrite((drive / "image_01/data" / Name(5, "png")).string(), cv::Mat(30, 40, CV_8UC1));
  EXPECT_NE(LoadError(*ds, 5).find("image size 40x30, expected 80x60"), std::string::npos);
}

TEST(IoRawDrive, BadOxtsThrowsOrIsSkippedOnRequest) {
  const ScopedTempDir dir("io_raw");
  const fs::path drive = WriteDrive(dir, {});
  const fs::path bad = drive / "oxts/data" / Name(2, "txt");
  std::string line;
  std::getline(std::ifstream(bad), line);
  std::ofstream(bad, std::ios::trunc) << line.substr(0, line.rfind(' ')) << "\n";  // 29 fields
  try {
    OpenDataset(drive);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), bad.string() + ":1: 29 fields, expected 30");
  }
  RawDriveOptions options;
  options.skip_bad_oxts = true;
  const auto ds = OpenDataset(drive, options);
  EXPECT_EQ(ds->report().oxts_records, kFrames - 1);
  EXPECT_EQ(ds->report().oxts_expected, kFrames);
  EXPECT_TRUE(HasNote(*ds, bad.string() + ":1: 29 fields"));
  ASSERT_EQ(ds->report().oxts_skipped.size(), 1u);
  EXPECT_NE(ds->report().oxts_skipped[0].find(bad.string() + ":1: 29 fields"), std::string::npos);
  // Frame 2 is interpolated between OXTS 1 and 3 (0.2 s gap < 0.5 s).
  ASSERT_TRUE(ds->ground_truth(2).has_value());
  EXPECT_NEAR(ds->ground_truth(2)->translation().norm(), 2 * kSpeedMps * 0.1, kPoseTol);
}

TEST(IoRawDrive, ExtractDriveRectifiesWithMapsAndEstimatesOxtsTimes) {
  DriveSpec spec;
  spec.name = "2011_09_26_drive_0001_extract";
  spec.oxts_per_frame = 10;
  const ScopedTempDir dir("io_raw");
  const fs::path drive = WriteDrive(dir, spec);
  const auto ds = OpenDataset(drive);
  EXPECT_EQ(ds->kind(), "raw_extract");
  // Identity rectification (D = 0, R_rect = I, P_rect = K): remap returns the input.
  const StereoImages im = ds->Load(2);
  const cv::Mat raw = cv::imread((drive / "image_01/data" / Name(2, "png")).string(),
                                 cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(cv::norm(im.right, raw, cv::NORM_INF), 0.0);
  // No oxts/timestamps.txt: t = t(frame 0) + 0.1 s + index * 0.01 s.
  EXPECT_TRUE(ds->report().oxts_timestamps_estimated);
  EXPECT_EQ(ds->report().oxts_expected, kFrames * 10);
  EXPECT_EQ(ds->oxts()[7].t_ns, kT0 + 100'000'000 + 7 * 10'000'000);
  // The estimate shifts OXTS 0.1 s late: frame 0 is before the first record.
  EXPECT_FALSE(ds->ground_truth(0).has_value());
  ASSERT_TRUE(ds->ground_truth(1).has_value());
  EXPECT_LT(ds->ground_truth(1)->translation().norm(), kPoseTol);  // world anchor
  EXPECT_TRUE(HasNote(*ds, "world = cam0 at frame 1"));
}

TEST(IoRawDrive, OxtsTimestampsFileIsUsedWhenPresent) {
  DriveSpec spec;
  spec.name = "2011_09_26_drive_0001_extract";
  spec.oxts_per_frame = 10;
  spec.oxts_timestamps = true;
  const ScopedTempDir dir("io_raw");
  const auto ds = OpenDataset(WriteDrive(dir, spec));
  EXPECT_FALSE(ds->report().oxts_timestamps_estimated);
  EXPECT_EQ(ds->oxts()[7].t_ns, kT0 + 70'000'000);
  // Records at 0.00..0.59 s cover every frame (0.0..0.5 s): world = cam0 at frame 0.
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(ds->ground_truth(i).has_value()) << i;
    EXPECT_NEAR(ds->ground_truth(i)->translation().norm(), kSpeedMps * 0.1 * i, kPoseTol);
  }
}

TEST(IoRawDrive, LayoutFromImageSizeWhenNameHasNoSuffix) {
  DriveSpec spec;
  spec.name = "some_drive";
  spec.raw = {100, 80};
  spec.rect = {80, 60};
  const ScopedTempDir dir("io_raw");
  const auto ds = OpenDataset(WriteDrive(dir, spec));
  EXPECT_EQ(ds->kind(), "raw_extract");
  const StereoImages im = ds->Load(0);
  EXPECT_EQ(im.left.size(), cv::Size(80, 60));
  EXPECT_TRUE(HasNote(*ds, "layout detected from the image size: extract"));
}

TEST(IoRawDrive, OpenDatasetRejectsUnknownFolders) {
  const ScopedTempDir dir("io_raw");
  try {
    OpenDataset(dir);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir.path().string() + ": not a KITTI dataset"),
              std::string::npos);
  }
  EXPECT_THROW(OpenDataset(dir / "absent"), Error);
  // Raw drive without calibration in the parent: names the calib file.
  fs::create_directories(dir / "drive_sync/image_00");
  try {
    OpenDataset(dir / "drive_sync");
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("calib_cam_to_cam.txt: cannot open"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace locaid::kitti

TEST(IoRawDrive, TrailingSlashAndRelativePathsOpenTheSameDrive) {
  const char* root = LOCAID_SHARED_DATA;
  const std::filesystem::path drive = std::filesystem::path(root) / "raw/2011_09_26/2011_09_26_drive_unknown_extract";
  if (!std::filesystem::exists(drive)) GTEST_SKIP() << "shared KITTI excerpt not found at " << drive;
  const auto plain = locaid::kitti::OpenDataset(drive);
  const auto slash = locaid::kitti::OpenDataset(drive.string() + "/");
  const auto dotted = locaid::kitti::OpenDataset(drive / "." / "image_00" / "..");
  EXPECT_EQ(slash->size(), plain->size());
  EXPECT_EQ(dotted->size(), plain->size());
  EXPECT_EQ(slash->time_ns(5), plain->time_ns(5));
}
