// Server configuration: YAML + validation give precise errors.
#include "server/config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace locaid::server {
namespace {

std::filesystem::path WriteTemp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::path(::testing::TempDir()) / name;
  std::ofstream(path) << text;
  return path;
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ServerConfig, YamlOverridesDefaultsAndValidates) {
  ServerConfig c;
  ApplyYamlConfig(WriteTemp("ok.yaml", "listen: 127.0.0.1:0\nqueue_size: 32\nshutdown_grace_s: 0.5\n"), &c);
  EXPECT_EQ(c.listen, "127.0.0.1:0");
  EXPECT_EQ(c.queue_size, 32u);
  EXPECT_DOUBLE_EQ(c.shutdown_grace_s, 0.5);
  EXPECT_NO_THROW(ValidateConfig(&c));
}

TEST(ServerConfig, UnknownKeyNamesFileLineAndKey) {
  ServerConfig c;
  const auto path = WriteTemp("bad_key.yaml", "listen: 127.0.0.1:0\nqueue_sise: 3\n");
  const std::string e = ErrorOf([&] { ApplyYamlConfig(path, &c); });
  EXPECT_NE(e.find("bad_key.yaml:2"), std::string::npos) << e;
  EXPECT_NE(e.find("queue_sise"), std::string::npos) << e;
}

TEST(ServerConfig, WrongTypeAndRangeAreReported) {
  ServerConfig c;
  std::string e = ErrorOf([&] { ApplyYamlConfig(WriteTemp("type.yaml", "queue_size: many\n"), &c); });
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

TEST(ServerConfig, TokenFileIsRead) {
  ServerConfig c;
  c.token_file = WriteTemp("token.txt", "s3cret\n").string();
  ValidateConfig(&c);
  EXPECT_EQ(c.token, "s3cret");
}

}  // namespace
}  // namespace locaid::server
