// locaid-server: the gRPC localization service.
#include "server/boot_session.hpp"
#include "server/config.hpp"
#include "server/malloc_arenas.hpp"
#include "server/server.hpp"

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

#include <csignal>
#include <cstdio>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>

namespace {

using locaid::server::ServerConfig;

// What the command line gives: each flag fills the ServerConfig field it
// names; --config names a YAML file with any of them.
struct ServerFlags {
  ServerConfig given;
  std::string config_file;
};

void AddFlags(CLI::App& app, ServerFlags& f) {
  ServerConfig& cli = f.given;
  app.add_option("--config", f.config_file, "YAML file with any of the settings below (flags override it)")
      ->check(CLI::ExistingFile);
  app.add_option("--listen", cli.listen, "host:port to listen on (port 0: pick one)")->capture_default_str();
  app.add_option("--listen-unix", cli.listen_unix,
                 "also listen on a Unix-domain socket at this path (same TLS/token; file mode 0660; a stale "
                 "socket file is replaced, removed on clean shutdown); clients use unix:PATH");
  app.add_option("--tls-cert", cli.tls_cert_file, "PEM certificate chain (TLS when given with --tls-key)");
  app.add_option("--tls-key", cli.tls_key_file, "PEM private key");
  app.add_option("--token", cli.token, "require 'authorization: Bearer TOKEN' on every call");
  app.add_option("--token-file", cli.token_file, "read the token from the first line of this file");
  app.add_option("--max-receive-mb", cli.max_receive_mb, "largest accepted message, MiB")->capture_default_str();
  app.add_option("--history-size", cli.history_size, "default poses kept per session")->capture_default_str();
  app.add_option("--queue-size", cli.queue_size, "default per-subscriber queue, poses")->capture_default_str();
  app.add_option("--max-sessions", cli.max_sessions, "running sessions at once")->capture_default_str();
  app.add_option("--behind-threshold-s", cli.behind_threshold_s,
                 "a paced session more than this late is falling behind (stats, metrics, status)")
      ->capture_default_str();
  app.add_option("--max-cpu-cores", cli.max_cpu_cores,
                 "admit real-time sessions by measured CPU load, cores (0: off, only --max-sessions)")
      ->capture_default_str();
  app.add_option("--session-cpu-cores-prior", cli.session_cpu_cores_prior,
                 "CPU estimate of a real-time session before one has been measured, cores")
      ->capture_default_str();
  app.add_option("--work-dir", cli.work_dir, "where synthetic drives are rendered");
  app.add_option("--max-synthetic-frames", cli.max_synthetic_frames, "largest synthetic drive a session may ask for")
      ->capture_default_str();
  app.add_option("--max-ended-sessions", cli.max_ended_sessions,
                 "ended sessions kept for GetSession / history (oldest removed first)")
      ->capture_default_str();
  app.add_option("--ended-session-ttl-s", cli.ended_session_ttl_s, "ended sessions are removed this long after")
      ->capture_default_str();
  app.add_option("--max-concurrent-renders", cli.max_concurrent_renders,
                 "synthetic drives rendered at once (StartSession beyond: RESOURCE_EXHAUSTED)")
      ->capture_default_str();
  app.add_option("--default-scenario", cli.default_scenario, "GPS scenario when a session names none")
      ->capture_default_str();
  app.add_option("--default-vo", cli.default_vo_method, "VO method when a session names none")->capture_default_str();
  app.add_option("--shutdown-grace-s", cli.shutdown_grace_s, "streams still open this long after SIGTERM are cancelled")
      ->capture_default_str();
  app.add_option("--malloc-arena-max", cli.malloc_arena_max,
                 "at most this many glibc malloc arenas (0: glibc's default, 8 per core); keeps RSS level over "
                 "rounds of sessions and streams; MALLOC_ARENA_MAX in the environment wins")
      ->capture_default_str();
  app.add_option("--port-file", cli.port_file, "write the bound port to this file once listening (after the startup line)");
  app.add_option("--metrics-listen", cli.metrics_listen,
                 "serve Prometheus metrics on host:port (GET /metrics; off by default; no token)");
}

// The settings the server runs with: --config's file, then every flag given
// on the command line over it; validated. Throws with what is wrong.
ServerConfig ResolveConfig(const CLI::App& app, const ServerFlags& f) {
  ServerConfig config;
  if (!f.config_file.empty()) locaid::server::ApplyYamlConfig(f.config_file, &config);
  const ServerConfig& cli = f.given;
  // Flags given on the command line override the file.
  auto take = [&](const char* flag, auto member) {
    if (app.count(flag) > 0) config.*member = cli.*member;
  };
  take("--listen", &ServerConfig::listen);
  take("--listen-unix", &ServerConfig::listen_unix);
  if (app.count("--listen-unix") > 0) locaid::server::CheckListenUnixPath(config.listen_unix);  // rejects ""
  take("--tls-cert", &ServerConfig::tls_cert_file);
  take("--tls-key", &ServerConfig::tls_key_file);
  take("--token", &ServerConfig::token);
  take("--token-file", &ServerConfig::token_file);
  take("--max-receive-mb", &ServerConfig::max_receive_mb);
  take("--history-size", &ServerConfig::history_size);
  take("--queue-size", &ServerConfig::queue_size);
  take("--max-sessions", &ServerConfig::max_sessions);
  take("--behind-threshold-s", &ServerConfig::behind_threshold_s);
  take("--max-cpu-cores", &ServerConfig::max_cpu_cores);
  take("--session-cpu-cores-prior", &ServerConfig::session_cpu_cores_prior);
  take("--work-dir", &ServerConfig::work_dir);
  take("--max-synthetic-frames", &ServerConfig::max_synthetic_frames);
  take("--max-concurrent-renders", &ServerConfig::max_concurrent_renders);
  take("--max-ended-sessions", &ServerConfig::max_ended_sessions);
  take("--ended-session-ttl-s", &ServerConfig::ended_session_ttl_s);
  take("--default-scenario", &ServerConfig::default_scenario);
  take("--default-vo", &ServerConfig::default_vo_method);
  take("--shutdown-grace-s", &ServerConfig::shutdown_grace_s);
  take("--malloc-arena-max", &ServerConfig::malloc_arena_max);
  take("--port-file", &ServerConfig::port_file);
  take("--metrics-listen", &ServerConfig::metrics_listen);
  locaid::server::ValidateConfig(&config);
  config.log_shutdown = true;
  return config;
}

// The signals that stop the server.
sigset_t StopSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

int WaitForSignal() {
  const sigset_t set = StopSignals();
  int sig = 0;
  sigwait(&set, &sig);
  return sig;
}

std::string StartupLine(const ServerConfig& config, const locaid::server::LocalizationServer& server) {
  std::ostringstream line;
  line << "locaid-server listening on " << config.listen.substr(0, config.listen.rfind(':')) << ":" << server.port()
       << (config.listen_unix.empty() ? "" : " and " + server.unix_target() + " (mode 0660)")
       << (server.replaced_stale_socket() ? " (replaced a stale socket file)" : "")
       << (config.tls_cert_file.empty() ? "" : " (TLS)") << (config.token.empty() ? "" : " (token)")
       << (server.metrics_port() > 0 ? "; metrics on " + config.metrics_listen.substr(0, config.metrics_listen.rfind(':')) +
                                           ":" + std::to_string(server.metrics_port()) + "/metrics"
                                     : "");
  return line.str();
}

// Serves until SIGINT or SIGTERM, then shuts down: exit status 0, or 1 when
// the server cannot start or fails.
int RunServer(const ServerConfig& config) {
  // Before the server starts any thread: arenas made before it would stay.
  // Only the config's parsing ran so far, on this thread (main_arena).
  locaid::server::ApplyMallocArenaMax(config.malloc_arena_max);
  cv::setNumThreads(1);  // one pipeline thread per session; no nested pools
  try {
    locaid::server::LocalizationServer server(config);
    std::cout << StartupLine(config, server) << std::endl;
    server.WritePortFile();  // after the line: whoever waits for the file finds it in the log
    std::optional<locaid::server::BootSession> boot;
    if (config.live_cameras) {
      boot.emplace(
          *config.live_cameras,
          [&server](const locaid::v1::StartSessionRequest& req, std::string* id) { return server.StartSession(req, id); },
          [](const std::string& line) { std::cout << "locaid-server: " << line << std::endl; });
    }
    const int sig = WaitForSignal();
    std::cout << "locaid-server: signal " << sig << ", shutting down" << std::endl;
    boot.reset();  // stops retrying
    server.Shutdown();
  } catch (const std::exception& e) {
    std::cerr << "locaid-server: " << e.what() << "\n";
    return 1;
  }
  std::cout << "locaid-server: stopped" << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Block the signals in every thread; RunServer waits for them with sigwait.
  const sigset_t stop = StopSignals();
  pthread_sigmask(SIG_BLOCK, &stop, nullptr);
  // A peer that hangs up must cost a connection, never the process: libgps
  // writes to gpsd with plain write(2), so a gpsd that closes the socket
  // would otherwise kill the server with SIGPIPE (gRPC's own sockets use
  // MSG_NOSIGNAL). Writes then fail with EPIPE and are handled as errors.
  std::signal(SIGPIPE, SIG_IGN);

  CLI::App app{"locaid-server: stereo VO + GPS/IMU EKF localization over gRPC (health + reflection on)"};
  ServerFlags flags;
  AddFlags(app, flags);
  CLI11_PARSE(app, argc, argv);
  ServerConfig config;
  try {
    config = ResolveConfig(app, flags);
  } catch (const std::exception& e) {
    std::cerr << "locaid-server: config: " << e.what() << "\n";
    return 2;
  }
  return RunServer(config);
}
