// Runs the real build/bin/locaid-eval on small files and checks its output
// and exit status. JSON is checked by plain string search (no JSON library in
// this test target).
#include "eval/devkit.hpp"
#include "eval/trajectory_metrics.hpp"
#include "kitti/pose_io.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace locaid::eval {
namespace {

namespace fs = std::filesystem;

// JSON numbers are printed with round-trip precision; t_rel_pct is
// t_err * 100 computed in double, so allow a few ulps.
constexpr double kJsonTol = 1e-12;
constexpr int kExitBadInput = 2;

const fs::path kBinary = fs::path(LOCAID_BIN_DIR) / "locaid-eval";

struct ProcessResult {
  int status = -1;
  std::string out, err;
};

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// The raw text of the value of a TOP-LEVEL key of a JSON object (scalars:
// numbers, null, strings), skipping nested objects/arrays and string contents.
std::optional<std::string> JsonRaw(const std::string& json, const std::string& key) {
  int depth = 0;
  for (size_t i = 0; i < json.size(); ++i) {
    const char c = json[i];
    if (c == '{' || c == '[') {
      ++depth;
    } else if (c == '}' || c == ']') {
      --depth;
    } else if (c == '"') {
      size_t end = i + 1;
      while (end < json.size() && json[end] != '"') end += (json[end] == '\\') ? 2 : 1;
      const std::string name = json.substr(i + 1, end - i - 1);
      i = end;
      if (depth == 1 && name == key && end + 1 < json.size() && json[end + 1] == ':') {
        const size_t start = end + 2;
        size_t stop = start;
        if (json[start] == '"') {
          stop = json.find('"', start + 1) + 1;
        } else {
          stop = json.find_first_of(",}", start);
        }
        return json.substr(start, stop - start);
      }
    }
  }
  return std::nullopt;
}

double JsonNumber(const std::string& json, const std::string& key) {
  const auto raw = JsonRaw(json, key);
  if (!raw) {
    ADD_FAILURE() << "key " << key << " missing in " << json;
    return std::nan("");
  }
  return std::strtod(raw->c_str(), nullptr);
}

std::vector<Eigen::Isometry3d> StraightLine(size_t frames, double step_m, double scale = 1.0) {
  std::vector<Eigen::Isometry3d> poses(frames, Eigen::Isometry3d::Identity());
  for (size_t i = 0; i < frames; ++i) poses[i].translation() = Eigen::Vector3d(0.01 * i, 0, scale * step_m * i);
  return poses;
}

class EvalAppTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(fs::exists(kBinary)) << kBinary << " not built (build target locaid-eval, a dependency of eval_tests)";
  }

  ProcessResult Exec(const std::string& args) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = Quote(kBinary.string()) + " " + args + " >" + Quote(out.string()) + " 2>" +
                            Quote(err.string());
    ProcessResult r;
    const int raw = std::system(cmd.c_str());
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = Slurp(out);
    r.err = Slurp(err);
    return r;
  }

  const locaid::test_support::ScopedTempDir dir_{"eval_app"};
};

TEST_F(EvalAppTest, JsonMatchesLibraryOnKittiFiles) {
  const auto gt = StraightLine(301, 1.0);         // ~300 m
  const auto est = StraightLine(301, 1.0, 1.02);  // 2 % scale error
  kitti::WriteKittiPoses(dir_ / "gt.txt", gt);
  kitti::WriteKittiPoses(dir_ / "est.txt", est);
  const ProcessResult r = Exec("--json --gt " + Quote((dir_ / "gt.txt").string()) + " --est " +
                     Quote((dir_ / "est.txt").string()));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string& j = r.out;
  ASSERT_EQ(j.front(), '{') << j;

  const DevkitResult d = EvaluateDevkit(gt, est);
  const AteResult ate = ComputeAte(gt, est, Alignment::kSe3);
  const RpeResult rpe = ComputeRpe(gt, est);
  EXPECT_EQ(JsonNumber(j, "frames"), 301);
  EXPECT_EQ(JsonNumber(j, "segments"), static_cast<double>(d.segments.size()));
  EXPECT_NEAR(JsonNumber(j, "length_m"), PathLengthM(gt), kJsonTol);
  EXPECT_NEAR(JsonNumber(j, "t_rel_pct"), *d.t_err * 100, kJsonTol);
  EXPECT_NEAR(JsonNumber(j, "r_rel_deg_per_100m"), *d.r_err_rad_per_m * 180 / M_PI * 100, kJsonTol);
  // Steps are 1.00005 m long, so the last frame of a segment overshoots L by
  // 0.005 m only: ~2 % to float precision.
  EXPECT_NEAR(JsonNumber(j, "t_rel_pct"), 2.0, 1e-4);
  EXPECT_NEAR(JsonNumber(j, "ate_rmse_m"), ate.trans_m.rmse, kJsonTol);
  EXPECT_NEAR(JsonNumber(j, "rpe_trans_rmse_m"), rpe.trans_m.rmse, kJsonTol);
  EXPECT_NEAR(JsonNumber(j, "rpe_rot_rmse_deg"), rpe.rot_deg.rmse, kJsonTol);
  EXPECT_NE(j.find("\"per_length\":[{"), std::string::npos) << j;
  EXPECT_EQ(JsonRaw(j, "note"), std::nullopt);
}

