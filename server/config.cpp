#include "server/config.hpp"

#include "connection/host_port.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

namespace locaid::server {
namespace {

std::string Num(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

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

namespace {
std::string Prefix(const std::string& field) { return field.empty() ? std::string() : field + ": "; }
}  // namespace

size_t ParseSizeField(const std::string& field_in, const std::string& text) {
  const std::string field = Prefix(field_in);
  const std::string quoted = "'" + text + "'";
  if (text.empty()) throw ConfigError(field + "value " + quoted + " is empty, expected a non-negative integer");
  if (text[0] == '-') throw ConfigError(field + "value " + quoted + " is negative, expected an integer >= 0");
  unsigned long long x = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data() + (text[0] == '+' ? 1 : 0), end, x);
  if (ec == std::errc::result_out_of_range || (ec == std::errc() && x > std::numeric_limits<size_t>::max())) {
    throw ConfigError(field + "value " + quoted + " is out of range, expected an integer in [0, " +
                      std::to_string(std::numeric_limits<size_t>::max()) + "]");
  }
  if (ec != std::errc() || ptr != end) {
    throw ConfigError(field + "value " + quoted + " is not a non-negative integer");
  }
  return static_cast<size_t>(x);
}

double ParseRealField(const std::string& field_in, const std::string& text) {
  const std::string field = Prefix(field_in);
  const std::string quoted = "'" + text + "'";
  if (text.empty()) throw ConfigError(field + "value " + quoted + " is empty, expected a number");
  double x = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data() + (text[0] == '+' ? 1 : 0), end, x);
  if (ec == std::errc::result_out_of_range) {
    throw ConfigError(field + "value " + quoted + " is out of the range of a double");
  }
  if (ec != std::errc() || ptr != end) throw ConfigError(field + "value " + quoted + " is not a number");
  if (!std::isfinite(x)) throw ConfigError(field + "value " + quoted + " is not finite");
  return x;
}

int ParseListenPort(const std::string& listen) {
  const auto colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == listen.size()) {
    throw ConfigError("listen: expected host:port, got '" + listen + "'");
  }
  const std::string port = listen.substr(colon + 1);
  unsigned long x = 0;
  const char* end = port.data() + port.size();
  const auto [ptr, ec] = std::from_chars(port.data(), end, x);
  if (ec == std::errc::result_out_of_range || (ec == std::errc() && ptr == end && x > 65535)) {
    throw ConfigError("listen: port '" + port + "' in '" + listen + "' is out of range, expected [0, 65535]");
  }
  if (ec != std::errc() || ptr != end) {
    throw ConfigError("listen: port '" + port + "' in '" + listen + "' is not a number in [0, 65535]");
  }
  return static_cast<int>(x);
}

void CheckListenUnixPath(const std::string& path) {
  const std::string quoted = "'" + path + "'";
  if (path.empty()) throw ConfigError("listen_unix: path is empty (leave the setting out to listen on TCP only)");
  if (path.find('\0') != std::string::npos) throw ConfigError("listen_unix: path contains a NUL byte");
  if (path.rfind("unix:", 0) == 0) {
    throw ConfigError("listen_unix: give the socket path without the 'unix:' prefix, got " + quoted);
  }
  if (path.size() > kMaxUnixPathBytes) {
    throw ConfigError("listen_unix: path " + quoted + " is " + std::to_string(path.size()) +
                      " bytes, a Unix-domain socket path must be shorter than " +
                      std::to_string(kMaxUnixPathBytes + 1) + " bytes (sun_path)");
  }
  if (path.back() == '/') throw ConfigError("listen_unix: path " + quoted + " ends in '/', expected a file name");
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const std::filesystem::path dir = parent.empty() ? std::filesystem::path(".") : parent;
  std::error_code ec;
  const auto status = std::filesystem::status(dir, ec);
  if (!std::filesystem::exists(status)) {
    throw ConfigError("listen_unix: directory '" + dir.string() + "' of " + quoted + " does not exist");
  }
  if (!std::filesystem::is_directory(status)) {
    throw ConfigError("listen_unix: '" + dir.string() + "' (parent of " + quoted + ") is not a directory");
  }
}

