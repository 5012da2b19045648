#include "server/config.hpp"

#include <yaml-cpp/yaml.h>

#include <fstream>
#include <functional>
#include <map>
#include <sstream>

namespace locaid::server {
namespace {

std::string ReadFirstLine(const std::string& path, const std::string& field) {
  std::ifstream in(path);
  if (!in) throw ConfigError(field + ": cannot read '" + path + "'");
  std::string line;
  std::getline(in, line);
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  if (line.empty()) throw ConfigError(field + ": '" + path + "' has an empty first line");
  return line;
}

void CheckReadable(const std::string& path, const std::string& field) {
  std::ifstream in(path);
  if (!in) throw ConfigError(field + ": cannot read '" + path + "'");
}

}  // namespace

void ApplyYamlConfig(const std::filesystem::path& file, ServerConfig* c) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw ConfigError(file.string() + ": " + e.what());
  }
  if (root.IsNull()) return;
  if (!root.IsMap()) throw ConfigError(file.string() + ": expected a map of settings");
  using Setter = std::function<void(const YAML::Node&)>;
  auto str = [](std::string* v) -> Setter { return [v](const YAML::Node& n) { *v = n.as<std::string>(); }; };
  auto size = [](size_t* v) -> Setter {
    return [v](const YAML::Node& n) {
      const long long x = n.as<long long>();
      if (x < 0) throw ConfigError("must be >= 0, got " + std::to_string(x));
      *v = static_cast<size_t>(x);
    };
  };
  auto real = [](double* v) -> Setter { return [v](const YAML::Node& n) { *v = n.as<double>(); }; };
  const std::map<std::string, Setter> setters = {
      {"listen", str(&c->listen)},
      {"tls_cert_file", str(&c->tls_cert_file)},
      {"tls_key_file", str(&c->tls_key_file)},
      {"token", str(&c->token)},
      {"token_file", str(&c->token_file)},
      {"max_receive_mb", size(&c->max_receive_mb)},
      {"history_size", size(&c->history_size)},
      {"max_history_size", size(&c->max_history_size)},
      {"queue_size", size(&c->queue_size)},
      {"max_queue_size", size(&c->max_queue_size)},
      {"max_sessions", size(&c->max_sessions)},
      {"max_subscribers_per_session", size(&c->max_subscribers_per_session)},
      {"work_dir", str(&c->work_dir)},
      {"default_scenario", str(&c->default_scenario)},
      {"default_vo_method", str(&c->default_vo_method)},
      {"synthetic_default_frames", size(&c->synthetic_default_frames)},
      {"keepalive_time_s", real(&c->keepalive_time_s)},
      {"keepalive_timeout_s", real(&c->keepalive_timeout_s)},
      {"shutdown_grace_s", real(&c->shutdown_grace_s)},
      {"port_file", str(&c->port_file)},
  };
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    const std::string where = file.string() + ":" + std::to_string(kv.first.Mark().line + 1) + ": key '" + key + "'";
    auto it = setters.find(key);
    if (it == setters.end()) {
      std::ostringstream known;
      for (const auto& s : setters) known << " " << s.first;
      throw ConfigError(where + ": unknown (known:" + known.str() + ")");
    }
    try {
      it->second(kv.second);
    } catch (const YAML::Exception& e) {
      throw ConfigError(where + ": wrong type (" + e.msg + ")");
    } catch (const ConfigError& e) {
      throw ConfigError(where + ": " + e.what());
    }
  }
}

void ValidateConfig(ServerConfig* c) {
  const auto colon = c->listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == c->listen.size()) {
    throw ConfigError("listen: expected host:port, got '" + c->listen + "'");
  }
  const std::string port = c->listen.substr(colon + 1);
  if (port.find_first_not_of("0123456789") != std::string::npos || std::stol(port) > 65535) {
    throw ConfigError("listen: port '" + port + "' is not a number in [0, 65535]");
  }
  if (c->tls_cert_file.empty() != c->tls_key_file.empty()) {
    throw ConfigError("tls_cert_file and tls_key_file must be given together");
  }
  if (!c->tls_cert_file.empty()) {
    CheckReadable(c->tls_cert_file, "tls_cert_file");
    CheckReadable(c->tls_key_file, "tls_key_file");
  }
  if (!c->token.empty() && !c->token_file.empty()) throw ConfigError("token and token_file are exclusive");
  if (!c->token_file.empty()) c->token = ReadFirstLine(c->token_file, "token_file");
  if (c->max_receive_mb < 1 || c->max_receive_mb > 1024) {
    throw ConfigError("max_receive_mb: must be in [1, 1024], got " + std::to_string(c->max_receive_mb));
  }
  if (c->history_size > c->max_history_size) {
    throw ConfigError("history_size: " + std::to_string(c->history_size) + " exceeds max_history_size " +
                      std::to_string(c->max_history_size));
  }
  if (c->queue_size < 1 || c->queue_size > c->max_queue_size) {
    throw ConfigError("queue_size: must be in [1, max_queue_size=" + std::to_string(c->max_queue_size) +
                      "], got " + std::to_string(c->queue_size));
  }
  if (c->max_sessions < 1) throw ConfigError("max_sessions: must be >= 1");
  if (c->max_subscribers_per_session < 1) throw ConfigError("max_subscribers_per_session: must be >= 1");
  if (!(c->keepalive_time_s >= 1)) throw ConfigError("keepalive_time_s: must be >= 1");
  if (!(c->keepalive_timeout_s >= 1)) throw ConfigError("keepalive_timeout_s: must be >= 1");
  if (!(c->shutdown_grace_s >= 0 && c->shutdown_grace_s <= 60)) {
    throw ConfigError("shutdown_grace_s: must be in [0, 60]");
  }
  if (c->synthetic_default_frames < 2) throw ConfigError("synthetic_default_frames: must be >= 2");
}

}  // namespace locaid::server
