// WsServer: a Foxglove WebSocket protocol server (subprotocol
// foxglove.websocket.v1) on Boost.Beast, for a fixed table of channels.
//
// What it speaks: on connect, serverInfo (name, no capabilities, sessionId)
// and one advertise of every channel; it handles subscribe / unsubscribe and
// sends subscribed messages as binary messageData (opcode 1, uint32
// subscription id, uint64 timestamp in ns, payload; little endian). Client
// publishing, parameters and services are not offered (a client that tries
// gets a status message). SetSessionId() sends a new serverInfo to every
// client, which is how a viewer learns that the data now comes from another
// session; channels and subscriptions stay.
//
// Threads: Run() runs the network on the calling thread until Stop(); every
// other method may be called from any thread (they post to the server's
// strand, where all its work runs one job at a time). RunReady() runs the
// ready handlers (the posted publish and the writes it starts, but also any
// accept or read that is ready) on the calling thread at once. The network
// thread is still woken by the post and may take some of that work; the
// strand keeps it one job at a time. A message so need not wait for that
// wake-up (on a busy or virtual machine 0.2 ms on average, several ms at
// worst).
// Each client has a bounded queue of outgoing messages: when a message
// arrives and the queue is full, the oldest queued messageData is dropped
// and counted, so a slow client never stalls the producer or other clients.
// serverInfo/advertise/status are never dropped; the first drop sends the
// client a warning status ("Send buffer limit reached").
//
// Delay: every messageData frame carries the time its content reached the
// caller (Publish's `since`; the bridge passes the moment the gRPC pose
// arrived). When the frame's last byte has been handed to the client's
// socket, the difference goes into a histogram (10 us bins up to 100 ms,
// 80 KB, fixed); stats() reports its percentiles. That is the delay the
// bridge adds, as docs/benchmarks.md measures it.
#pragma once

#include "output/channels.hpp"

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::foxglove {

// The channel table and the messages published on it are output/'s (shared
// with MCAP recording).
using output::ChannelSpec;
using output::OutMessage;

class Connection;

struct WsServerOptions {
  std::string host = "127.0.0.1";  // loopback by default: the bridge has no authentication
  uint16_t port = 8765;            // 0: the OS picks one (see WsServer::port())
  std::string name = "locaid-foxglove";
  size_t max_queued_messages = 2000;  // per client
  // SO_SNDBUF of each client's socket (0: the OS default, which Linux grows
  // to megabytes). Smaller keeps a slow viewer closer to live: what it cannot
  // take waits in the bridge's queue, where the oldest is dropped, instead
  // of in the kernel.
  int socket_send_buffer_bytes = 0;
  // One line per event (connect, subscribe, disconnect with drop count).
  std::function<void(const std::string&)> log = [](const std::string&) {};
};

struct WsServerStats {
  uint64_t clients_connected = 0;  // since start
  uint64_t messages_sent = 0;      // messageData frames written, all clients
  uint64_t messages_dropped = 0;   // messageData dropped from full queues, all clients
  // Publish -> written to the socket, over every messageData frame sent
  // (histogram bins of 10 us: each figure is its bin's upper edge; 100 ms
  // stands for "100 ms or more").
  double delay_p50_ms = 0;
  double delay_p99_ms = 0;
  double delay_max_ms = 0;
};

class WsServer {
 public:
  // Binds and listens; throws std::runtime_error naming the address when
  // that fails (port in use, bad address).
  WsServer(WsServerOptions options, std::vector<ChannelSpec> channels);
  ~WsServer();
  WsServer(const WsServer&) = delete;
  WsServer& operator=(const WsServer&) = delete;

  uint16_t port() const;
  // Serves clients on this thread; returns after Stop() once every
  // connection is closed (close handshakes are bounded by a 2 s timeout).
  void Run();
  // Closes the listener and every connection (sending a close frame).
  void Stop();
  // Runs the network work that is ready (e.g. what Publish just queued: the
  // socket writes) on the calling thread, and returns without waiting.
  void RunReady();

  // Sends serverInfo with this sessionId to every client (and to later ones).
  void SetSessionId(std::string session_id);
  // Queues messages (OutMessage::topic indexes the channel table) for each
  // client subscribed to their channel, in order. Never blocks on a client.
  // `since`: when their content reached the caller (the start of the delay
  // stats() reports). One call per pose: the network thread wakes once and
  // writes them all.
  void Publish(std::vector<OutMessage> messages,
               std::chrono::steady_clock::time_point since = std::chrono::steady_clock::now());

  WsServerStats stats() const;

 private:
  struct Impl;
  friend class Connection;  // one client's state (ws_server.cpp)
  std::unique_ptr<Impl> impl_;
};

// Base64 (RFC 4648, with padding), as the protocol wants binary schemas.
std::string Base64(std::string_view bytes);

}  // namespace locaid::foxglove
