// A ROS 2 bag written by the field's own libraries (js/kitti_to_bag.mjs:
// @mcap/core + @foxglove/rosmsg2-serialization) from the real KITTI excerpt,
// read by locaid: the same frames and VO as the drive folder, the same fused
// track when the bag holds the same fixes, every layout variant, and clear
// errors for what cannot be read.
#include "kitti/dataset.hpp"
#include "pipeline/bag_frame_source.hpp"
#include "pipeline/cli_support.hpp"
#include "needs_tool.hpp"
#include "temp_dir.hpp"
#include "vo/stereo_odometry.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using locaid::test::RunCommand;
using locaid::test_support::HaveCommand;
using locaid::test_support::ScopedTempDir;

namespace locaid {
namespace {

const fs::path kDrive = fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/2011_09_26_drive_unknown_extract";
const std::string kReplay = std::string(LOCAID_BIN_DIR) + "/locaid-replay";

#define REQUIRE_DATA_AND_NODE()                                                             \
  do {                                                                                      \
    if (!fs::exists(kDrive)) GTEST_SKIP() << "shared real KITTI excerpt absent: " << kDrive; \
    LOCAID_NEEDS_TOOL(HaveCommand("node"), "node not installed (the bag writer runs on it)"); \
  } while (false)

// Writes the drive as a bag with the official libraries; `options` are
// kitti_to_bag.mjs's.
fs::path Convert(const fs::path& out, const std::string& options = "") {
  const auto r = RunCommand("node " + std::string(LOCAID_ROSBAG_JS_DIR) + "/kitti_to_bag.mjs --drive " +
                            kDrive.string() + " --out " + out.string() + " " + options);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return out;
}

nlohmann::json ReplayJson(const std::string& args, std::string* log = nullptr) {
  // stdout only: the progress and notes go to stderr.
  const auto r = RunCommand("(" + kReplay + " " + args + " --json 2>/dev/null)");
  EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.out;
  if (log) *log = r.out;
  try {
    return nlohmann::json::parse(r.out);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not JSON: " << e.what() << "\n" << r.out;
    return {};
  }
}

struct VoRun {
  std::vector<int64_t> frame_times;
  double drift_pct = 0;  // end error / path length, VO chained from the first frame's ground truth
};

// Runs VO over `source` and scores it against the drive's ground truth at
// the same image times.
VoRun RunVo(pipeline::FrameSource& source, const kitti::StereoDataset& drive) {
  std::map<int64_t, size_t> index_of;
  for (size_t i = 0; i < drive.size(); ++i) index_of[drive.time_ns(i)] = i;
  auto vo = vo::MakeStereoOdometry("default", source.camera());
  VoRun run;
  std::optional<Eigen::Isometry3d> T_est, first_gt, last_gt, prev_gt;
  double path_m = 0;
  for (;;) {
    pipeline::SourceItem item = source.Next();
    if (item.kind == pipeline::SourceItem::Kind::kEnd) break;
    if (item.kind != pipeline::SourceItem::Kind::kFrame) continue;
    run.frame_times.push_back(item.t_ns);
    const auto motion = vo->Track({item.t_ns, item.left, item.right});
    const auto it = index_of.find(item.t_ns);
    if (it == index_of.end()) continue;
    const auto gt = drive.ground_truth(it->second);
    if (!gt) continue;
    if (!T_est) {
      T_est = *gt;
      first_gt = *gt;
    } else {
      *T_est = *T_est * motion.T_prev_curr;
      path_m += (gt->translation() - prev_gt->translation()).norm();
    }
    prev_gt = *gt;
    last_gt = *gt;
  }
  if (T_est && path_m > 0) run.drift_pct = 100 * (T_est->translation() - last_gt->translation()).norm() / path_m;
  return run;
}

VoRun VoOfDrive() {
  auto drive = kitti::OpenDataset(kDrive);
  pipeline::DatasetFrameSource source(kitti::OpenDataset(kDrive), 0, -1);
  return RunVo(source, *drive);
}

TEST(BagSource, RawAndPngBagsGiveTheDrivesFramesAndVo) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_vo");
  const VoRun folder = VoOfDrive();
  ASSERT_GT(folder.frame_times.size(), 150u);
  for (const std::string options : {"", "--images png --compression lz4"}) {
    SCOPED_TRACE("kitti_to_bag.mjs " + options);
    const fs::path bag = Convert(dir.path() / "drive.mcap", options);
    auto drive = kitti::OpenDataset(kDrive);
    pipeline::BagFrameSource source(bag, {});
    // Rectified at the raw size as image_proc does, then cropped to the part
    // without border: about KITTI's own rectified size.
    EXPECT_NEAR(source.camera().width, drive->camera().width, 40);
    EXPECT_NEAR(source.camera().height, drive->camera().height, 40);
    EXPECT_NEAR(source.camera().baseline_m, drive->camera().baseline_m, 1e-9);
    // The extrinsic from /tf_static and CameraInfo's R: the drive's calibration.
    EXPECT_TRUE(source.T_cam0_imu().isApprox(drive->T_cam0_imu(), 1e-6))
        << source.T_cam0_imu().matrix() << "\nvs\n" << drive->T_cam0_imu().matrix();
    const VoRun bag_run = RunVo(source, *drive);
    EXPECT_EQ(bag_run.frame_times, folder.frame_times) << "the same frames, none skipped more or less";
    EXPECT_EQ(source.stats().bad_images, 0u);
    // Drift equal within 1 % of itself... of the distance: percentage points.
    EXPECT_NEAR(bag_run.drift_pct, folder.drift_pct, 1.0);
    std::cout << "VO drift: folder " << folder.drift_pct << " %, bag " << bag_run.drift_pct << " %\n";
    fs::remove(bag);
  }
}

TEST(BagSource, FusedLikeTheDriveWhenTheBagHoldsTheSameFixes) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_fused");
  const fs::path fixes = dir.path() / "fixes.csv", drive_csv = dir.path() / "drive.csv",
                 bag_csv = dir.path() / "bag.csv";
  const auto drive = ReplayJson("--drive " + kDrive.string() + " --scenario urban-canyon --out-fixes " +
                                fixes.string() + " --out-csv " + drive_csv.string());
  const fs::path bag = Convert(dir.path() / "uc.mcap", "--gps-csv " + fixes.string());
  const auto replayed = ReplayJson("--bag " + bag.string() + " --out-csv " + bag_csv.string());
  ASSERT_TRUE(replayed.contains("bag"));
  EXPECT_EQ(replayed["bag"]["frames"], drive["frames"]);
  EXPECT_EQ(replayed["gps_used"], drive["gps_used"]);
  // Horizontal error of each run against the drive's ground truth at the same times.
  const auto read = [](const fs::path& p) {
    std::ifstream in(p);
    std::string line;
    std::getline(in, line);
    std::vector<std::map<std::string, std::string>> rows;
    std::vector<std::string> names;
    for (std::stringstream h(line); std::getline(h, line, ',');) names.push_back(line);
    while (std::getline(in, line)) {
      std::map<std::string, std::string> row;
      std::stringstream ss(line);
      for (const auto& n : names) std::getline(ss, row[n], ',');
      rows.push_back(row);
    }
    return rows;
  };
  const auto d = read(drive_csv), b = read(bag_csv);
  ASSERT_EQ(d.size(), b.size());
  double se_drive = 0, se_bag = 0;
  int n = 0;
  for (size_t k = 0; k < d.size(); ++k) {
    if (d[k].at("initialized") != "1" || b[k].at("initialized") != "1" || d[k].at("gt_e").empty()) continue;
    ASSERT_EQ(d[k].at("t_s"), b[k].at("t_s"));
    const double ge = std::stod(d[k].at("gt_e")), gn = std::stod(d[k].at("gt_n"));
    se_drive += std::pow(std::stod(d[k].at("est_e")) - ge, 2) + std::pow(std::stod(d[k].at("est_n")) - gn, 2);
    se_bag += std::pow(std::stod(b[k].at("est_e")) - ge, 2) + std::pow(std::stod(b[k].at("est_n")) - gn, 2);
    ++n;
  }
  ASSERT_GT(n, 100);
  const double rmse_drive = std::sqrt(se_drive / n), rmse_bag = std::sqrt(se_bag / n);
  std::cout << "fused RMSE: drive " << rmse_drive << " m, bag " << rmse_bag << " m over " << n << " poses\n";
  EXPECT_NEAR(rmse_bag, rmse_drive, 0.10 * rmse_drive);
}

