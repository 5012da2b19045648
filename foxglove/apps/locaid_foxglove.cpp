// locaid-foxglove: a Foxglove WebSocket bridge. Streams a session's fused
// poses from locaid-server (gRPC) and serves them to Foxglove / Lichtblick
// as foxglove.websocket.v1 on --listen (loopback by default).
//
//   locaid-foxglove --server 127.0.0.1:50051 [--token-file F] [--tls-ca F]
//                   [--listen 127.0.0.1:8765] [--session ID] [--lag S]
//
// Threads (all started and joined here): the WebSocket server's network
// thread, the session follower (gRPC) on its own thread, and main, which
// waits for SIGTERM/SIGINT and then stops both. Exit status: 0 after a
// signal, 1 when the WebSocket port cannot be opened, 2 for bad flags.
#include "connection/connection.hpp"
#include "connection/session_follower.hpp"
#include "output/channels.hpp"
#include "foxglove/ws_server.hpp"

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>

#include <pthread.h>

#include <cctype>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>

namespace fx = locaid::foxglove;

namespace {

std::mutex g_log_mu;

// One line per event on stderr.
void Log(const std::string& line) {
  std::lock_guard lock(g_log_mu);
  std::cerr << "locaid-foxglove: " << line << std::endl;
}

// "--listen": an IPv4 address or "localhost", ':' and a port 0-65535
// (0: the OS picks one; the start-up line says which).
struct ListenAddress {
  std::string host;
  uint16_t port = 0;
};
std::string ParseListen(const std::string& text, ListenAddress* out) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) return "expected HOST:PORT, e.g. 127.0.0.1:8765";
  std::string host = text.substr(0, colon), port = text.substr(colon + 1);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty()) return "the host before ':' is empty";
  if (host == "localhost") host = "127.0.0.1";
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535) {
    return "port '" + port + "' is not a number in [0, 65535]";
  }
  out->host = host;
  out->port = static_cast<uint16_t>(std::stoi(port));
  return "";
}


}  // namespace

int main(int argc, char** argv) {
  std::string server, token_file, tls_ca, listen = "127.0.0.1:8765", session;
  size_t queue = 2000;
  int send_buffer = 0;
  double lag_s = 0;
  CLI::App app{"locaid-foxglove: serves a locaid session live to Foxglove / Lichtblick (foxglove.websocket.v1)"};
  app.add_option("--server", server, "locaid-server address: host:port or unix:PATH")->required();
  app.add_option("--token-file", token_file, "file holding the server's bearer token")->check(CLI::ExistingFile);
  app.add_option("--tls-ca", tls_ca, "PEM file of the CA (or self-signed cert) to trust; enables TLS")
      ->check(CLI::ExistingFile);
  app.add_option("--listen", listen, "WebSocket address HOST:PORT (no authentication: keep it on loopback)")
      ->capture_default_str();
  app.add_option("--session", session, "session id to serve (default: follow the newest STARTING/RUNNING session)");
  app.add_option("--lag", lag_s,
                 "show the smoothed track: each pose given everything up to S seconds (sensor time) later, "
                 "S seconds behind the session (0 = the causal poses; docs/api.md \"Lagged stream\")")
      ->check(CLI::Range(0.0, 30.0));
  app.add_option("--queue", queue, "messages queued per WebSocket client before the oldest are dropped")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--send-buffer", send_buffer,
                 "kernel send buffer per WebSocket client, bytes (default: the OS's); smaller keeps slow viewers "
                 "closer to live")
      ->check(CLI::Range(4096, 64 << 20));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the precise message; every usage error exits with 2.
    return app.exit(e) == 0 ? 0 : 2;
  }

  ListenAddress address;
  if (const std::string why = ParseListen(listen, &address); !why.empty()) {
    std::cerr << "--listen '" << listen << "': " << why << "\nRun with --help for more information.\n";
    return 2;
  }
  locaid::connection::FollowerOptions follow;
  try {
    locaid::connection::Connection connection;
    connection.server = server;
    connection.token_file = token_file;
    connection.tls_ca = tls_ca;
    locaid::connection::ResolveToken(connection);
    follow.token = connection.token;
    follow.channel = locaid::connection::MakeChannel(connection);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
  follow.session = session;
  follow.smoothing_lag_s = lag_s;
  follow.log = Log;

  // Signals are taken by sigwait on main; every thread started below
  // inherits the mask, so none of them is interrupted by one.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::unique_ptr<fx::WsServer> ws;
  try {
    fx::WsServerOptions ws_options;
    ws_options.host = address.host;
    ws_options.port = address.port;
    ws_options.max_queued_messages = queue;
    ws_options.socket_send_buffer_bytes = send_buffer;
    ws_options.log = Log;
    ws = std::make_unique<fx::WsServer>(ws_options, locaid::output::Channels());
  } catch (const std::exception& e) {
    Log(e.what());
    return 1;
  }
  std::ostringstream lagged;
  if (lag_s > 0) lagged << ", smoothed poses " << lag_s << " s behind";
  Log("listening on ws://" + address.host + ":" + std::to_string(ws->port()) + " (foxglove.websocket.v1), server " +
      server + (session.empty() ? ", following the newest session" : ", session " + session) + lagged.str());

  locaid::output::PoseConverter converter;  // follower thread only
  locaid::connection::SessionFollower follower(
      follow,
      [&](const std::string& id) {
        converter.Reset();
        ws->SetSessionId(id);
      },
      [&](const locaid::v1::PoseUpdate& pose) {
        const auto received = std::chrono::steady_clock::now();  // the bridge's delay starts here
        ws->Publish(converter.Convert(pose), received);
        ws->RunReady();  // start the writes from this thread (the network thread may be slower to wake)
      });

  std::thread ws_thread([&] { ws->Run(); });
  std::thread follower_thread([&] { follower.Run(); });

  int signal = 0;
  sigwait(&signals, &signal);
  Log(std::string("stopping on ") + (signal == SIGTERM ? "SIGTERM" : "SIGINT"));
  follower.Stop();
  ws->Stop();
  follower_thread.join();
  ws_thread.join();
  const fx::WsServerStats stats = ws->stats();
  std::ostringstream delay;  // only when there is something to report
  if (stats.messages_sent > 0) {
    delay << std::fixed << std::setprecision(2) << "; delay from gRPC pose to socket p50 " << stats.delay_p50_ms
          << " ms, p99 " << stats.delay_p99_ms << " ms, max " << stats.delay_max_ms << " ms";
  }
  Log("stopped (" + std::to_string(stats.clients_connected) + " clients served, " +
      std::to_string(stats.messages_sent) + " messages sent, " + std::to_string(stats.messages_dropped) +
      " dropped" + delay.str() + ")");
  return 0;
}
