// Inputs the fuzzers found (fuzz/corpus/<target>/, also the regression corpus
// every fuzz run starts from) replayed through the parsers in the ordinary
// test build, so a regression fails here even without clang.
#include "sim/scenario.hpp"
#include "pipeline/live_frame_source.hpp"
#include "pipeline/scenario_yaml.hpp"
#include "server/live_source_request.hpp"
#include "server/push_requests.hpp"

#include <gtest/gtest.h>

#include <climits>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <typeinfo>
#include <vector>

namespace locaid {
namespace {

// (file name, content) of every file in fuzz/corpus/<target>/.
std::vector<std::pair<std::string, std::string>> Corpus(const std::string& target) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(LOCAID_FUZZ_CORPUS) / target)) {
    std::ifstream in(entry.path(), std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    out.emplace_back(entry.path().filename().string(), text.str());
  }
  return out;
}

// Found by fuzz_scenario_yaml: a mapping or list used as a key escaped as
// YAML::TypedBadConversion instead of a ScenarioError naming the line.
TEST(FuzzRegression, ScenarioYamlCorpusParsesOrThrowsScenarioError) {
  const auto corpus = Corpus("scenario_yaml");
  ASSERT_GE(corpus.size(), 3u);
  for (const auto& [name, text] : corpus) {
    try {
      (void)pipeline::ParseScenarioYaml(text, name);
    } catch (const pipeline::ScenarioError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << name << ": threw " << typeid(e).name() << ": " << e.what();
    }
  }
}

TEST(FuzzRegression, MappingAsScenarioKeyNamesTheLine) {
  try {
    (void)pipeline::ParseScenarioYaml("seed: 1\ngps: {rate_hz: 1, {a: 1}: 2}\n", "key.yaml");
    FAIL() << "accepted a mapping as a key";
  } catch (const pipeline::ScenarioError& e) {
    EXPECT_STREQ(e.what(), "key.yaml:2: field 'gps': a key must be a plain name");
  }
}

