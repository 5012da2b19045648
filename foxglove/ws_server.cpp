#include "foxglove/ws_server.hpp"

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <map>
#include <set>
#include <stdexcept>

namespace locaid::foxglove {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using nlohmann::json;

constexpr const char* kSubprotocol = "foxglove.websocket.v1";
constexpr uint8_t kMessageDataOpcode = 1;
constexpr auto kUpgradeTimeout = std::chrono::seconds(5);

// True when the client's Sec-WebSocket-Protocol list offers the protocol.
bool OffersSubprotocol(std::string_view header) {
  while (!header.empty()) {
    const size_t comma = header.find(',');
    std::string_view item = header.substr(0, comma);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (item == kSubprotocol) return true;
    if (comma == std::string_view::npos) break;
    header.remove_prefix(comma + 1);
  }
  return false;
}

std::string MessageDataHeader(uint32_t subscription_id, uint64_t timestamp_ns) {
  std::string h(13, '\0');
  h[0] = static_cast<char>(kMessageDataOpcode);
  for (int i = 0; i < 4; ++i) h[static_cast<size_t>(1 + i)] = static_cast<char>((subscription_id >> (8 * i)) & 0xff);
  for (int i = 0; i < 8; ++i) h[static_cast<size_t>(5 + i)] = static_cast<char>((timestamp_ns >> (8 * i)) & 0xff);
  return h;
}

std::string StatusJson(int level, const std::string& message) {
  return json{{"op", "status"}, {"level", level}, {"message", message}}.dump();
}

// One queued frame: a JSON text message, or a messageData header plus the
// payload every subscribed client shares.
struct Outgoing {
  bool text = false;
  std::string head;
  std::shared_ptr<const std::string> payload;
  std::chrono::steady_clock::time_point since{};  // messageData: when Publish got it
};

// Counts of delays in 10 us bins, the last bin holding 100 ms and more.
// Written on the strand, read by stats() from any thread.
class DelayHistogram {
 public:
  void Add(std::chrono::steady_clock::duration d) {
    const auto bin = std::clamp<int64_t>(std::chrono::duration_cast<std::chrono::microseconds>(d).count() / 10, 0,
                                         static_cast<int64_t>(kBins) - 1);
    bins_[static_cast<size_t>(bin)].fetch_add(1, std::memory_order_relaxed);
  }
  // Upper edges, in ms, of the bins holding each quantile of `qs` (0 when
  // empty), from one read of the bins.
  template <size_t N>
  std::array<double, N> QuantilesMs(const std::array<double, N>& qs) const {
    std::array<uint64_t, kBins> counts;
    uint64_t total = 0;
    for (size_t i = 0; i < kBins; ++i) total += counts[i] = bins_[i].load(std::memory_order_relaxed);
    std::array<double, N> out{};
    if (total == 0) return out;
    for (size_t k = 0; k < N; ++k) {
      const uint64_t rank = std::max<uint64_t>(static_cast<uint64_t>(std::ceil(qs[k] * static_cast<double>(total))), 1);
      uint64_t seen = 0;
      out[k] = static_cast<double>(kBins) * 0.01;
      for (size_t i = 0; i < kBins; ++i) {
        seen += counts[i];
        if (seen >= rank) {
          out[k] = static_cast<double>(i + 1) * 0.01;
          break;
        }
      }
    }
    return out;
  }

 private:
  static constexpr size_t kBins = 10'000;
  std::array<std::atomic<uint64_t>, kBins> bins_{};
};

}  // namespace

class Connection;

struct WsServer::Impl {
  WsServerOptions options;
  std::vector<ChannelSpec> channels;
  std::string advertise;  // the advertise message, built once
  net::io_context ioc;  // run by Run()'s thread, and briefly by RunReady()'s callers
  // Every socket, timer and posted job of the server runs on this one
  // strand, so whichever thread runs the io_context, they run one at a time.
  net::strand<net::io_context::executor_type> strand = net::make_strand(ioc);
  tcp::acceptor acceptor{strand};
  net::executor_work_guard<net::io_context::executor_type> work = net::make_work_guard(ioc);
  std::set<std::shared_ptr<Connection>> connections;  // strand only
  std::string session_id;                             // strand only
  bool stopping = false;                              // strand only
  uint16_t port = 0;
  std::atomic<uint64_t> clients_connected{0}, sent{0}, dropped{0};
  DelayHistogram delays;

  // sessionId is left out until a session is known (it is optional).
  std::string ServerInfo() const {
    json info = {{"op", "serverInfo"}, {"name", options.name}, {"capabilities", json::array()}, {"metadata", json::object()}};
    if (!session_id.empty()) info["sessionId"] = session_id;
    return info.dump();
  }
  void Accept();
};