// Each layout the bag writer offers, read by locaid-replay --bag as a user runs it.
TEST(BagSource, EveryLayoutVariantReplays) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_variants");
  struct Variant {
    std::string options;
    int min_frames;
  };
  const std::vector<Variant> variants = {
      {"--images jpeg --compression none", 48}, {"--no-chunks", 48},           {"--no-summary", 48},
      {"--compression lz4 --chunk-size 200000", 48}, {"--imu-no-orientation", 48}, {"--speed", 48},
  };
  for (const auto& v : variants) {
    SCOPED_TRACE(v.options);
    const fs::path bag = Convert(dir.path() / "v.mcap", "--max-frames 50 " + v.options);
    const auto j = ReplayJson("--bag " + bag.string());
    ASSERT_TRUE(j.contains("bag"));
    EXPECT_GE(j["bag"]["frames"].get<int>(), v.min_frames);
    EXPECT_GT(j["bag"]["imu_samples"].get<int>(), 50);
    EXPECT_GT(j["gps_used"].get<int>(), 0);
    if (v.options == "--speed") EXPECT_GT(j["bag"]["speed_samples"].get<int>(), 50);
    fs::remove(bag);
  }
}

TEST(BagSource, SplitBagDirectoryIsReadInOrder) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_split");
  const fs::path whole = Convert(dir.path() / "whole.mcap", "--max-frames 50");
  const fs::path split = Convert(dir.path() / "split", "--max-frames 50 --split 60");
  ASSERT_TRUE(fs::exists(split / "metadata.yaml"));
  const auto a = ReplayJson("--bag " + whole.string()), b = ReplayJson("--bag " + split.string());
  EXPECT_EQ(a["bag"]["frames"], b["bag"]["frames"]);
  EXPECT_EQ(a["bag"]["imu_samples"], b["bag"]["imu_samples"]);
  EXPECT_EQ(a["gps_used"], b["gps_used"]);
}

