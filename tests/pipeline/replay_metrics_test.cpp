// Replay metrics and the plot CSV shared by locaid-replay and locaid-score.
#include "pipeline/replay_metrics.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

using locaid::pipeline::PlotExtras;
using locaid::pipeline::ReplaySample;
using locaid::test_support::ScopedTempDir;

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A straight 10 m/s drive with a 1 m east offset, GPS in use throughout.
std::vector<ReplaySample> StraightDrive(int frames) {
  std::vector<ReplaySample> samples(frames);
  for (int k = 0; k < frames; ++k) {
    auto& s = samples[k];
    s.t_s = 0.1 * k;
    s.p_enu_gt_m = {0.0, 1.0 * k, 0.0};
    s.p_enu_est_m = s.p_enu_gt_m + Eigen::Vector3d(1.0, 0.0, 0.0);
    s.mode = locaid::fusion::Mode::kGpsFused;
    s.initialized = true;
  }
  return samples;
}

TEST(ReplayMetrics, RmseWhileGpsUsedIsTheHorizontalOffset) {
  const auto metrics = locaid::pipeline::ComputeReplayMetrics(StraightDrive(50), 3.0);
  EXPECT_EQ(metrics.frames, 50);
  EXPECT_NEAR(metrics.rmse_gps_m, 1.0, 1e-9);
  EXPECT_TRUE(metrics.outages.empty());
}

// A frame without ground truth (its position reads as zero) after an outage
// must not count as a pose jump, stretch the outage distance, or enter the
// RMSE; the CSV leaves its ground truth and error empty.
TEST(ReplayMetrics, FramesWithoutGroundTruthAreLeftOutOfEveryMetric) {
  auto samples = StraightDrive(60);
  for (int k = 20; k < 30; ++k) samples[k].in_outage = true;
  samples[25].has_gt = false;
  samples[25].p_enu_gt_m.setZero();
  samples[59].has_gt = false;
  samples[59].p_enu_gt_m.setZero();
  const auto metrics = locaid::pipeline::ComputeReplayMetrics(samples, 3.0);
  EXPECT_NEAR(metrics.rmse_gps_m, 1.0, 1e-9);
  ASSERT_EQ(metrics.outages.size(), 1u);
  EXPECT_NEAR(metrics.outages[0].distance_m, 10.0, 1e-9);  // frames 19 -> 29, 1 m each
  EXPECT_NEAR(metrics.outages[0].end_error_m, 1.0, 1e-9);
  EXPECT_NEAR(metrics.outages[0].max_error_m, 1.0, 1e-9);
  EXPECT_NEAR(metrics.outages[0].max_jump_m, 0.0, 1e-9);

  const ScopedTempDir dir("replay_metrics");
  const std::string path = (dir / "plot_no_gt.csv").string();
  locaid::pipeline::WritePlotCsv(path, samples);
  const auto lines = Lines(path);
  ASSERT_EQ(lines.size(), 61u);
  EXPECT_EQ(lines[60].rfind("5.9000,,,,1.0000,59.0000,0.0000,", 0), 0u) << lines[60];
  EXPECT_NE(lines[60].find(",1.0000,1.0000,1.0000,,GPS_FUSED,0,1,"), std::string::npos) << lines[60];
}

TEST(ReplayMetrics, PlotCsvLeavesUnknownTracksEmptyAndFillsKnownOnes) {
  const auto samples = StraightDrive(3);
  const ScopedTempDir dir("replay_metrics");
  const std::string bare = (dir / "plot_bare.csv").string();
  locaid::pipeline::WritePlotCsv(bare, samples);
  const auto lines = Lines(bare);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].rfind("t_s,gt_e,gt_n,gt_u,est_e,est_n,est_u,gps_e,gps_n,gps_u,gps_rejected,vo_e", 0), 0u);
  // Frame 2: gt (0, 2, 0), est (1, 2, 0), no GPS, not rejected, no VO, err_h 1.
  EXPECT_EQ(lines[3].substr(0, lines[3].find(",1.0000,1.0000,1.0000,")),
            "0.2000,0.0000,2.0000,0.0000,1.0000,2.0000,0.0000,,,,0,,,");
  EXPECT_NE(lines[3].find(",GPS_FUSED,0,1"), std::string::npos) << lines[3];

  std::vector<PlotExtras> extras(3);
  extras[1] = {Eigen::Vector3d(5, 6, 7), true, Eigen::Vector3d(8, 9, 10), Eigen::Vector3d(5.5, 6.5, 7)};
  const std::string full = (dir / "plot_full.csv").string();
  locaid::pipeline::WritePlotCsv(full, samples, extras);
  const auto full_lines = Lines(full);
  ASSERT_EQ(full_lines.size(), 4u);
  EXPECT_NE(full_lines[2].find(",5.0000,6.0000,7.0000,1,8.0000,9.0000,10.0000,"), std::string::npos)
      << full_lines[2];
}

TEST(ReplayMetrics, PlotCsvRejectsMismatchedExtrasAndUnwritablePaths) {
  const auto samples = StraightDrive(3);
  const ScopedTempDir dir("replay_metrics");
  EXPECT_THROW(locaid::pipeline::WritePlotCsv((dir / "x.csv").string(), samples, std::vector<PlotExtras>(2)),
               std::invalid_argument);
  EXPECT_THROW(locaid::pipeline::WritePlotCsv("/proc/no/such/dir/plot.csv", samples), std::runtime_error);
}

}  // namespace
