// Scenario YAML files: good files load, bad files fail naming the field.
#include "pipeline/scenario_yaml.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace locaid::pipeline {
namespace {

using test_support::ScopedTempDir;

// `name` in `dir`, holding `text` (a scenario file is named after its file).
std::string WriteTemp(const ScopedTempDir& dir, const std::string& name, const std::string& text) {
  const auto path = dir / name;
  std::ofstream(path) << text;
  return path.string();
}

// Every example shipped in scenarios/ loads, and the two urban-canyon files
// differ from the built-in only where they say.
TEST(ScenarioYaml, ShippedExamplesLoad) {
  const auto dir = std::filesystem::path(LOCAID_SOURCE_DIR) / "scenarios";
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".yaml") continue;
    ++files;
    EXPECT_NO_THROW(LoadScenario(e.path().string())) << e.path();
  }
  EXPECT_GE(files, 5);
  const auto builtin = sim::BuiltinScenario("urban-canyon");
  const auto per_axis = LoadScenario((dir / "urban-canyon.yaml").string());
  const auto two_d = LoadScenario((dir / "urban-canyon-2drms.yaml").string());
  EXPECT_DOUBLE_EQ(per_axis.gps_sigma_h_m, builtin.gps_sigma_h_m);
  EXPECT_NEAR(two_d.gps_sigma_h_m * std::sqrt(2.0), builtin.gps_sigma_h_m, 1e-4);
  EXPECT_DOUBLE_EQ(two_d.gps_rate_hz, builtin.gps_rate_hz);
  EXPECT_DOUBLE_EQ(two_d.jump_probability, builtin.jump_probability);
  EXPECT_DOUBLE_EQ(two_d.jump_size_m, builtin.jump_size_m);
}

TEST(ScenarioYaml, LoadsAGoodFile) {
  const ScopedTempDir dir("scenario_yaml");
  const auto path = WriteTemp(dir, "good.yaml",
                              "base: urban-canyon\n"
                              "gps: {rate_hz: 2, sigma_h_m: 4.5, jump_probability: 0.1}\n"
                              "imu: {grade: mems}\n"
                              "outages:\n  - {start_s: 10, duration_s: 5}\n  - {start_s: 30, end_s: 42}\n"
                              "seed: 17\n");
  const auto s = LoadScenario(path);
  EXPECT_EQ(s.name, "good");
  EXPECT_DOUBLE_EQ(s.gps_rate_hz, 2);
  EXPECT_DOUBLE_EQ(s.gps_sigma_h_m, 4.5);
  EXPECT_DOUBLE_EQ(s.jump_size_m, sim::BuiltinScenario("urban-canyon").jump_size_m);
  EXPECT_EQ(s.imu_grade, sim::ImuGrade::kMems);
  ASSERT_EQ(s.outages.size(), 2u);
  EXPECT_DOUBLE_EQ(s.outages[1].duration_s, 12);
  EXPECT_EQ(s.seed, 17u);
}

TEST(ScenarioYaml, BuiltinNames) {
  for (const auto& n : sim::BuiltinScenarioNames()) EXPECT_EQ(LoadScenario(n).name, n);
  EXPECT_THROW(LoadScenario("no-such-scenario"), ScenarioError);
}

struct BadCase {
  const char* name;
  const char* yaml;
  const char* field;   // must appear in the message
  const char* reason;  // must appear in the message
};

class BadScenarioFile : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadScenarioFile, ErrorNamesFieldAndReason) {
  const auto& c = GetParam();
  const ScopedTempDir dir("scenario_yaml");
  const auto path = WriteTemp(dir, std::string(c.name) + ".yaml", c.yaml);
  try {
    LoadScenario(path);
    FAIL() << "accepted: " << c.yaml;
  } catch (const ScenarioError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.field), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.reason), std::string::npos) << msg;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadScenarioFile,
    ::testing::Values(
        BadCase{"unknown_top", "gsp: {rate_hz: 1}\n", "gsp", "unknown key"},
        BadCase{"unknown_nested", "gps: {rate: 1}\n", "gps.rate", "unknown key"},
        BadCase{"wrong_type", "gps: {sigma_h_m: three}\n", "gps.sigma_h_m", "expected a number"},
        BadCase{"negative_sigma", "gps: {sigma_h_m: -2}\n", "gps.sigma_h_m", ">= 0"},
        BadCase{"zero_rate", "gps: {rate_hz: 0}\n", "gps.rate_hz", "> 0"},
        BadCase{"zero_stated", "gps: {stated_sigma_scale: 0}\n", "gps.stated_sigma_scale", "> 0"},
        BadCase{"huge_stated", "gps: {stated_sigma_scale: 1000}\n", "gps.stated_sigma_scale", "(0, 100]"},
        BadCase{"probability", "gps: {jump_probability: 1.5}\n", "gps.jump_probability", "[0, 1]"},
        BadCase{"end_before_start", "outages: [{start_s: 20, end_s: 10}]\n", "outages[0].end_s", "before"},
        BadCase{"no_duration", "outages: [{start_s: 20}]\n", "outages[0].duration_s", "missing"},
        BadCase{"outages_not_list", "outages: {start_s: 1}\n", "outages", "expected a list"},
        BadCase{"bad_grade", "imu: {grade: tactical}\n", "imu.grade", "mems"},
        BadCase{"bad_base", "base: mars\n", "base", "unknown scenario"},
        BadCase{"bad_seed", "seed: -3\n", "seed", ">= 0"},
        BadCase{"syntax", "gps: {rate_hz: 1\n", ":", "YAML syntax"}),
    [](const ::testing::TestParamInfo<BadCase>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace locaid::pipeline