namespace {

json AdvertiseJson(const std::vector<ChannelSpec>& channels) {
  json list = json::array();
  for (size_t id = 0; id < channels.size(); ++id) {
    const ChannelSpec& c = channels[id];
    // Text schemas go as they are; binary ones (a FileDescriptorSet) in base64.
    const bool binary = c.schema_encoding == "protobuf";
    list.push_back({{"id", id},
                    {"topic", c.topic},
                    {"encoding", c.encoding},
                    {"schemaName", c.schema_name},
                    {"schemaEncoding", c.schema_encoding},
                    {"schema", binary ? Base64(c.schema) : c.schema}});
  }
  return {{"op", "advertise"}, {"channels", std::move(list)}};
}

}  // namespace

// One client: HTTP upgrade, then a read loop for its requests and a write
// loop draining its bounded queue. Lives on the server's strand only.
class Connection : public std::enable_shared_from_this<Connection> {
 public:
  Connection(tcp::socket socket, WsServer::Impl& server) : ws_(std::move(socket)), server_(server) {
    beast::error_code ec;
    const auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    peer_ = ec ? "?" : ep.address().to_string() + ":" + std::to_string(ep.port());
  }

  void Start() {
    beast::get_lowest_layer(ws_).expires_after(kUpgradeTimeout);
    http::async_read(beast::get_lowest_layer(ws_), buffer_, upgrade_,
                     [self = shared_from_this()](beast::error_code ec, size_t) { self->OnUpgradeRead(ec); });
  }

  void Deliver(size_t channel, uint64_t timestamp_ns, const std::shared_ptr<const std::string>& payload,
               std::chrono::steady_clock::time_point since) {
    for (const auto& [subscription, subscribed_channel] : subscriptions_) {
      if (subscribed_channel == channel) Send({false, MessageDataHeader(subscription, timestamp_ns), payload, since});
    }
  }

  void SendText(std::string text) { Send({true, std::move(text), nullptr}); }

  void Close() {
    if (!open_) {
      beast::error_code ignored;
      beast::get_lowest_layer(ws_).socket().close(ignored);
      return;
    }
    if (closing_) return;
    closing_ = true;
    ws_.async_close(websocket::close_code::going_away,
                    [self = shared_from_this()](beast::error_code ec) { self->Finish(ec ? ec.message() : "closed"); });
  }

  bool open() const { return open_; }