TEST(BagSource, ACutFileIsReadUpToTheCutAndSaysSo) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_cut");
  const fs::path bag = Convert(dir.path() / "cut.mcap", "--max-frames 40 --truncate-at 0.6");
  std::string log;
  const auto r = RunCommand(kReplay + " --bag " + bag.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("cut"), std::string::npos) << r.out;  // the note names the cut
  const auto j = nlohmann::json::parse(r.out.substr(r.out.find('{')));
  EXPECT_GT(j["bag"]["frames"].get<int>(), 10);
  EXPECT_LT(j["bag"]["frames"].get<int>(), 40);
}

TEST(BagSource, NoFixWindowsAndOtherTopicNamesAreHandled) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_nofix");
  const fs::path bag = Convert(dir.path() / "car.mcap", "--max-frames 80 --prefix /car --nofix 4:6");
  const auto j = ReplayJson("--bag " + bag.string());
  EXPECT_EQ(j["bag"]["topics"]["imu"], "/car/imu/data");
  EXPECT_GT(j["bag"]["no_fix"].get<int>(), 10);  // NaN fixes with NO_FIX: never fused
  const auto all = ReplayJson("--bag " + Convert(dir.path() / "all.mcap", "--max-frames 80").string());
  EXPECT_LT(j["gps_used"].get<int>(), all["gps_used"].get<int>());
}

