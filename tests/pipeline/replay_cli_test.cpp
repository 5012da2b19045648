// locaid-replay as a user runs it: on a small rendered drive, the VO cache
// gives the same filter result without rerunning VO, a cache of another run
// is refused by name, and --ekf settings are checked. Also
// bench/fusion/causal_bound.py, on a CSV whose answer is known by hand and on
// a real locaid-replay CSV.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;

using locaid::test::JsonField;
using locaid::test::RunCommand;

class ReplayCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<locaid::test_support::ScopedTempDir>("replay_cli");
    root_ = *dir_;
    const auto r = RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-synth --out " + root_.string() +
                       " --frames 80 --width 640 --height 192 --seed 7 -q");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    for (const auto& e : fs::directory_iterator(root_))
      if (e.is_directory()) drive_ = e.path();
  }
  static void TearDownTestSuite() { dir_.reset(); }
  static std::string Replay(const std::string& args) {
    return std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() +
           " --scenario open-sky --json " + args;
  }
  static inline std::unique_ptr<locaid::test_support::ScopedTempDir> dir_;
  static inline fs::path root_, drive_;
};

TEST_F(ReplayCli, VoCacheReproducesTheFilterResultWithoutVo) {
  ASSERT_FALSE(drive_.empty());
  const fs::path cache = root_ / "vo.cache";
  fs::remove(cache);
  const auto first = RunCommand(Replay("--vo-cache " + cache.string()));
  ASSERT_EQ(first.exit_code, 0) << first.out;
  ASSERT_TRUE(fs::exists(cache));
  EXPECT_EQ(JsonField(first.out, "vo_from_cache"), " false");
  // The cached run reads no image: with every left image garbled it gives
  // the same result. The images are put back afterwards: the suite's tests
  // share the drive (one process runs them all when not run by CTest).
  const fs::path left = drive_ / "image_00" / "data", kept = root_ / "image_00_kept";
  fs::copy(left, kept, fs::copy_options::recursive);
  struct PutBack {
    fs::path from, to;
    ~PutBack() {
      std::error_code ec;
      fs::remove_all(to, ec);
      fs::rename(from, to, ec);
    }
  } put_back{kept, left};
  for (const auto& e : fs::directory_iterator(left)) {
    std::ofstream(e.path(), std::ios::binary | std::ios::trunc) << "not a PNG any more";
  }
  const auto second = RunCommand(Replay("--vo-cache " + cache.string()));
  ASSERT_EQ(second.exit_code, 0) << second.out;
  EXPECT_EQ(JsonField(second.out, "vo_from_cache"), " true");
  const std::string rmse1 = JsonField(first.out, "rmse_gps_m"), rmse2 = JsonField(second.out, "rmse_gps_m");
  ASSERT_FALSE(rmse1.empty()) << first.out;
  EXPECT_NEAR(std::stod(rmse1), std::stod(rmse2), 1e-9);
  EXPECT_EQ(JsonField(first.out, "frames"), JsonField(second.out, "frames"));
  // A filter setting changes the result while the cache is reused.
  const auto tuned = RunCommand(Replay("--vo-cache " + cache.string() + " --ekf vo.cov_scale=50"));
  ASSERT_EQ(tuned.exit_code, 0) << tuned.out;
  EXPECT_NE(JsonField(tuned.out, "rmse_gps_m"), rmse1);
  // The setting's flat name of earlier versions sets the same field.
  const auto flat = RunCommand(Replay("--vo-cache " + cache.string() + " --ekf vo_cov_scale=50"));
  ASSERT_EQ(flat.exit_code, 0) << flat.out;
  EXPECT_EQ(JsonField(flat.out, "rmse_gps_m"), JsonField(tuned.out, "rmse_gps_m"));
}

