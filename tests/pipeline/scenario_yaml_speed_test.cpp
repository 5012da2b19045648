// The scenario YAML's `speed:` mapping (a simulated vehicle speed sensor):
// loads with the documented defaults; bad values fail naming the field and the rule.
#include "error_of.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace locaid::pipeline {
namespace {

TEST(ScenarioYamlSpeed, LoadsTheSensorAndItsDefaults) {
  const sim::Scenario s =
      ParseScenarioYaml("speed: {rate_hz: 20, sigma_mps: 0.1, scale_error: 0.005}\n", "speed.yaml");
  ASSERT_TRUE(s.speed.has_value());
  EXPECT_DOUBLE_EQ(s.speed->rate_hz, 20);
  EXPECT_DOUBLE_EQ(s.speed->sigma_mps, 0.1);
  EXPECT_DOUBLE_EQ(s.speed->scale_error, 0.005);

  const sim::Scenario d = ParseScenarioYaml("speed: {}\n", "speed.yaml");
  ASSERT_TRUE(d.speed.has_value()) << "an empty mapping is a sensor with the defaults";
  EXPECT_DOUBLE_EQ(d.speed->rate_hz, 50);
  EXPECT_DOUBLE_EQ(d.speed->sigma_mps, 0.05);
  EXPECT_DOUBLE_EQ(d.speed->scale_error, 0);

  const sim::Scenario neg = ParseScenarioYaml("speed: {scale_error: -0.02}\n", "speed.yaml");
  ASSERT_TRUE(neg.speed.has_value());
  EXPECT_DOUBLE_EQ(neg.speed->scale_error, -0.02) << "a tyre that reads low";

  EXPECT_FALSE(ParseScenarioYaml("name: x\n", "x.yaml").speed.has_value()) << "no key: no speed sensor";
}

// The message of the ScenarioError `yaml` raises.
std::string ErrorOf(const std::string& yaml) {
  return test_support::ErrorOf<ScenarioError>([&] { ParseScenarioYaml(yaml, "bad.yaml"); });
}

TEST(ScenarioYamlSpeed, BadValuesNameTheFieldAndTheRule) {
  struct Case {
    std::string yaml, expected;
  };
  const std::vector<Case> cases = {
      {"speed: 50\n", "bad.yaml:1: field 'speed': expected a mapping"},
      {"speed: [50]\n", "field 'speed': expected a mapping"},
      {"speed: {rate: 50}\n", "field 'speed.rate': unknown key (allowed: rate_hz, scale_error, sigma_mps)"},
      {"speed: {rate_hz: fast}\n", "field 'speed.rate_hz': expected a number, got 'fast'"},
      {"speed: {sigma_mps: [1]}\n", "field 'speed.sigma_mps': expected a number"},
      {"speed: {rate_hz: 0}\n", "field 'speed.rate_hz': must be > 0, got 0"},
      {"speed: {sigma_mps: -0.1}\n", "field 'speed.sigma_mps': must be > 0, got -0.1"},
      {"speed: {scale_error: high}\n", "field 'speed.scale_error': expected a number, got 'high'"},
      {"speed: {scale_error: 0.7}\n", "field speed.scale_error: must be in [-0.5, 0.5], got 0.7"},
      {"speed: {rate_hz: 5000}\n", "field speed.rate_hz: must be in (0, 1000], got 5000"},
      {"speed: {sigma_mps: 11}\n", "field speed.sigma_mps: must be in (0, 10], got 11"},
  };
  for (const Case& c : cases) {
    const std::string error = ErrorOf(c.yaml);
    EXPECT_NE(error.find(c.expected), std::string::npos) << c.yaml << "gave: " << error;
  }
}

}  // namespace
}  // namespace locaid::pipeline
