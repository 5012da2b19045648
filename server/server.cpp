// Building the gRPC server: listeners (TCP, Unix socket), TLS, health,
// reflection, metrics, and the orderly shutdown.
#include "server/server.hpp"

#include "server/status.hpp"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>

#include <netdb.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

namespace locaid::server {

UnixPathState InspectUnixSocketPath(const std::string& path) {
  const std::string where = "listen_unix '" + path + "': ";
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return UnixPathState::kAbsent;
    throw std::runtime_error(where + "cannot examine the path: " + std::strerror(errno));
  }
  if (!S_ISSOCK(st.st_mode)) {
    const char* kind = S_ISREG(st.st_mode)   ? "a regular file"
                       : S_ISDIR(st.st_mode) ? "a directory"
                       : S_ISLNK(st.st_mode) ? "a symbolic link"
                                             : "not a socket";
    throw std::runtime_error(where + "exists and is " + kind + ", not a socket; not replacing it");
  }
  // A socket file: stale when connecting is refused. Non-blocking, so a live
  // server with a full accept backlog answers EAGAIN instead of blocking us.
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error(where + "socket(): " + std::strerror(errno));
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), std::min(path.size(), sizeof(addr.sun_path) - 1));
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  const int err = rc == 0 ? 0 : errno;
  ::close(fd);
  if (err == ECONNREFUSED) return UnixPathState::kStaleSocket;
  if (err == ENOENT) return UnixPathState::kAbsent;  // removed meanwhile
  if (err == 0 || err == EAGAIN || err == EINPROGRESS) {
    throw std::runtime_error(where + "another process is listening on this socket (another locaid-server?); "
                             "stop it or choose another path");
  }
  throw std::runtime_error(where + "cannot tell whether the existing socket is in use: connect(): " +
                           std::strerror(err));
}

namespace {

// Why binding `listen` ("host:port", "[v6]:port") failed, found by binding it
// ourselves (gRPC only logs the reason): "address already in use (...)" etc.
std::string DescribeTcpBindFailure(const std::string& listen) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos) return "cannot bind (not host:port)";
  std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  if (const int rc = ::getaddrinfo(host.empty() ? nullptr : host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    return std::string("cannot bind: cannot resolve the address: ") + ::gai_strerror(rc);
  }
  int err = 0;
  for (addrinfo* a = found; a != nullptr && err == 0; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));  // as gRPC does: TIME_WAIT is no conflict
    if (::bind(fd, a->ai_addr, a->ai_addrlen) != 0) err = errno;
    ::close(fd);
  }
  ::freeaddrinfo(found);
  if (err == EADDRINUSE) {
    return "cannot bind: address already in use (another locaid-server or another program listens on this "
           "port; stop it or choose another port)";
  }
  if (err != 0) return std::string("cannot bind: ") + std::strerror(err);
  return "cannot bind (see gRPC's message above)";
}

}  // namespace

