// The scenario YAML's `camera:` list: good lists load with the documented
// defaults, bad ones fail naming the entry, the field and the rule.
#include "pipeline/scenario_yaml.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace locaid::pipeline {
namespace {

using sim::CameraFaultKind;

TEST(ScenarioYamlCamera, LoadsEveryFaultWithItsParametersAndDefaults) {
  const sim::Scenario s = ParseScenarioYaml(
      "camera: [{start_s: 20, duration_s: 10, fault: dark, gain: 0.12, noise_dn: 2},\n"
      "         {start_s: 40, end_s: 50, fault: frozen},\n"
      "         {start_s: 1, duration_s: 2, fault: dark},\n"
      "         {start_s: 3, duration_s: 1, fault: noise},\n"
      "         {start_s: 4, duration_s: 1, fault: blur, blur_sigma_px: 5},\n"
      "         {start_s: 5, duration_s: 1, fault: drop},\n"
      "         {start_s: 6, duration_s: 1, fault: left_only},\n"
      "         {start_s: 7, duration_s: 1, fault: right_only}]\n",
      "cams.yaml");
  ASSERT_EQ(s.camera_faults.size(), 8u);
  const auto& dark = s.camera_faults[0];
  EXPECT_EQ(dark.kind, CameraFaultKind::kDark);
  EXPECT_DOUBLE_EQ(dark.start_s, 20);
  EXPECT_DOUBLE_EQ(dark.duration_s, 10);
  EXPECT_DOUBLE_EQ(dark.gain, 0.12);
  EXPECT_DOUBLE_EQ(dark.noise_dn, 2);
  EXPECT_EQ(s.camera_faults[1].kind, CameraFaultKind::kFrozen);
  EXPECT_DOUBLE_EQ(s.camera_faults[1].duration_s, 10) << "end_s 50 - start_s 40";
  EXPECT_DOUBLE_EQ(s.camera_faults[2].gain, 0.06) << "dark's default gain";
  EXPECT_DOUBLE_EQ(s.camera_faults[2].noise_dn, 3) << "dark's default noise";
  EXPECT_DOUBLE_EQ(s.camera_faults[3].noise_dn, 8) << "a noise fault's default";
  EXPECT_DOUBLE_EQ(s.camera_faults[4].blur_sigma_px, 5);
  const std::vector<CameraFaultKind> kinds = {CameraFaultKind::kDrop, CameraFaultKind::kLeftOnly,
                                              CameraFaultKind::kRightOnly};
  for (size_t i = 0; i < kinds.size(); ++i) EXPECT_EQ(s.camera_faults[5 + i].kind, kinds[i]);
  for (const auto& f : s.camera_faults) EXPECT_STREQ(ToString(f.kind), ToString(f.kind));  // named
  EXPECT_STREQ(ToString(CameraFaultKind::kLeftOnly), "left_only");
  EXPECT_TRUE(ParseScenarioYaml("name: x\n", "x.yaml").camera_faults.empty()) << "no key: no fault";
}

// The message of the ScenarioError `yaml` raises ("" when it loads).
std::string ErrorOf(const std::string& yaml) {
  try {
    ParseScenarioYaml(yaml, "bad.yaml");
  } catch (const ScenarioError& e) {
    return e.what();
  }
  return "";
}

TEST(ScenarioYamlCamera, BadEntriesNameTheFieldAndTheRule) {
  struct Case {
    std::string yaml, expected;
  };
  const std::vector<Case> cases = {
      {"camera: {start_s: 1}\n", "bad.yaml:1: field 'camera': expected a list"},
      {"camera: [3]\n", "field 'camera[0]': expected a mapping"},
      {"camera: [{start_s: 1, duration_s: 2}]\n", "field 'camera[0].fault': missing"},
      {"camera: [{start_s: 1, duration_s: 2, fault: fog}]\n",
       "field 'camera[0].fault': expected dark, noise, blur, frozen, drop, left_only or right_only, got 'fog'"},
      {"camera: [{start_s: 1, duration_s: 2, fault: frozen, gain: 0.1}]\n",
       "field 'camera[0].gain': applies to dark faults, not to frozen"},
      {"camera: [{start_s: 1, duration_s: 2, fault: blur, noise_dn: 1}]\n",
       "field 'camera[0].noise_dn': applies to dark and noise faults, not to blur"},
      {"camera: [{start_s: 1, duration_s: 2, fault: dark, blur_sigma_px: 2}]\n",
       "field 'camera[0].blur_sigma_px': applies to blur faults, not to dark"},
      {"camera: [{start_s: 1, duration_s: 2, fault: noise, colour: red}]\n",
       "field 'camera[0].colour': unknown key (allowed: duration_s, end_s, fault, noise_dn, start_s)"},
      {"camera: [{duration_s: 2, fault: drop}]\n", "field 'camera[0].start_s': missing"},
      {"camera: [{start_s: 1, fault: drop}]\n", "field 'camera[0].duration_s': missing (give duration_s or end_s)"},
      {"camera: [{start_s: 1, duration_s: 2, end_s: 3, fault: drop}]\n",
       "field 'camera[0]': give duration_s or end_s, not both"},
      {"camera: [{start_s: 5, end_s: 4, fault: drop}]\n", "field 'camera[0].end_s': fault ends (4 s) before or at its start"},
      {"camera: [{start_s: -1, duration_s: 2, fault: drop}]\n", "field 'camera[0].start_s': must be >= 0, got -1"},
      {"camera: [{start_s: 1, duration_s: 0, fault: drop}]\n", "field 'camera[0].duration_s': must be > 0, got 0"},
      {"camera: [{start_s: 1, duration_s: 1, fault: drop}, {start_s: 1, duration_s: 1, fault: dark, gain: 2}]\n",
       "bad.yaml:1: field 'camera[1].gain': must be in (0, 1], got 2"},
      {"camera: [{start_s: 1, duration_s: 1, fault: dark, gain: 0}]\n", "field 'camera[0].gain': must be > 0, got 0"},
      {"camera: [{start_s: 1, duration_s: 1, fault: dark, gain: .nan}]\n", "field 'camera[0].gain': must be > 0"},
      {"camera: [{start_s: 1, duration_s: 1, fault: noise, noise_dn: 300}]\n",
       "field 'camera[0].noise_dn': must be in [0, 255], got 300"},
      {"camera: [{start_s: 1, duration_s: 1, fault: blur, blur_sigma_px: 80}]\n",
       "field 'camera[0].blur_sigma_px': must be in (0, 50], got 80"},
      {"camera: [{start_s: 1, duration_s: 1, fault: blur, blur_sigma_px: fuzzy}]\n",
       "field 'camera[0].blur_sigma_px': expected a number, got 'fuzzy'"},
      {"camera: [{start_s: 2e6, duration_s: 1, fault: drop}]\n",
       "bad.yaml: scenario bad: field camera[0].start_s: must be in [0, 1e6], got 2e+06"},
  };
  for (const Case& c : cases) {
    const std::string error = ErrorOf(c.yaml);
    EXPECT_NE(error.find(c.expected), std::string::npos) << c.yaml << "gave: " << (error.empty() ? "(loaded)" : error);
  }
}

}  // namespace
}  // namespace locaid::pipeline
