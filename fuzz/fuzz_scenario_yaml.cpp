// libFuzzer target: scenario YAML (pipeline/scenario_yaml.hpp).
// Contract: ParseScenarioYaml returns a scenario or throws
// pipeline::ScenarioError (no yaml-cpp or std exception escapes); an accepted
// scenario passes fusion::ValidateScenario and drives a GpsScenario over a
// short synthetic drive without undefined behaviour.
#include "fuzz/fuzz_support.hpp"
#include "fusion/scenario.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <exception>
#include <typeinfo>

namespace {

constexpr int kFixes = 50;
constexpr int64_t kStepNs = 100'000'000;  // 10 Hz OXTS
constexpr int64_t kStartNs = 1'317'000'000'000'000'000;

void Exercise(const locaid::fusion::Scenario& scenario) {
  locaid::fusion::ValidateScenario(scenario);
  locaid::fusion::GpsScenario gps(locaid::fusion::PlaceOutagesForDrive(scenario, 60.0));
  for (int i = 0; i < kFixes; ++i) {
    const int64_t t_ns = kStartNs + i * kStepNs;
    const auto fix = gps.Apply(t_ns, 49.0 + 1e-6 * i, 8.4, 110.0);
    (void)fix;
    (void)gps.InOutage(t_ns);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  locaid::fusion::Scenario scenario;
  try {
    scenario = locaid::pipeline::ParseScenarioYaml(text, "fuzz.yaml");
  } catch (const locaid::pipeline::ScenarioError&) {
    return 0;
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("ParseScenarioYaml threw ") + typeid(e).name() + ": " + e.what());
  }
  try {
    Exercise(scenario);
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("accepted scenario fails: ") + typeid(e).name() + ": " + e.what());
  }
  return 0;
}
