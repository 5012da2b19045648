// The server that hosts the gRPC service: listeners (TCP, Unix socket), TLS,
// health, reflection, metrics, and the orderly shutdown.
#pragma once

#include "server/config.hpp"
#include "server/metrics.hpp"
#include "server/service.hpp"

#include <grpcpp/grpcpp.h>

#include <memory>
#include <mutex>
#include <string>

namespace locaid::server {

// What is at a `listen_unix` path before the server binds it.
enum class UnixPathState {
  kAbsent,       // nothing there
  kStaleSocket,  // a socket file nobody listens on (left by a crashed server)
};
// Looks at `path` without changing it: kAbsent or kStaleSocket, else throws
// std::runtime_error "listen_unix 'PATH': REASON" when a process accepts
// connections on the socket, or the path is a regular file, directory, ...
// (which the server must not delete), or cannot be examined.
UnixPathState InspectUnixSocketPath(const std::string& path);

// Owns the grpc::Server, health and reflection.
class LocalizationServer {
 public:
  // Builds and starts the server; throws ConfigError / std::runtime_error
  // (e.g. "listen 127.0.0.1:80: cannot bind", "listen_unix '/run/x.sock':
  // exists and is a regular file, not a socket; not replacing it").
  LocalizationServer(ServerConfig config, pipeline::EstimatorMaker make_estimator = pipeline::MakeLocalizer);
  ~LocalizationServer();
  int port() const { return port_; }
  // "unix:PATH" when config.listen_unix is set, else empty.
  std::string unix_target() const { return config_.listen_unix.empty() ? "" : "unix:" + config_.listen_unix; }
  // True when a stale socket file was at listen_unix and was replaced.
  bool replaced_stale_socket() const { return replaced_stale_socket_; }
  // Writes the bound port to config.port_file (nothing when unset), through a
  // temporary file renamed into place so a reader never sees it half written.
  // locaid-server calls it after its startup line: a script (or test) that
  // waits for the file finds that line already in the log. Throws
  // std::runtime_error naming the file when it cannot be written.
  void WritePortFile() const;
  // StartSession from inside the server (ServerConfig::live_cameras).
  grpc::Status StartSession(const locaid::v1::StartSessionRequest& req, std::string* id);
  // Port of the /metrics endpoint (0: metrics_listen not set).
  int metrics_port() const { return metrics_ ? metrics_->port() : 0; }
  // Health NOT_SERVING, sessions stopped, streams ended with UNAVAILABLE,
  // grpc Shutdown with deadline now + shutdown_grace_s, sessions joined.
  void Shutdown();
  void Wait();

 private:
  ServerConfig config_;
  std::unique_ptr<LocalizationService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<MetricsExporter> metrics_;  // after service_: destroyed first
  int port_ = 0;
  bool replaced_stale_socket_ = false;
  std::once_flag shutdown_once_;
};

}  // namespace locaid::server