LocalizationServer::LocalizationServer(ServerConfig config, pipeline::EstimatorMaker make_estimator)
    : config_(std::move(config)) {
  ValidateConfig(&config_);
  service_ = std::make_unique<LocalizationService>(config_, std::move(make_estimator));
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (!config_.tls_cert_file.empty()) {
    auto read = [](const std::string& path) {
      std::ifstream in(path);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({read(config_.tls_key_file), read(config_.tls_cert_file)});
    creds = grpc::SslServerCredentials(ssl);
  } else {
    creds = grpc::InsecureServerCredentials();
  }
  builder.AddListeningPort(config_.listen, creds, &port_);
  int unix_port = 0;  // gRPC sets 1 once the socket is bound
  if (!config_.listen_unix.empty()) {
    // gRPC 1.51 itself unlinks a socket file before bind (any socket, even a
    // live one) and refuses (EADDRINUSE) anything else; the inspection above
    // it makes "live socket" and "not a socket" clear errors, and removes a
    // stale socket here so the behaviour does not depend on gRPC's.
    if (InspectUnixSocketPath(config_.listen_unix) == UnixPathState::kStaleSocket) {
      if (::unlink(config_.listen_unix.c_str()) != 0 && errno != ENOENT) {
        throw std::runtime_error("listen_unix '" + config_.listen_unix +
                                 "': cannot remove the stale socket file: " + std::strerror(errno));
      }
      replaced_stale_socket_ = true;
    }
    builder.AddListeningPort("unix:" + config_.listen_unix, creds, &unix_port);
  }
  builder.RegisterService(service_.get());
  builder.SetMaxReceiveMessageSize(static_cast<int>(config_.max_receive_mb * 1024 * 1024));
  // gRPC sets SO_REUSEPORT by default, so a second server would share a port
  // that one already serves, and clients would get either: refused instead.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, static_cast<int>(config_.keepalive_time_s * 1000));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, static_cast<int>(config_.keepalive_timeout_s * 1000));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 5000);
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) {
    if (port_ != 0 && !config_.listen_unix.empty() && unix_port == 0) {
      throw std::runtime_error("listen_unix '" + config_.listen_unix +
                               "': cannot bind (the directory is not writable, or see gRPC's message above)");
    }
    throw std::runtime_error("listen " + config_.listen + ": " + DescribeTcpBindFailure(config_.listen));
  }
  if (!config_.listen_unix.empty()) {
    // Owner and group may connect (connecting needs write permission on the
    // socket file); until this chmod the file has 0777 & ~umask. gRPC
    // removes the file again when the server shuts down (UnixSocketTest
    // checks it).
    if (::chmod(config_.listen_unix.c_str(), 0660) != 0) {
      const std::string reason = std::strerror(errno);
      server_->Shutdown(std::chrono::system_clock::now());
      throw std::runtime_error("listen_unix '" + config_.listen_unix + "': cannot make the socket file 0660: " +
                               reason);
    }
  }
  // Health answers for the server ("") and for the service by its full name.
  server_->GetHealthCheckService()->SetServingStatus(true);
  server_->GetHealthCheckService()->SetServingStatus(ServiceName(), true);
  if (!config_.metrics_listen.empty()) {
    LocalizationService* service = service_.get();
    metrics_ = std::make_unique<MetricsExporter>(config_.metrics_listen, [service] { return service->CollectMetrics(); });
  }
}

void LocalizationServer::WritePortFile() const {
  if (config_.port_file.empty()) return;
  const std::string tmp = config_.port_file + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << port_ << "\n";
    if (!out.flush()) throw std::runtime_error("--port-file " + tmp + ": cannot write: " + std::strerror(errno));
  }
  if (std::rename(tmp.c_str(), config_.port_file.c_str()) != 0)
    throw std::runtime_error("--port-file " + config_.port_file + ": cannot rename " + tmp + " to it: " +
                             std::strerror(errno));
}

LocalizationServer::~LocalizationServer() { Shutdown(); }

void LocalizationServer::Shutdown() {
  std::call_once(shutdown_once_, [this] {
    const auto t0 = std::chrono::steady_clock::now();
    auto ms = [&t0] {
      return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    };
    server_->GetHealthCheckService()->SetServingStatus(false);
    server_->GetHealthCheckService()->SetServingStatus(ServiceName(), false);
    metrics_.reset();  // its threads stop before the sessions go
    service_->BeginShutdown();
    // Every stream was just told to end with UNAVAILABLE; once all have
    // delivered that status nothing is left to wait for, so idle client
    // connections (which grpc::Server::Shutdown(deadline) would wait on for
    // the whole grace time) are cut at once.
    const auto grace = std::chrono::milliseconds(static_cast<int64_t>(config_.shutdown_grace_s * 1000));
    const bool streams_done = service_->WaitForStreams(std::chrono::steady_clock::now() + grace);
    server_->Shutdown(streams_done ? std::chrono::system_clock::now()
                                   : std::chrono::system_clock::now() + std::chrono::milliseconds(100));
    const double grpc_ms = ms();
    service_->JoinSessions();
    if (config_.log_shutdown) {
      std::fprintf(stderr, "locaid-server: shutdown: rpcs done after %.0f ms, sessions joined after %.0f ms\n",
                   grpc_ms, ms());
    }
  });
}

void LocalizationServer::Wait() { server_->Wait(); }


grpc::Status LocalizationServer::StartSession(const locaid::v1::StartSessionRequest& req, std::string* id) {
  return service_->StartLocal(req, id);
}

}  // namespace locaid::server