TEST_F(EvalAppTest, ShortTrajectoryHasNullDevkitMetricAndANote) {
  const auto gt = StraightLine(51, 1.0);  // 50 m < 100 m
  auto est = gt;
  for (auto& T : est) T.translation() += Eigen::Vector3d(3, 4, 0);
  kitti::WriteKittiPoses(dir_ / "gt.txt", gt);
  kitti::WriteKittiPoses(dir_ / "est.txt", est);
  const ProcessResult r = Exec("--json --align none --gt " + Quote((dir_ / "gt.txt").string()) + " --est " +
                     Quote((dir_ / "est.txt").string()));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(JsonRaw(r.out, "t_rel_pct"), "null");
  EXPECT_EQ(JsonRaw(r.out, "r_rel_deg_per_100m"), "null");
  EXPECT_EQ(JsonNumber(r.out, "segments"), 0);
  ASSERT_TRUE(JsonRaw(r.out, "note").has_value()) << r.out;
  EXPECT_NE(r.out.find("shorter than the shortest KITTI segment"), std::string::npos) << r.out;
  EXPECT_NEAR(JsonNumber(r.out, "ate_rmse_m"), 5.0, 1e-9);  // offset (3,4,0), no alignment

  const ProcessResult table = Exec("--gt " + Quote((dir_ / "gt.txt").string()) + " --est " +
                         Quote((dir_ / "est.txt").string()));
  ASSERT_EQ(table.status, 0) << table.err;
  EXPECT_NE(table.out.find("no devkit segments"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("ATE (alignment se3)"), std::string::npos) << table.out;
}

TEST_F(EvalAppTest, TumFilesAreAssociatedByTime) {
  std::vector<kitti::StampedPose> gt, est;
  const auto line = StraightLine(200, 1.0);
  for (size_t i = 0; i < line.size(); ++i) {
    gt.push_back({1000.0 + 0.1 * i, line[i]});
    if (i % 2 == 0) est.push_back({1000.0 + 0.1 * i - 0.005, line[i]});
  }
  kitti::WriteTumPoses(dir_ / "gt.tum", gt);
  kitti::WriteTumPoses(dir_ / "est.tum", est);
  const std::string files =
      " --gt " + Quote((dir_ / "gt.tum").string()) + " --est " + Quote((dir_ / "est.tum").string());
  const ProcessResult r = Exec("--json" + files);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(JsonNumber(r.out, "frames"), 100);
  EXPECT_EQ(JsonRaw(r.out, "format"), "\"tum\"");
  EXPECT_LT(JsonNumber(r.out, "ate_rmse_m"), 1e-9);
  EXPECT_NEAR(JsonNumber(r.out, "t_rel_pct"), 0.0, 1e-9);

  const ProcessResult strict = Exec("--json --max-dt 0.001" + files);
  EXPECT_EQ(strict.status, kExitBadInput);
  EXPECT_NE(strict.err.find("only 0 matched poses"), std::string::npos) << strict.err;
}

TEST_F(EvalAppTest, BadUsageAndBadInputExitWithStatus2) {
  kitti::WriteKittiPoses(dir_ / "gt.txt", StraightLine(5, 1.0));
  std::ofstream(dir_ / "bad.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n";
  const std::string gt = Quote((dir_ / "gt.txt").string());

  const ProcessResult missing_est = Exec("--gt " + gt);
  EXPECT_EQ(missing_est.status, kExitBadInput);
  EXPECT_NE(missing_est.err.find("--est"), std::string::npos) << missing_est.err;

  const ProcessResult bad_align = Exec("--gt " + gt + " --est " + gt + " --align sim3");
  EXPECT_EQ(bad_align.status, kExitBadInput);
  EXPECT_FALSE(bad_align.err.empty());

  const ProcessResult bad_file = Exec("--gt " + gt + " --est " + Quote((dir_ / "bad.txt").string()));
  EXPECT_EQ(bad_file.status, kExitBadInput);
  EXPECT_NE(bad_file.err.find("bad.txt:2: 11 numbers, expected 12"), std::string::npos) << bad_file.err;
  EXPECT_TRUE(bad_file.out.empty()) << bad_file.out;

  const ProcessResult absent = Exec("--gt " + gt + " --est " + Quote((dir_ / "absent.txt").string()));
  EXPECT_EQ(absent.status, kExitBadInput);
  EXPECT_NE(absent.err.find("absent.txt: cannot open"), std::string::npos) << absent.err;

  const ProcessResult help = Exec("--help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.out.find("--max-dt"), std::string::npos) << help.out;
}

}  // namespace
}  // namespace locaid::eval