// Found by fuzz_scenario_yaml (UBSan): gps.rate_hz 1e91 overflowed the int64
// fix slot (FixSlot) and jump_duration_s 1e300 the int64 jump end, both
// float-to-integer casts out of range; now refused by ValidateScenario.
TEST(FuzzRegression, ScenarioRatesAndDurationsThatOverflowInt64AreRefused) {
  const std::pair<const char*, const char*> cases[] = {
      {"gps: {rate_hz: 1e91}\n", "field gps.rate_hz: must be in (0, 1000]"},
      {"gps: {jump_probability: 1, jump_duration_s: 1e300}\n", "field gps.jump_duration_s: must be in [0, 1e6]"},
  };
  for (const auto& [yaml, message] : cases) {
    try {
      (void)pipeline::ParseScenarioYaml(yaml, "big.yaml");
      ADD_FAILURE() << "accepted: " << yaml;
    } catch (const pipeline::ScenarioError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
  // The bounds themselves are accepted.
  sim::Scenario s;
  s.gps_rate_hz = 1000;
  s.jump_duration_s = 1e6;
  EXPECT_NO_THROW(sim::ValidateScenario(s));
}

// Found by fuzz_push_requests (fuzz/corpus/push_requests/crash-zero-variance-
// covariance): a GpsFix covariance with a zero U variance and a 1e-135 E-U
// term passed the symmetry check, and Eigen's eigensolver gave its smallest
// eigenvalue as +3e-267, so a matrix that is not positive definite was
// accepted. The check is a Cholesky factorisation now.
TEST(FuzzRegression, GpsCovarianceWithAZeroVarianceIsRefused) {
  v1::GpsFix fix;
  fix.set_t_ns(3'000'000);
  fix.set_fix_type(v1::GPS_FIX_RTK_FIXED);
  fix.set_latitude_deg(49.015);
  fix.set_longitude_deg(8.43);
  fix.set_altitude_m(116.4);
  for (double v : {0.04, 0.01, 0.0, 0.01, 0.04, 0.0, -2.7516420536594796e-135, 3.11261356879985e-322, 0.0}) {
    fix.add_covariance_enu_m2(v);
  }
  pipeline::LiveItem item;
  EXPECT_EQ(server::GpsItemFromProto(fix, &item), "covariance_enu_m2: not positive definite");
  // The same fix with a U variance is taken, covariance and all.
  fix.set_covariance_enu_m2(8, 0.09);
  pipeline::LiveItem good;
  ASSERT_EQ(server::GpsItemFromProto(fix, &good), "");
  ASSERT_TRUE(good.gps.cov_enu_m2.has_value());
  EXPECT_DOUBLE_EQ((*good.gps.cov_enu_m2)(2, 2), 0.09);
}

// fuzz/corpus/push_requests/start-overflowing-extrinsic: a LiveSource whose
// T_cam0_imu is finite but whose R R^T overflows (inf - inf = NaN, the
// determinant +inf) passed `norm > 1e-6 || det < 0`, both false with NaN.
// The check is `!(norm <= 1e-6)` now; fuzz_push_requests' contract catches it.
TEST(FuzzRegression, ExtrinsicWhoseRotationCheckOverflowsIsRefused) {
  v1::LiveSource live;
  live.set_fx(20);
  live.set_fy(20);
  live.set_cx(7.5);
  live.set_cy(7.5);
  live.set_baseline_m(0.5);
  live.set_width(16);
  live.set_height(16);
  for (double v : {1e200, 1e200, 0.0, 0.0, -1e200, 1e200, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0}) live.add_t_cam0_imu(v);
  server::LiveSourceSetup setup;
  EXPECT_EQ(server::LiveSourceFromProto(live, Eigen::Isometry3d::Identity(), &setup),
            "live.T_cam0_imu: rotation part is not orthonormal");
  // A rotation (x right, y down, z forward from x forward, y left, z up) is taken.
  live.clear_t_cam0_imu();
  for (double v : {0.0, -1.0, 0.0, 0.1, 0.0, 0.0, -1.0, -0.2, 1.0, 0.0, 0.0, -1.1}) live.add_t_cam0_imu(v);
  ASSERT_EQ(server::LiveSourceFromProto(live, Eigen::Isometry3d::Identity(), &setup), "");
  EXPECT_DOUBLE_EQ(setup.camera.T_cam0_imu.translation().z(), -1.1);
  EXPECT_DOUBLE_EQ(setup.camera.max_gps_delay_s, server::kDefaultGpsDelayS);
}

// Found by fuzz_push_requests (crash-denormal-asymmetric-covariance): with
// denormal entries (1e-316) isApprox's squared norms underflow to 0, so an
// asymmetric covariance passed as symmetric. Compared entry by entry now.
TEST(FuzzRegression, DenormalAsymmetricGpsCovarianceIsRefused) {
  v1::GpsFix fix;
  fix.set_t_ns(3'000'000);
  fix.set_latitude_deg(49.015);
  fix.set_longitude_deg(8.43);
  fix.set_altitude_m(116.4);
  for (double v : {1.61855905577592e-319, 0.0, 0.0, 0.0, 1.61855905577592e-319, 4.97342763507486e-316, 0.0, 0.0,
                   1.78246869343015e-314}) {
    fix.add_covariance_enu_m2(v);
  }
  pipeline::LiveItem item;
  EXPECT_EQ(server::GpsItemFromProto(fix, &item), "covariance_enu_m2: not symmetric");
}

// Found by fuzz_push_requests (frame-at-int64-min-then-fix): after a frame at
// t_ns = INT64_MIN + 1, the staleness check of the next fix computed
// frame time - max_gps_delay_s, a signed overflow (UBSan); wrapped, it called
// a fix at t = 0, after the frame, stale. Saturated now.
TEST(FuzzRegression, FixAfterAFrameAtTheEarliestTimeIsNotStale) {
  pipeline::LiveCameraSetup setup;
  setup.camera = StereoCamera{20.0, 20.0, 7.5, 7.5, 0.5, 16, 16};
  pipeline::LiveFrameSource source(setup);
  pipeline::LiveItem frame;
  frame.kind = pipeline::LiveItem::Kind::kFrame;
  frame.t_ns = INT64_MIN + 1;
  frame.png = false;
  frame.left = frame.right = std::string(16 * 16, '\x40');
  ASSERT_TRUE(source.Push(std::move(frame), [] {}));
  pipeline::LiveItem fix;
  fix.kind = pipeline::LiveItem::Kind::kGps;
  fix.t_ns = fix.gps.t_ns = 0;
  fix.gps.lat_deg = 49.015;
  fix.gps.lon_deg = 8.43;
  ASSERT_TRUE(source.Push(std::move(fix), [] {}));
  source.CloseInput();
  EXPECT_EQ(source.Next().kind, pipeline::SourceItem::Kind::kFrame);
  EXPECT_EQ(source.Next().kind, pipeline::SourceItem::Kind::kEnd);
  const pipeline::LiveInputStats stats = source.input_stats();
  EXPECT_EQ(stats.gps_fixes_in, 1u);
  EXPECT_EQ(stats.gps_fixes_late, 0u) << stats.last_error;
}

}  // namespace
}  // namespace locaid