// Learned noise (docs/api.md "Learned noise") in the JSON, and the two flags
// that keep the fixed models.
TEST_F(ReplayCli, NoiseIsLearnedUnlessTheFixedModelsAreAsked) {
  ASSERT_FALSE(drive_.empty());
  const fs::path yaml = root_ / "overconfident.yaml";
  std::ofstream(yaml) << "name: overconfident\n"
                         "gps: {rate_hz: 10, sigma_h_m: 3.0, sigma_v_m: 5.0, stated_sigma_scale: 0.3333333333}\n";
  auto run = [&](const std::string& flags) {
    return RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() + " --scenario " +
                      yaml.string() + " --json " + flags);
  };
  const auto learned = run(""), fixed = run("--fixed-vo-noise --fixed-gps-noise");
  fs::remove(yaml);
  ASSERT_EQ(learned.exit_code, 0) << learned.out;
  ASSERT_EQ(fixed.exit_code, 0) << fixed.out;
  const std::string h = JsonField(learned.out, "gps_scale_horizontal");
  ASSERT_FALSE(h.empty()) << learned.out;
  EXPECT_GT(std::stod(h), 2.0) << "the fixes scatter 3x what they state";
  EXPECT_EQ(std::stod(JsonField(fixed.out, "gps_scale_horizontal")), 1.0);
  EXPECT_EQ(std::stod(JsonField(fixed.out, "gps_scale_vertical")), 1.0);
  EXPECT_FALSE(JsonField(learned.out, "nees6_mean_model_gps_good").empty()) << learned.out;
  EXPECT_FALSE(JsonField(learned.out, "nees_mean_after_30s").empty()) << learned.out;
}

TEST_F(ReplayCli, CacheOfAnotherRunIsRefusedByName) {
  ASSERT_FALSE(drive_.empty());
  const fs::path cache = root_ / "other.cache";
  fs::remove(cache);
  ASSERT_EQ(RunCommand(Replay("--max-frames 40 --vo-cache " + cache.string())).exit_code, 0);
  const auto r = RunCommand(Replay("--vo-cache " + cache.string()));  // 80 frames, not 40
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("VO cache written for another run"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frames=40"), std::string::npos) << r.out;

  std::ofstream(root_ / "garbage.cache") << "not a cache\n";
  const auto g = RunCommand(Replay("--vo-cache " + (root_ / "garbage.cache").string()));
  EXPECT_NE(g.exit_code, 0);
  EXPECT_NE(g.out.find("garbage.cache"), std::string::npos) << g.out;
}

// A cache whose header matches but that lacks a frame's line (edited, or
// cut short) ends the replay with the frame's time, not with wrong figures.
TEST_F(ReplayCli, ACacheMissingAFrameNamesIt) {
  ASSERT_FALSE(drive_.empty());
  const fs::path cache = root_ / "cut.cache";
  fs::remove(cache);
  ASSERT_EQ(RunCommand(Replay("--max-frames 30 --vo-cache " + cache.string())).exit_code, 0);
  std::vector<std::string> lines;
  {
    std::ifstream in(cache);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  ASSERT_EQ(lines.size(), 31u);  // header + 30 frames
  std::istringstream line_20(lines[21]);
  std::string index, t_ns;
  line_20 >> index >> t_ns;
  ASSERT_EQ(index, "20");
  {
    std::ofstream out(cache, std::ios::trunc);
    for (size_t i = 0; i < lines.size(); ++i)
      if (i != 21) out << lines[i] << '\n';
  }
  const auto r = RunCommand(Replay("--max-frames 30 --vo-cache " + cache.string()));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("VO cache: no result for the frame at t_ns " + t_ns), std::string::npos) << r.out;
}

TEST_F(ReplayCli, BadEkfSettingsNameTheProblem) {
  ASSERT_FALSE(drive_.empty());
  const auto unknown = RunCommand(Replay("--max-frames 5 --ekf no_such_field=1"));
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.out.find("no_such_field=1: expected NAME=VALUE"), std::string::npos) << unknown.out;
  for (const std::string model : {"imu.", "gps.", "vo.", "vehicle.", "startup."}) {
    EXPECT_NE(unknown.out.find(model), std::string::npos) << "the settings of each model are listed: " << unknown.out;
  }
  EXPECT_NE(unknown.out.find("vo.cov_scale"), std::string::npos) << unknown.out;
  EXPECT_NE(RunCommand(Replay("--max-frames 5 --ekf vo.cov_scale")).exit_code, 0) << "a name without a value";
  for (const std::string bad : {"vo.cov_scale=abc", "vo_cov_scale=nan", "vo.cov_scale=-1", "vo_cov_scale=1x"}) {
    const auto r = RunCommand(Replay("--max-frames 5 --ekf " + bad));
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.out.find("value must be a finite number >= 0"), std::string::npos) << bad << ": " << r.out;
  }
}

