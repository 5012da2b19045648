// locaid-replay as a user runs it: on a small rendered drive, the VO cache
// gives the same filter result without rerunning VO, a cache of another run
// is refused by name, and --ekf settings are checked.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exit_code = -1;
  std::string out;  // stdout + stderr
};

RunResult RunCommand(const std::string& cmd) {
  RunResult r;
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string JsonField(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) return {};
  const auto start = at + key.size() + 3;
  return json.substr(start, json.find_first_of(",\n}", start) - start);
}

class ReplayCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: CTest runs each test of the suite as its own process.
    root_ = fs::path(::testing::TempDir()) / ("replay_cli_" + std::to_string(getpid()));
    fs::remove_all(root_);
    const auto r = RunCommand(std::string(LOCAID_BIN_DIR) + "/locaid-synth --out " + root_.string() +
                       " --frames 80 --width 640 --height 192 --seed 7 -q");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    for (const auto& e : fs::directory_iterator(root_))
      if (e.is_directory()) drive_ = e.path();
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }
  static std::string Replay(const std::string& args) {
    return std::string(LOCAID_BIN_DIR) + "/locaid-replay --drive " + drive_.string() +
           " --scenario open-sky --json " + args;
  }
  static inline fs::path root_, drive_;
};

TEST_F(ReplayCli, VoCacheReproducesTheFilterResultWithoutVo) {
  ASSERT_FALSE(drive_.empty());
  const fs::path cache = root_ / "vo.cache";
  fs::remove(cache);
  const auto first = RunCommand(Replay("--vo-cache " + cache.string()));
  ASSERT_EQ(first.exit_code, 0) << first.out;
  ASSERT_TRUE(fs::exists(cache));
  const auto second = RunCommand(Replay("--vo-cache " + cache.string()));
  ASSERT_EQ(second.exit_code, 0) << second.out;
  const std::string rmse1 = JsonField(first.out, "rmse_gps_m"), rmse2 = JsonField(second.out, "rmse_gps_m");
  ASSERT_FALSE(rmse1.empty()) << first.out;
  EXPECT_NEAR(std::stod(rmse1), std::stod(rmse2), 1e-9);
  // The cached run did no VO work.
  EXPECT_EQ(std::stod(JsonField(second.out, "vo_ms_mean")), 0.0);
  EXPECT_GT(std::stod(JsonField(first.out, "vo_ms_mean")), 0.0);
  // A filter setting changes the result while the cache is reused.
  const auto tuned = RunCommand(Replay("--vo-cache " + cache.string() + " --ekf vo_cov_scale=50"));
  ASSERT_EQ(tuned.exit_code, 0) << tuned.out;
  EXPECT_NE(JsonField(tuned.out, "rmse_gps_m"), rmse1);
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

TEST_F(ReplayCli, BadEkfSettingsNameTheProblem) {
  ASSERT_FALSE(drive_.empty());
  const auto unknown = RunCommand(Replay("--max-frames 5 --ekf no_such_field=1"));
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.out.find("no_such_field=1: expected NAME=VALUE"), std::string::npos) << unknown.out;
  EXPECT_NE(unknown.out.find("vo_cov_scale"), std::string::npos) << unknown.out;
  for (const std::string bad : {"vo_cov_scale=abc", "vo_cov_scale=nan", "vo_cov_scale=-1", "vo_cov_scale=1x"}) {
    const auto r = RunCommand(Replay("--max-frames 5 --ekf " + bad));
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.out.find("value must be a finite number >= 0"), std::string::npos) << bad << ": " << r.out;
  }
}

}  // namespace