// The shipped scenario for a bag: its fixes at 1 Hz with more noise, and a
// 10 s outage in the middle; as-recorded only the outage would apply.
TEST(BagSource, AScenarioDegradesTheBagsOwnFixesOnRequest) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_scenario");
  const fs::path bag = Convert(dir.path() / "all.mcap");
  const std::string scenario = std::string(LOCAID_SOURCE_DIR) + "/scenarios/bag-fixes-degraded.yaml";
  const auto recorded = ReplayJson("--bag " + bag.string());
  const fs::path fixes = dir.path() / "fixes.csv";
  const auto degraded =
      ReplayJson("--bag " + bag.string() + " --scenario " + scenario + " --out-fixes " + fixes.string());
  ASSERT_EQ(degraded["outages"].size(), 1u);
  const int used = recorded["gps_used"].get<int>(), worse = degraded["gps_used"].get<int>();
  std::cout << "fixes fused: as recorded " << used << ", degraded " << worse << "\n";
  EXPECT_GT(used, 100);
  EXPECT_LT(worse, used / 5) << "1 Hz instead of the bag's rate, and an outage";
  EXPECT_GT(worse, 3);
  // The filter is told: the model's 3 m on top of the recorded sigma.
  std::ifstream in(fixes);
  std::string line;
  std::getline(in, line);
  int rows = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    for (std::stringstream ss(line); std::getline(ss, f.emplace_back(), ',');) {
    }
    f.pop_back();
    ASSERT_EQ(f.size(), 6u) << line;  // t_ns, lat, lon, alt, sigma_h, sigma_v
    const double sigma_h = std::stod(f[4]);
    EXPECT_GT(sigma_h, 3.0) << line;
    ++rows;
  }
  EXPECT_EQ(rows, worse);
}

TEST(BagSource, InspectListsTopicsAndTheChoice) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_inspect");
  const fs::path bag = Convert(dir.path() / "i.mcap", "--max-frames 10 --speed");
  const auto r = RunCommand(kReplay + " --bag " + bag.string() + " --inspect");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const std::string want : {"/camera/left/image_raw", "left image", "right camera_info", "sensor_msgs/msg/Imu",
                                 "imu", "gps", "/vehicle/speed", "speed"})
    EXPECT_NE(r.out.find(want), std::string::npos) << want << "\n" << r.out;
}

TEST(BagSource, BadInputGetsAPreciseError) {
  REQUIRE_DATA_AND_NODE();
  ScopedTempDir dir("bag_errors");
  const fs::path bag = Convert(dir.path() / "b.mcap", "--max-frames 5");
  const auto expect_error = [&](const std::string& args, const std::string& want) {
    const auto r = RunCommand(kReplay + " " + args);
    EXPECT_NE(r.exit_code, 0) << args;
    EXPECT_NE(r.out.find(want), std::string::npos) << args << "\n" << r.out;
  };
  expect_error("--bag " + (dir.path() / "missing.mcap").string(), "no such bag");
  {
    std::ofstream(dir.path() / "text.mcap") << "not a bag at all, just text\n";
  }
  expect_error("--bag " + (dir.path() / "text.mcap").string(), "text.mcap");
  {
    std::ofstream(dir.path() / "topics.yaml") << "imu: /camera/left/image_raw\n";
  }
  expect_error("--bag " + bag.string() + " --bag-topics " + (dir.path() / "topics.yaml").string(),
               "imu: topic /camera/left/image_raw has type sensor_msgs/msg/Image");
  {
    std::ofstream(dir.path() / "typo.yaml") << "left_imag: /x\n";
  }
  expect_error("--bag " + bag.string() + " --bag-topics " + (dir.path() / "typo.yaml").string(),
               "unknown key 'left_imag'");
  expect_error("--bag " + bag.string() + " --drive " + kDrive.string(), "excludes");
}

}  // namespace
}  // namespace locaid
