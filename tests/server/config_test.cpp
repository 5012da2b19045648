// Server configuration: YAML + validation give precise errors.
#include "server/boot_session.hpp"
#include "server/config.hpp"
#include "server/malloc_arenas.hpp"
#include "error_of.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <tuple>
#include <vector>

namespace locaid::server {
namespace {

using locaid::test_support::ScopedTempDir;

// `name` in `dir`, holding `text`.
std::filesystem::path WriteTemp(const ScopedTempDir& dir, const std::string& name, const std::string& text) {
  const auto path = dir / name;
  std::ofstream(path) << text;
  return path;
}

namespace fs = std::filesystem;

std::string ErrorOf(const std::function<void()>& f) { return locaid::test_support::ErrorOf<ConfigError>(f); }

TEST(ServerConfig, YamlOverridesDefaultsAndValidates) {
  const ScopedTempDir dir("config");
  ServerConfig c;
  ApplyYamlConfig(WriteTemp(dir, "ok.yaml", "listen: 127.0.0.1:0\nqueue_size: 32\nshutdown_grace_s: 0.5\n"), &c);
  EXPECT_EQ(c.listen, "127.0.0.1:0");
  EXPECT_EQ(c.queue_size, 32u);
  EXPECT_DOUBLE_EQ(c.shutdown_grace_s, 0.5);
  EXPECT_NO_THROW(ValidateConfig(&c));
}

// live_cameras.no_imu: a car without IMU boots into the odometry model
// (LiveSource.no_imu); anything but true or false is refused by name.
TEST(ServerConfig, LiveCamerasNoImu) {
  const ScopedTempDir dir("config");
  const std::string cameras = "live_cameras:\n  stereo_pipeline: videotestsrc\n  left_camera_info: " +
                              WriteTemp(dir, "l.yaml", "image_width: 1\n").string() + "\n  right_camera_info: " +
                              WriteTemp(dir, "r.yaml", "image_width: 1\n").string() + "\n";
  ServerConfig c;
  ApplyYamlConfig(WriteTemp(dir, "default.yaml", cameras), &c);
  ASSERT_TRUE(c.live_cameras);
  EXPECT_FALSE(BootCamerasRequest(*c.live_cameras).live().no_imu());
  ApplyYamlConfig(WriteTemp(dir, "no_imu.yaml", cameras + "  no_imu: true\n"), &c);
  EXPECT_TRUE(BootCamerasRequest(*c.live_cameras).live().no_imu());
  const std::string e = ErrorOf([&] { ApplyYamlConfig(WriteTemp(dir, "bad.yaml", cameras + "  no_imu: yes\n"), &c); });
  EXPECT_NE(e.find("live_cameras.no_imu: expected true or false, got 'yes'"), std::string::npos) << e;
}

TEST(ServerConfig, UnknownKeyNamesFileLineAndKey) {
  const ScopedTempDir dir("config");
  ServerConfig c;
  const auto path = WriteTemp(dir, "bad_key.yaml", "listen: 127.0.0.1:0\nqueue_sise: 3\n");
  const std::string e = ErrorOf([&] { ApplyYamlConfig(path, &c); });
  EXPECT_NE(e.find("bad_key.yaml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("queue_sise"), std::string::npos) << e;
}

// Found by fuzz_server_config (2026-11-27): a key that is not a name (an
// explicit `?` key left empty, a list or a map as a key) threw yaml-cpp's
// TypedBadConversion out of ApplyYamlConfig. The fuzzer's reproducers are in
// fuzz/corpus/server_config/; each parses or throws ConfigError.
TEST(ServerConfig, AKeyThatIsNotANameIsAConfigErrorNamingTheLine) {
  const ScopedTempDir dir("config");
  for (const auto& [name, text, kind] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"empty_key.yaml", "# settings\n?\n: 1\n", ""},  // the fuzzer's input (yaml-cpp reads a map there)
           {"list_key.yaml", "listen: 127.0.0.1:0\n[a, b]: 2\n", "sequence"},
           {"map_key.yaml", "{a: 1}: 2\n", "map"}}) {
    ServerConfig c;
    const std::string e = ErrorOf([&] { ApplyYamlConfig(WriteTemp(dir, name, text), &c); });
    EXPECT_NE(e.find(name + ":"), std::string::npos) << e;
    EXPECT_NE(e.find("a key must be a name, got a " + kind), std::string::npos) << e;
  }
  for (const auto& entry : fs::directory_iterator(std::string(LOCAID_SOURCE_DIR) + "/fuzz/corpus/server_config")) {
    ServerConfig c;
    try {
      ApplyYamlConfig(entry.path(), &c);
      ValidateConfig(&c);
    } catch (const ConfigError&) {
    } catch (const std::exception& e) {
      ADD_FAILURE() << entry.path() << ": " << e.what();
    }
  }
}

TEST(ServerConfig, WrongTypeAndRangeAreReported) {
  const ScopedTempDir dir("config");
  ServerConfig c;
  std::string e = ErrorOf([&] { ApplyYamlConfig(WriteTemp(dir, "type.yaml", "queue_size: many\n"), &c); });
  EXPECT_NE(e.find("queue_size"), std::string::npos) << e;
  ServerConfig bad;
  bad.listen = "localhost";
  e = ErrorOf([&] { ValidateConfig(&bad); });
  EXPECT_NE(e.find("listen"), std::string::npos) << e;
  ServerConfig tls;
  tls.tls_cert_file = "/nonexistent/cert.pem";
  e = ErrorOf([&] { ValidateConfig(&tls); });
  EXPECT_NE(e.find("tls_key_file"), std::string::npos) << e;
  tls.tls_key_file = "/nonexistent/key.pem";
  e = ErrorOf([&] { ValidateConfig(&tls); });
  EXPECT_NE(e.find("/nonexistent/cert.pem"), std::string::npos) << e;
  ServerConfig q;
  q.queue_size = 0;
  e = ErrorOf([&] { ValidateConfig(&q); });
  EXPECT_NE(e.find("queue_size"), std::string::npos) << e;
}

TEST(ServerConfig, ListenPortOverflowIsAConfigErrorNamingListen) {
  ServerConfig c;
  c.listen = "127.0.0.1:99999999999999999999";
  std::string e;
  try {
    ValidateConfig(&c);
  } catch (const ConfigError& err) {
    e = err.what();
  }  // any other exception type (std::out_of_range) fails the test by escaping
  EXPECT_NE(e.find("listen"), std::string::npos) << e;
  EXPECT_NE(e.find("99999999999999999999"), std::string::npos) << e;
  EXPECT_NE(e.find("out of range"), std::string::npos) << e;
  c.listen = "127.0.0.1:65536";
  e = ErrorOf([&] { ValidateConfig(&c); });
  EXPECT_NE(e.find("'65536'"), std::string::npos) << e;
  c.listen = "127.0.0.1:80x";
  e = ErrorOf([&] { ValidateConfig(&c); });
  EXPECT_NE(e.find("not a number"), std::string::npos) << e;
  c.listen = "127.0.0.1:65535";
  EXPECT_EQ(ParseListenPort(c.listen), 65535);
}

TEST(ServerConfig, EveryNumericYamlFieldReportsFieldValueAndReason) {
  const ScopedTempDir dir("config");
  struct Case {
    std::string yaml, value, reason;
  };
  const std::vector<Case> size_cases = {
      {"99999999999999999999999", "99999999999999999999999", "out of range"},
      {"-3", "-3", "negative"},
      {"12abc", "12abc", "not a non-negative integer"},
      {"1.5", "1.5", "not a non-negative integer"},
  };
  const std::vector<std::string> size_fields = {"max_receive_mb", "history_size", "max_history_size",
                                                "queue_size",     "max_queue_size", "max_sessions",
                                                "max_subscribers_per_session", "synthetic_default_frames",
                                                "malloc_arena_max"};
  int n = 0;
  for (const auto& field : size_fields) {
    for (const auto& k : size_cases) {
      ServerConfig c;
      const auto path = WriteTemp(dir, "num" + std::to_string(n++) + ".yaml", "listen: 127.0.0.1:0\n" + field + ": " + k.yaml + "\n");
      const std::string e = ErrorOf([&] { ApplyYamlConfig(path, &c); });
      EXPECT_NE(e.find(":2: key '" + field + "'"), std::string::npos) << e;
      EXPECT_NE(e.find("'" + k.value + "'"), std::string::npos) << e;
      EXPECT_NE(e.find(k.reason), std::string::npos) << e;
    }
  }
  const std::vector<Case> real_cases = {
      {"1e999", "1e999", "out of the range"},
      {"fast", "fast", "not a number"},
      {".nan", ".nan", "not a number"},
  };
  for (const std::string field : {"keepalive_time_s", "keepalive_timeout_s", "shutdown_grace_s"}) {
    for (const auto& k : real_cases) {
      ServerConfig c;
      const auto path = WriteTemp(dir, "real" + std::to_string(n++) + ".yaml", field + ": " + k.yaml + "\n");
      const std::string e = ErrorOf([&] { ApplyYamlConfig(path, &c); });
      EXPECT_NE(e.find(":1: key '" + field + "'"), std::string::npos) << e;
      EXPECT_NE(e.find("'" + k.value + "'"), std::string::npos) << e;
      EXPECT_NE(e.find(k.reason), std::string::npos) << e;
    }
  }
  ServerConfig ok;
  ApplyYamlConfig(WriteTemp(dir, "num_ok.yaml", "max_sessions: 3\nkeepalive_time_s: 2.5e1\nqueue_size: +7\n"), &ok);
  EXPECT_EQ(ok.max_sessions, 3u);
  EXPECT_DOUBLE_EQ(ok.keepalive_time_s, 25.0);
  EXPECT_EQ(ok.queue_size, 7u);
  EXPECT_EQ(ParseSizeField("queue_size", "18446744073709551615"), static_cast<size_t>(18446744073709551615ull));
  const std::string e = ErrorOf([] { ParseSizeField("queue_size", "18446744073709551616"); });
  EXPECT_EQ(e.rfind("queue_size: value '18446744073709551616' is out of range", 0), 0u) << e;
}

TEST(ServerConfig, TokenFileIsRead) {
  const ScopedTempDir dir("config");
  ServerConfig c;
  c.token_file = WriteTemp(dir, "token.txt", "s3cret\n").string();
  ValidateConfig(&c);
  EXPECT_EQ(c.token, "s3cret");
}

// malloc_arena_max: a YAML key with a range; the environment's own bound
// (glibc already applied it) is never overridden, and 0 leaves glibc alone.
TEST(ServerConfig, MallocArenaMaxIsBoundedAndTheEnvironmentWins) {
  const ScopedTempDir dir("config");
  ServerConfig c;
  EXPECT_EQ(c.malloc_arena_max, 2u);
  ApplyYamlConfig(WriteTemp(dir, "arenas.yaml", "malloc_arena_max: 0\n"), &c);
  EXPECT_EQ(c.malloc_arena_max, 0u);
  EXPECT_NO_THROW(ValidateConfig(&c));
  c.malloc_arena_max = kMaxMallocArenas + 1;
  const std::string e = ErrorOf([&] { ValidateConfig(&c); });
  EXPECT_NE(e.find("malloc_arena_max: must be 0 (glibc's default) or in [1, 1024], got 1025"), std::string::npos) << e;

  using Source = MallocArenaPolicy::Source;
  EXPECT_EQ(ChooseMallocArenaPolicy(2, nullptr, nullptr).source, Source::kConfig);
  EXPECT_EQ(ChooseMallocArenaPolicy(2, nullptr, nullptr).arena_max, 2u);
  EXPECT_EQ(ChooseMallocArenaPolicy(0, nullptr, nullptr).source, Source::kGlibcDefault);
  EXPECT_EQ(ChooseMallocArenaPolicy(2, "8", nullptr).source, Source::kEnvironment);
  EXPECT_EQ(ChooseMallocArenaPolicy(0, "1", nullptr).source, Source::kEnvironment);
  EXPECT_EQ(ChooseMallocArenaPolicy(2, "", nullptr).source, Source::kConfig);  // set but empty: not a bound
  EXPECT_EQ(ChooseMallocArenaPolicy(2, nullptr, "glibc.malloc.check=0:glibc.malloc.arena_max=4").source,
            Source::kEnvironment);
  EXPECT_EQ(ChooseMallocArenaPolicy(2, nullptr, "glibc.malloc.tcache_count=0").source, Source::kConfig);
}

}  // namespace
}  // namespace locaid::server
