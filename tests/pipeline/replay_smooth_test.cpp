// locaid-replay --smooth and --lag as a user runs them, on a small rendered
// drive with an outage: the "smoothed" metrics, the files holding the
// smoothed trajectory, a lag longer than the drive equal to --smooth, a
// spilled store equal to one in memory, VO failing in places, and the
// errors for a lag out of range.
#include "cli_support.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

using locaid::test::RunCommand;

class ReplaySmooth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<locaid::test_support::ScopedTempDir>("replay_smooth");
    root_ = *dir_;
    const auto r = RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-synth --out " + root_.string() +
                              " --frames 150 --width 640 --height 192 --seed 11 -q");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    for (const auto& e : fs::directory_iterator(root_))
      if (e.is_directory()) drive_ = e.path();
    std::ofstream(root_ / "outage.yaml") << "base: open-sky\noutages:\n  - {start_s: 5, duration_s: 5}\nseed: 3\n";
    std::ofstream(root_ / "dark.yaml")
        << "base: open-sky\noutages:\n  - {start_s: 5, duration_s: 5}\n"
           "camera:\n  - {start_s: 6, duration_s: 2, fault: dark, gain: 0.01}\nseed: 3\n";
    // VO once for the suite: every run below reads the same cached motions.
    Replay(Cache());
  }
  static void TearDownTestSuite() { dir_.reset(); }
  // Runs locaid-replay with the outage scenario; VO once for the suite.
  static nlohmann::json Replay(const std::string& args, const std::string& scenario = "outage.yaml") {
    // The progress on stderr stays out of the JSON.
    const auto r = RunCommand("(" + std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() +
                              " --scenario " + (root_ / scenario).string() + " --json " + args + " 2>/dev/null)");
    EXPECT_EQ(r.exit_code, 0) << r.out;
    return r.exit_code == 0 ? nlohmann::json::parse(r.out) : nlohmann::json::object();
  }
  static std::string Cache() { return " --vo-cache " + (root_ / "vo.cache").string(); }
  static inline std::unique_ptr<locaid::test_support::ScopedTempDir> dir_;
  static inline fs::path root_, drive_;
};

TEST_F(ReplaySmooth, SmoothedMetricsSitBesideTheForwardOnes) {
  const nlohmann::json j = Replay("--smooth" + Cache());
  ASSERT_TRUE(j.contains("smoothed")) << j.dump();
  const nlohmann::json& s = j["smoothed"];
  for (const char* key : {"rmse_gps_m", "nees_mean"}) {
    ASSERT_TRUE(s[key].is_number()) << key;
    EXPECT_TRUE(std::isfinite(s[key].get<double>())) << key;
  }
  ASSERT_EQ(s["outages"].size(), 1u);
  ASSERT_EQ(j["outages"].size(), 1u);
  for (const nlohmann::json* o : {&j["outages"][0], &s["outages"][0]})
    for (const char* key : {"end_error_m", "end_error_pct", "max_error_m", "rmse_m"})
      EXPECT_TRUE((*o)[key].is_number()) << key << " in " << o->dump();
  EXPECT_LT(s["rmse_gps_m"].get<double>(), j["rmse_gps_m"].get<double>());
  EXPECT_LT(s["outages"][0]["rmse_m"].get<double>(), j["outages"][0]["rmse_m"].get<double>());
  EXPECT_EQ(j["smoothing"]["kind"], "offline");
  EXPECT_GT(j["smoothing"]["epochs"].get<int>(), 140);
  // Without --smooth: neither object.
  const nlohmann::json plain = Replay(Cache());
  EXPECT_FALSE(plain.contains("smoothed"));
  EXPECT_FALSE(plain.contains("smoothing"));
  EXPECT_EQ(plain["rmse_gps_m"], j["rmse_gps_m"]) << "smoothing leaves the forward filter as it is";
}

TEST_F(ReplaySmooth, TheFilesHoldTheSmoothedTrajectory) {
  const fs::path fwd = root_ / "fwd.tum", smo = root_ / "smo.tum", csv = root_ / "smo.csv";
  Replay("--out-tum " + fwd.string() + Cache());
  Replay("--smooth --out-tum " + smo.string() + " --out-csv " + csv.string() + Cache());
  const auto lines = [](const fs::path& p) {
    std::ifstream in(p);
    std::string l;
    std::vector<std::string> out;
    while (std::getline(in, l)) out.push_back(l);
    return out;
  };
  const auto a = lines(fwd), b = lines(smo);
  ASSERT_GT(a.size(), 100u);
  ASSERT_EQ(a.size(), b.size()) << "one pose per frame either way";
  int differ = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].substr(0, a[i].find(' ')), b[i].substr(0, b[i].find(' '))) << "same stamps";
    differ += a[i] != b[i];
  }
  EXPECT_GT(differ, static_cast<int>(a.size()) / 2);
  EXPECT_GT(lines(csv).size(), 100u);
}

TEST_F(ReplaySmooth, ALagLongerThanTheDriveIsTheWholeDriveSmoothed) {
  const nlohmann::json whole = Replay("--smooth" + Cache());
  const nlohmann::json lag = Replay("--lag 30" + Cache());  // the drive lasts 15 s
  EXPECT_EQ(lag["smoothing"]["kind"], "fixed_lag");
  EXPECT_EQ(lag["smoothed"], whole["smoothed"]);
  const nlohmann::json short_lag = Replay("--lag 0.5" + Cache());
  EXPECT_NE(short_lag["smoothed"], whole["smoothed"]);
}

TEST_F(ReplaySmooth, AStoreSpilledToDiskGivesTheSameResult) {
  // 1 MB holds about 90 epochs of the IMU model: the rest go to TMPDIR.
  const nlohmann::json memory = Replay("--smooth" + Cache());
  const nlohmann::json spilled = Replay("--smooth --smooth-memory-mb 1" + Cache());
  EXPECT_GT(spilled["smoothing"]["bytes_spilled"].get<double>(), 0);
  EXPECT_EQ(memory["smoothing"]["bytes_spilled"].get<double>(), 0);
  EXPECT_EQ(spilled["smoothed"], memory["smoothed"]);
}

TEST_F(ReplaySmooth, VoFailingInPlacesIsSmoothedThrough) {
  // Two seconds of (nearly) black images inside the outage: the filter dead-reckons,
  // the smoother runs over it (no VO cache: camera faults change the images).
  const nlohmann::json j = Replay("--smooth", "dark.yaml");
  ASSERT_TRUE(j.contains("smoothed"));
  EXPECT_GT(j["vo_lost_frames"].get<int>(), 5) << "VO failed in the dark";
  EXPECT_TRUE(std::isfinite(j["smoothed"]["rmse_gps_m"].get<double>()));
  EXPECT_LT(j["smoothed"]["outages"][0]["rmse_m"].get<double>(), j["outages"][0]["rmse_m"].get<double>());
}

TEST_F(ReplaySmooth, ALagOutOfRangeIsRefusedByName) {
  for (const std::string bad : {"31", "0", "-1", "x"}) {
    const auto r = RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() +
                              " --lag " + bad);
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.out.find("--lag"), std::string::npos) << r.out;
  }
}

}  // namespace