std::string CausalBound(const fs::path& csv) {
  return "/usr/bin/python3 " + std::string(LOCAID_SOURCE_DIR) + "/bench/fusion/causal_bound.py --json " +
         csv.string();
}

// A straight drive east at 1 m per frame, a fix on every frame exactly 0.5 m
// east of the truth, an outage on frames 20-29 (distance counted from frame
// 19, the last with GPS, as locaid-replay does: 10 m) and a filter that is
// 2 m north at the outage's last frame: the rigid fit recovers the 0.5 m
// offset exactly, so every bound figure is known.
TEST_F(ReplayCli, CausalBoundScriptOnAKnownTrack) {
  const fs::path csv = root_ / "known.csv";
  {
    std::ofstream f(csv);
    f << "t_s,gt_e,gt_n,gt_u,est_e,est_n,est_u,gps_e,gps_n,gps_u,gps_rejected,vo_e,vo_n,vo_u,sigma_e,sigma_n,"
         "sigma_u,err_h,mode,in_outage,initialized,gps_gt_e,gps_gt_n,gps_gt_u\n";
    for (int i = 0; i < 40; ++i) {
      const bool outage = i >= 20 && i < 30;
      const double e = i, est_n = i == 29 ? 2.0 : 0.0;
      f << 100 + 0.1 * i << "," << e << ",0,0," << e << "," << est_n << ",0,";
      if (outage) f << ",,,,";
      else f << e + 0.5 << ",0,0,0,";
      f << ",,,1,1,1,0," << (outage ? "VO_ONLY" : "GPS_FUSED") << "," << (outage ? 1 : 0) << ",1,";
      if (outage) f << ",,\n";
      else f << e << ",0,0\n";
    }
  }
  const auto r = RunCommand(CausalBound(csv));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "causal_ls_rmse_m")), 0.5, 1e-9) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "fixes_before")), 20, 0) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "distance_m")), 10.0, 1e-9) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "bound_end_error_m")), 0.5, 1e-9) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "filter_end_error_m")), 2.0, 1e-9) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "filter_end_error_pct")), 20.0, 1e-9) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "bound_end_error_pct")), 5.0, 1e-9) << r.out;

  std::ofstream(root_ / "not_replay.csv") << "a,b\n1,2\n";
  const auto bad = RunCommand(CausalBound(root_ / "not_replay.csv"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.out.find("not a locaid-replay CSV"), std::string::npos) << bad.out;
}

// On a real run with an outage the script agrees with locaid-replay on the
// filter's end-of-outage error and distance (to the CSV's 4 decimals).
TEST_F(ReplayCli, CausalBoundScriptAgreesWithReplayOnTheOutage) {
  ASSERT_FALSE(drive_.empty());
  const fs::path scenario = root_ / "outage.yaml", csv = root_ / "outage.csv";
  std::ofstream(scenario) << "base: open-sky\noutages:\n  - {start_s: 4, duration_s: 2}\n";
  const auto replay = RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() +
                                 " --scenario " + scenario.string() + " --json --out-csv " + csv.string());
  ASSERT_EQ(replay.exit_code, 0) << replay.out;
  const auto r = RunCommand(CausalBound(csv));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "filter_end_error_m")), std::stod(JsonField(replay.out, "end_error_m")),
              1e-3)
      << replay.out << "\n" << r.out;
  EXPECT_NEAR(std::stod(JsonField(r.out, "distance_m")), std::stod(JsonField(replay.out, "distance_m")), 1e-2)
      << replay.out << "\n" << r.out;
  EXPECT_GE(std::stod(JsonField(r.out, "bound_end_error_m")), 0.0) << r.out;
  EXPECT_GT(std::stod(JsonField(r.out, "fixes_before")), 10) << r.out;
}

}  // namespace
