// libFuzzer target: server config YAML (server/config.hpp).
// Contract: ApplyYamlConfig + ValidateConfig return or throw
// server::ConfigError (no yaml-cpp or std exception escapes). The file is read
// through a memfd path since the config API only takes a path.
#include "fuzz/fuzz_support.hpp"
#include "server/config.hpp"

#include <exception>
#include <typeinfo>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static locaid::fuzz::MemFile file;
  const std::filesystem::path& path = file.Write(locaid::fuzz::AsText(data, size));
  locaid::server::ServerConfig config;
  try {
    locaid::server::ApplyYamlConfig(path, &config);
    // Never read files named by fuzz input (token_file, TLS files).
    config.token_file.clear();
    config.tls_cert_file.clear();
    config.tls_key_file.clear();
    locaid::server::ValidateConfig(&config);
  } catch (const locaid::server::ConfigError&) {
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("config threw ") + typeid(e).name() + ": " + e.what());
  }
  return 0;
}