// `live_cameras:`, a map of the BootCameras keys (unknown ones refused).
template <typename Real>
BootCameras ParseBootCameras(const YAML::Node& n, const Real& real) {
  if (!n.IsMap()) throw ConfigError("expected a map (left_pipeline, right_pipeline or stereo_pipeline, "
                                    "left_camera_info, right_camera_info, gpsd, ...)");
  BootCameras b;
  const std::map<std::string, std::function<void(const YAML::Node&)>> keys = {
      {"left_pipeline", [&](const YAML::Node& v) { b.left_pipeline = v.as<std::string>(); }},
      {"right_pipeline", [&](const YAML::Node& v) { b.right_pipeline = v.as<std::string>(); }},
      {"stereo_pipeline", [&](const YAML::Node& v) { b.stereo_pipeline = v.as<std::string>(); }},
      {"left_camera_info", [&](const YAML::Node& v) { b.left_camera_info = v.as<std::string>(); }},
      {"right_camera_info", [&](const YAML::Node& v) { b.right_camera_info = v.as<std::string>(); }},
      {"gpsd", [&](const YAML::Node& v) { b.gpsd = v.as<std::string>(); }},
      {"scenario", [&](const YAML::Node& v) { b.scenario = v.as<std::string>(); }},
      {"pair_tolerance_ms", [&](const YAML::Node& v) { real(&b.pair_tolerance_ms)(v); }},
      {"stall_timeout_s", [&](const YAML::Node& v) { real(&b.stall_timeout_s)(v); }},
      {"no_imu",
       [&](const YAML::Node& v) {
         const std::string s = v.IsScalar() ? v.Scalar() : "";
         if (s != "true" && s != "false") throw ConfigError("expected true or false, got '" + s + "'");
         b.no_imu = s == "true";
       }},
  };
  for (const auto& kv : n) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "?";
    const auto it = keys.find(key);
    if (it == keys.end()) {
      std::string known;
      for (const auto& k : keys) known += " " + k.first;
      throw ConfigError("live_cameras." + key + ": unknown (known:" + known + ")");
    }
    try {
      it->second(kv.second);
    } catch (const ConfigError& e) {
      throw ConfigError("live_cameras." + key + ": " + e.what());
    }
  }
  if (b.left_camera_info.empty() || b.right_camera_info.empty()) {
    throw ConfigError("live_cameras: left_camera_info and right_camera_info are required (camera_info YAML files)");
  }
  if (!b.gpsd.empty()) {
    try {
      connection::SplitHostPort(b.gpsd, "live_cameras.gpsd");
    } catch (const std::invalid_argument& e) {
      throw ConfigError(e.what());
    }
  }
  const bool two = !b.left_pipeline.empty() || !b.right_pipeline.empty();
  if (two == !b.stereo_pipeline.empty()) {
    throw ConfigError("live_cameras: give left_pipeline and right_pipeline, or stereo_pipeline (not both)");
  }
  if (two && (b.left_pipeline.empty() || b.right_pipeline.empty())) {
    throw ConfigError(std::string("live_cameras.") + (b.left_pipeline.empty() ? "left" : "right") +
                      "_pipeline: missing");
  }
  return b;
}

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
  // Numbers are parsed from the scalar text so that overflow, sign and junk
  // get a message naming the value and the reason (yaml-cpp only says
  // "bad conversion"). The caller prefixes file, line and key.
  auto scalar = [](const YAML::Node& n) -> std::string {
    if (!n.IsScalar()) {
      throw ConfigError("expected a number, got a " +
                        std::string(n.IsMap() ? "map" : n.IsSequence() ? "sequence" : "null value"));
    }
    return n.Scalar();
  };
  auto size = [scalar](size_t* v) -> Setter {
    return [v, scalar](const YAML::Node& n) { *v = ParseSizeField("", scalar(n)); };
  };
  auto real = [scalar](double* v) -> Setter {
    return [v, scalar](const YAML::Node& n) { *v = ParseRealField("", scalar(n)); };
  };
  const std::map<std::string, Setter> setters = {
      {"listen", str(&c->listen)},
      // An empty value is an error here (not "TCP only"): leave the key out for that.
      {"listen_unix",
       [c](const YAML::Node& n) {
         c->listen_unix = n.as<std::string>();
         if (c->listen_unix.empty()) throw ConfigError("empty path (leave the key out to listen on TCP only)");
       }},
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
      {"behind_threshold_s", real(&c->behind_threshold_s)},
      {"max_cpu_cores", real(&c->max_cpu_cores)},
      {"session_cpu_cores_prior", real(&c->session_cpu_cores_prior)},
      {"max_subscribers_per_session", size(&c->max_subscribers_per_session)},
      {"work_dir", str(&c->work_dir)},
      {"default_scenario", str(&c->default_scenario)},
      {"default_vo_method", str(&c->default_vo_method)},
      {"synthetic_default_frames", size(&c->synthetic_default_frames)},
      {"max_synthetic_frames", size(&c->max_synthetic_frames)},
      {"max_concurrent_renders", size(&c->max_concurrent_renders)},
      {"max_ended_sessions", size(&c->max_ended_sessions)},
      {"ended_session_ttl_s", real(&c->ended_session_ttl_s)},
      {"keepalive_time_s", real(&c->keepalive_time_s)},
      {"keepalive_timeout_s", real(&c->keepalive_timeout_s)},
      {"shutdown_grace_s", real(&c->shutdown_grace_s)},
      {"malloc_arena_max", size(&c->malloc_arena_max)},
      {"port_file", str(&c->port_file)},
      {"metrics_listen", str(&c->metrics_listen)},
      {"live_cameras", [c, real](const YAML::Node& n) { c->live_cameras = ParseBootCameras(n, real); }},
  };
  for (const auto& kv : root) {
    if (!kv.first.IsScalar()) {  // `? [a]`, `? {a: 1}` or an empty `?` as a key
      throw ConfigError(file.string() + ":" + std::to_string(kv.first.Mark().line + 1) + ": a key must be a name, got a " +
                        (kv.first.IsMap() ? "map" : kv.first.IsSequence() ? "sequence" : "null value"));
    }
    const std::string key = kv.first.Scalar();
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
  ParseListenPort(c->listen);
  if (!c->listen_unix.empty()) CheckListenUnixPath(c->listen_unix);
  if (!c->metrics_listen.empty()) {
    try {
      ParseListenPort(c->metrics_listen);
    } catch (const ConfigError& e) {
      throw ConfigError(std::string("metrics_listen: ") + e.what());
    }
  }
  if (c->tls_cert_file.empty() != c->tls_key_file.empty()) {
    throw ConfigError("tls_cert_file and tls_key_file must be given together");
  }
  if (!c->tls_cert_file.empty()) {
    CheckReadable(c->tls_cert_file, "tls_cert_file");
    CheckReadable(c->tls_key_file, "tls_key_file");
  }
  if (!c->token.empty() && !c->token_file.empty()) throw ConfigError("token and token_file are exclusive");
  if (!c->token_file.empty()) {
    // Resolved here once: the file's token replaces the path, so validating
    // the same config again (LocalizationServer does) sees one token source.
    c->token = ReadFirstLine(c->token_file, "token_file");
    c->token_file.clear();
  }
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
  if (!(c->behind_threshold_s > 0 && c->behind_threshold_s <= 60)) {
    throw ConfigError("behind_threshold_s: must be in (0, 60], got " + Num(c->behind_threshold_s));
  }
  if (!(c->max_cpu_cores >= 0 && c->max_cpu_cores <= 4096)) {
    throw ConfigError("max_cpu_cores: must be 0 (off) or in (0, 4096], got " + Num(c->max_cpu_cores));
  }
  if (!(c->session_cpu_cores_prior > 0 && c->session_cpu_cores_prior <= 64)) {
    throw ConfigError("session_cpu_cores_prior: must be in (0, 64], got " + Num(c->session_cpu_cores_prior));
  }
  if (c->max_subscribers_per_session < 1) throw ConfigError("max_subscribers_per_session: must be >= 1");
  if (!(c->keepalive_time_s >= 1)) throw ConfigError("keepalive_time_s: must be >= 1");
  if (!(c->keepalive_timeout_s >= 1)) throw ConfigError("keepalive_timeout_s: must be >= 1");
  if (!(c->shutdown_grace_s >= 0 && c->shutdown_grace_s <= 60)) {
    throw ConfigError("shutdown_grace_s: must be in [0, 60]");
  }
  if (c->malloc_arena_max > kMaxMallocArenas) {
    throw ConfigError("malloc_arena_max: must be 0 (glibc's default) or in [1, " + std::to_string(kMaxMallocArenas) +
                      "], got " + std::to_string(c->malloc_arena_max));
  }
  if (c->max_ended_sessions > 100000) {
    throw ConfigError("max_ended_sessions: must be in [0, 100000], got " + std::to_string(c->max_ended_sessions));
  }
  if (!(c->ended_session_ttl_s >= 0 && c->ended_session_ttl_s <= 30 * 86400)) {
    throw ConfigError("ended_session_ttl_s: must be in [0, 2592000] (30 days)");
  }
  if (c->max_concurrent_renders < 1 || c->max_concurrent_renders > 64) {
    throw ConfigError("max_concurrent_renders: must be in [1, 64], got " + std::to_string(c->max_concurrent_renders));
  }
  if (c->max_synthetic_frames < 2 || c->max_synthetic_frames > 100000) {
    throw ConfigError("max_synthetic_frames: must be in [2, 100000], got " + std::to_string(c->max_synthetic_frames));
  }
  if (c->synthetic_default_frames < 2 || c->synthetic_default_frames > c->max_synthetic_frames) {
    throw ConfigError("synthetic_default_frames: must be in [2, max_synthetic_frames=" +
                      std::to_string(c->max_synthetic_frames) + "], got " + std::to_string(c->synthetic_default_frames));
  }
}

}  // namespace locaid::server