 private:
  void OnUpgradeRead(beast::error_code ec) {
    if (ec) return Finish("no WebSocket upgrade: " + ec.message());
    if (!websocket::is_upgrade(upgrade_) ||
        !OffersSubprotocol(std::string(upgrade_[http::field::sec_websocket_protocol]))) {
      return Reject();
    }
    beast::get_lowest_layer(ws_).expires_never();  // the websocket timeouts take over
    websocket::stream_base::timeout timeouts{};
    timeouts.handshake_timeout = std::chrono::seconds(2);
    timeouts.idle_timeout = std::chrono::seconds(30);
    timeouts.keep_alive_pings = true;  // a vanished peer is noticed and dropped
    ws_.set_option(timeouts);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::sec_websocket_protocol, kSubprotocol); }));
    ws_.async_accept(upgrade_, [self = shared_from_this()](beast::error_code e) { self->OnAccept(e); });
  }

  // Not a foxglove.websocket.v1 client: 400 with the reason, then close.
  void Reject() {
    rejection_ = http::response<http::string_body>(http::status::bad_request, upgrade_.version());
    rejection_.set(http::field::content_type, "text/plain");
    rejection_.body() = std::string("this is a Foxglove WebSocket server: connect with subprotocol ") + kSubprotocol + "\n";
    rejection_.keep_alive(false);
    rejection_.prepare_payload();
    http::async_write(beast::get_lowest_layer(ws_), rejection_, [self = shared_from_this()](beast::error_code, size_t) {
      beast::error_code ignored;
      beast::get_lowest_layer(self->ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
      self->Finish("refused: no foxglove.websocket.v1 subprotocol offered");
    });
  }

  void OnAccept(beast::error_code ec) {
    if (ec) return Finish("handshake failed: " + ec.message());
    open_ = true;
    ++server_.clients_connected;
    server_.options.log("client " + peer_ + " connected");
    if (server_.stopping) return Close();
    SendText(server_.ServerInfo());
    SendText(server_.advertise);
    ReadNext();
  }

  void ReadNext() {
    ws_.async_read(read_buffer_, [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec) return Finish(ec == websocket::error::closed ? "closed by the client" : ec.message());
    if (ws_.got_text()) {
      HandleRequest(beast::buffers_to_string(read_buffer_.data()));
    } else {
      SendText(StatusJson(2, "binary client messages are not supported (no clientPublish capability)"));
    }
    read_buffer_.consume(read_buffer_.size());
    ReadNext();
  }

  void HandleRequest(const std::string& text) {
    const json request = json::parse(text, nullptr, false);
    if (!request.is_object() || !request.contains("op") || !request["op"].is_string()) {
      return SendText(StatusJson(2, "expected a JSON object with an \"op\" string"));
    }
    const std::string op = request["op"];
    try {
      if (op == "subscribe") {
        for (const json& s : request.at("subscriptions")) Subscribe(s.at("id"), s.at("channelId"));
      } else if (op == "unsubscribe") {
        for (const json& id : request.at("subscriptionIds")) Unsubscribe(id);
      } else {
        SendText(StatusJson(1, "op '" + op + "' is not supported by this server"));
      }
    } catch (const json::exception& e) {
      SendText(StatusJson(2, "malformed '" + op + "': " + e.what()));
    }
  }

  void Subscribe(uint32_t id, size_t channel) {
    if (channel >= server_.channels.size()) {
      return SendText(StatusJson(2, "subscribe: unknown channel " + std::to_string(channel)));
    }
    if (!subscriptions_.emplace(id, channel).second) {
      return SendText(StatusJson(2, "subscribe: subscription id " + std::to_string(id) + " is already in use"));
    }
    server_.options.log("client " + peer_ + " subscribed to " + server_.channels[channel].topic);
  }

  void Unsubscribe(uint32_t id) {
    if (subscriptions_.erase(id) == 0) {
      SendText(StatusJson(1, "unsubscribe: no subscription " + std::to_string(id)));
    }
  }

  // Queues a frame; when the queue is full the oldest queued messageData
  // makes room (control messages are never dropped). The first drop is
  // announced with a warning status; Foxglove and Lichtblick show this very
  // text with a hint that the server is dropping messages for the viewer.
  void Send(Outgoing m) {
    if (!open_ || closing_) return;
    bool first_drop = false;
    if (queue_.size() >= server_.options.max_queued_messages) {
      for (auto it = queue_.begin(); it != queue_.end(); ++it) {
        if (it->text) continue;
        queue_.erase(it);
        first_drop = dropped_++ == 0;
        ++server_.dropped;
        break;
      }
    }
    queue_.push_back(std::move(m));
    if (first_drop) queue_.push_back({true, StatusJson(1, "Send buffer limit reached"), nullptr});
    WriteNext();
  }

  // The frame being written lives in in_flight_, outside the queue, so
  // dropping from the queue never touches buffers the socket is using.
  void WriteNext() {
    if (writing_ || queue_.empty() || closing_) return;
    writing_ = true;
    in_flight_ = std::move(queue_.front());
    queue_.pop_front();
    ws_.text(in_flight_.text);
    auto done = [self = shared_from_this()](beast::error_code ec, size_t) { self->OnWrite(ec); };
    if (in_flight_.text) {
      ws_.async_write(net::buffer(in_flight_.head), std::move(done));
    } else {
      const std::array<net::const_buffer, 2> frame{net::buffer(in_flight_.head), net::buffer(*in_flight_.payload)};
      ws_.async_write(frame, std::move(done));
    }
  }

  void OnWrite(beast::error_code ec) {
    writing_ = false;
    if (ec) return Finish("write failed: " + ec.message());
    if (!in_flight_.text) {
      ++sent_;
      ++server_.sent;
      server_.delays.Add(std::chrono::steady_clock::now() - in_flight_.since);
    }
    in_flight_ = {};
    WriteNext();
  }

  // Forgets the connection (the handler's shared_ptr keeps it alive until it returns).
  void Finish(const std::string& why) {
    if (finished_) return;
    finished_ = true;
    if (open_) {
      server_.options.log("client " + peer_ + " disconnected (" + why + "; sent " + std::to_string(sent_) +
                          " messages, dropped " + std::to_string(dropped_) + ")");
    } else {
      server_.options.log("connection from " + peer_ + " " + why);
    }
    open_ = false;
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
    server_.connections.erase(shared_from_this());
  }

  websocket::stream<beast::tcp_stream> ws_;
  WsServer::Impl& server_;
  std::string peer_;
  beast::flat_buffer buffer_, read_buffer_;
  http::request<http::string_body> upgrade_;
  http::response<http::string_body> rejection_;
  std::deque<Outgoing> queue_;
  Outgoing in_flight_;
  std::map<uint32_t, size_t> subscriptions_;  // subscription id -> channel
  bool open_ = false, closing_ = false, writing_ = false, finished_ = false;
  uint64_t sent_ = 0, dropped_ = 0;
};

void WsServer::Impl::Accept() {
  acceptor.async_accept(strand, [this](beast::error_code ec, tcp::socket socket) {
    if (ec) {
      if (!stopping) options.log("accept failed: " + ec.message());
      if (stopping || ec == net::error::operation_aborted) return;
    } else {
      if (options.socket_send_buffer_bytes > 0) {
        beast::error_code ignored;  // best effort: the OS may round or cap it
        socket.set_option(net::socket_base::send_buffer_size(options.socket_send_buffer_bytes), ignored);
      }
      auto connection = std::make_shared<Connection>(std::move(socket), *this);
      connections.insert(connection);
      connection->Start();
    }
    Accept();
  });
}

WsServer::WsServer(WsServerOptions options, std::vector<ChannelSpec> channels) : impl_(std::make_unique<Impl>()) {
  impl_->options = std::move(options);
  impl_->channels = std::move(channels);
  impl_->advertise = AdvertiseJson(impl_->channels).dump();
  const std::string where = impl_->options.host + ":" + std::to_string(impl_->options.port);
  try {
    const tcp::endpoint endpoint(net::ip::make_address(impl_->options.host), impl_->options.port);
    impl_->acceptor.open(endpoint.protocol());
    impl_->acceptor.set_option(net::socket_base::reuse_address(true));
    impl_->acceptor.bind(endpoint);
    impl_->acceptor.listen();
    impl_->port = impl_->acceptor.local_endpoint().port();
  } catch (const boost::system::system_error& e) {
    throw std::runtime_error("cannot listen on " + where + ": " + e.code().message());
  }
  impl_->Accept();
}

WsServer::~WsServer() = default;

uint16_t WsServer::port() const { return impl_->port; }

void WsServer::Run() { impl_->ioc.run(); }

void WsServer::RunReady() { impl_->ioc.poll(); }

void WsServer::Stop() {
  net::post(impl_->strand, [impl = impl_.get()] {
    if (impl->stopping) return;
    impl->stopping = true;
    beast::error_code ignored;
    impl->acceptor.close(ignored);
    // Copy: closing may remove connections from the set.
    const auto connections = impl->connections;
    for (const auto& c : connections) c->Close();
    impl->work.reset();  // Run() returns once the last connection is gone
  });
}

void WsServer::SetSessionId(std::string session_id) {
  net::post(impl_->strand, [impl = impl_.get(), id = std::move(session_id)] {
    impl->session_id = id;
    const std::string info = impl->ServerInfo();
    for (const auto& c : impl->connections) {
      if (c->open()) c->SendText(info);
    }
  });
}

void WsServer::Publish(std::vector<OutMessage> messages, std::chrono::steady_clock::time_point since) {
  struct Shared {
    size_t channel;
    uint64_t timestamp_ns;
    std::shared_ptr<const std::string> payload;  // one copy, whatever the number of clients
  };
  std::vector<Shared> shared;
  shared.reserve(messages.size());
  for (OutMessage& m : messages) {
    shared.push_back({static_cast<size_t>(m.topic), m.log_time_ns, std::make_shared<const std::string>(std::move(m.data))});
  }
  net::post(impl_->strand, [impl = impl_.get(), shared = std::move(shared), since] {
    for (const Shared& m : shared) {
      for (const auto& c : impl->connections) c->Deliver(m.channel, m.timestamp_ns, m.payload, since);
    }
  });
}

WsServerStats WsServer::stats() const {
  const auto q = impl_->delays.QuantilesMs(std::array<double, 3>{0.5, 0.99, 1.0});
  return {impl_->clients_connected.load(), impl_->sent.load(), impl_->dropped.load(), q[0], q[1], q[2]};
}

std::string Base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (static_cast<uint8_t>(bytes[i]) << 16) | (static_cast<uint8_t>(bytes[i + 1]) << 8) |
                       static_cast<uint8_t>(bytes[i + 2]);
    for (int shift : {18, 12, 6, 0}) out.push_back(kAlphabet[(v >> shift) & 0x3f]);
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const uint32_t v = (static_cast<uint8_t>(bytes[i]) << 16) | (two ? static_cast<uint8_t>(bytes[i + 1]) << 8 : 0);
    out.push_back(kAlphabet[(v >> 18) & 0x3f]);
    out.push_back(kAlphabet[(v >> 12) & 0x3f]);
    out.push_back(two ? kAlphabet[(v >> 6) & 0x3f] : '=');
    out.push_back('=');
  }
  return out;
}

}  // namespace locaid::foxglove
