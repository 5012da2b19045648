// WsServer in-process, with Beast WebSocket clients on loopback: subprotocol
// negotiation, serverInfo / advertise, subscribe and messageData framing, a
// new serverInfo on a session switch, and a client that stops reading
// losing its oldest messages without holding up another client.
#include "foxglove/ws_server.hpp"

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <thread>

namespace fx = locaid::foxglove;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using nlohmann::json;

namespace {

class TestClient {
 public:
  // Connects; `subprotocol` empty: offers none.
  TestClient(uint16_t port, const std::string& subprotocol) : ws_(ioc_) {
    ws_.next_layer().connect(net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
    if (!subprotocol.empty()) {
      ws_.set_option(websocket::stream_base::decorator(
          [subprotocol](websocket::request_type& req) { req.set(beast::http::field::sec_websocket_protocol, subprotocol); }));
    }
    ws_.handshake(response_, "127.0.0.1", "/");
  }
  const websocket::response_type& response() const { return response_; }
  json ReadJson() {
    const std::string text = Read();
    EXPECT_TRUE(ws_.got_text());
    return json::parse(text);
  }
  std::string Read() {
    beast::flat_buffer buffer;
    ws_.read(buffer);
    return beast::buffers_to_string(buffer.data());
  }
  void Send(const json& j) { ws_.write(net::buffer(j.dump())); }
  void Shutdown() {
    beast::error_code ignored;
    ws_.next_layer().shutdown(net::ip::tcp::socket::shutdown_both, ignored);
  }

 private:
  net::io_context ioc_;
  websocket::stream<net::ip::tcp::socket> ws_;
  websocket::response_type response_;
};

uint64_t ReadLe(const std::string& s, size_t offset, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(s[offset + static_cast<size_t>(i)]);
  return v;
}

class WsServerTest : public ::testing::Test {
 protected:
  void Start(size_t max_queued) {
    fx::WsServerOptions options;
    options.port = 0;
    options.max_queued_messages = max_queued;
    std::vector<fx::ChannelSpec> channels = {{"/a", "json", "A", "jsonschema", "{}"},
                                             {"/b", "protobuf", "B", "protobuf", std::string("\x01\x02\x03", 3)}};
    server_ = std::make_unique<fx::WsServer>(options, channels);
    thread_ = std::thread([this] { server_->Run(); });
  }
  void TearDown() override {
    if (!server_) return;
    server_->Stop();
    thread_.join();
  }
  // One message on channel `channel` (0 or 1 of the table above).
  void Publish(size_t channel, uint64_t timestamp_ns, std::string data,
               std::chrono::steady_clock::time_point since = std::chrono::steady_clock::now()) {
    std::vector<fx::OutMessage> one;
    one.push_back({static_cast<locaid::output::Topic>(channel), timestamp_ns, std::move(data)});
    server_->Publish(std::move(one), since);
  }
  // Publishes on channel 1 until the client's subscription shows (the
  // protocol has no acknowledgement); returns the first message it read.
  std::string PublishUntilReceived(TestClient& client) {
    std::atomic<bool> received{false};
    std::thread producer([&] {
      for (int i = 0; i < 500 && !received; ++i) {  // at most 5 s
        Publish(1, 42, "warm-up");
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    });
    const std::string first = client.Read();
    received = true;
    producer.join();
    return first;
  }

  std::unique_ptr<fx::WsServer> server_;
  std::thread thread_;
};

TEST_F(WsServerTest, RefusesAClientWithoutTheSubprotocol) {
  Start(16);
  EXPECT_THROW(TestClient(server_->port(), ""), beast::system_error);
  EXPECT_THROW(TestClient(server_->port(), "some.other.protocol"), beast::system_error);
}

TEST_F(WsServerTest, SpeaksFoxgloveWebsocketV1) {
  Start(16);
  TestClient client(server_->port(), "foxglove.websocket.v1");
  EXPECT_EQ(client.response()[beast::http::field::sec_websocket_protocol], "foxglove.websocket.v1");
  const json info = client.ReadJson();
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["capabilities"], json::array());
  EXPECT_FALSE(info.contains("sessionId"));  // no session yet
  const json advertise = client.ReadJson();
  ASSERT_EQ(advertise["op"], "advertise");
  ASSERT_EQ(advertise["channels"].size(), 2u);
  EXPECT_EQ(advertise["channels"][0]["schema"], "{}");
  EXPECT_EQ(advertise["channels"][1]["schema"], "AQID");  // base64 of the binary schema
  EXPECT_EQ(advertise["channels"][1]["schemaEncoding"], "protobuf");

  client.Send({{"op", "subscribe"}, {"subscriptions", {{{"id", 7}, {"channelId", 1}}}}});
  const std::string frame = PublishUntilReceived(client);
  ASSERT_EQ(frame.size(), 13u + 7u);
  EXPECT_EQ(frame[0], 1);                // messageData
  EXPECT_EQ(ReadLe(frame, 1, 4), 7u);    // subscription id
  EXPECT_EQ(ReadLe(frame, 5, 8), 42u);   // timestamp
  EXPECT_EQ(frame.substr(13), "warm-up");

  server_->SetSessionId("s123");
  // Messages already queued may come first; the new serverInfo follows.
  for (int i = 0; i < 1000; ++i) {
    const std::string next = client.Read();
    if (next.front() != '{') continue;
    const json j = json::parse(next);
    EXPECT_EQ(j["op"], "serverInfo");
    EXPECT_EQ(j["sessionId"], "s123");
    break;
  }
  client.Send({{"op", "subscribe"}, {"subscriptions", {{{"id", 8}, {"channelId", 99}}}}});
  for (int i = 0; i < 1000; ++i) {
    const std::string next = client.Read();
    if (next.front() != '{') continue;
    const json j = json::parse(next);
    EXPECT_EQ(j["op"], "status");
    EXPECT_EQ(j["level"], 2);
    EXPECT_NE(j["message"].get<std::string>().find("unknown channel 99"), std::string::npos) << j.dump();
    break;
  }
}

// The delay counts from Publish's `since`: content that waited 30 ms before
// Publish shows a delay of at least 30 ms once written, and content that
// waited 10 s lands in the last bin, reported as 100 ms ("100 ms or more").
TEST_F(WsServerTest, DelayIsCountedFromWhenTheContentArrived) {
  Start(16);
  TestClient client(server_->port(), "foxglove.websocket.v1");
  client.ReadJson();  // serverInfo
  client.ReadJson();  // advertise
  client.Send({{"op", "subscribe"}, {"subscriptions", {{{"id", 1}, {"channelId", 0}}}}});
  // Subscribing has no acknowledgement: publish until one arrives.
  std::atomic<bool> received{false};
  std::thread producer([&] {
    for (int i = 0; i < 500 && !received; ++i) {
      Publish(0, 1, "{}", std::chrono::steady_clock::now() - std::chrono::milliseconds(30));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  });
  client.Read();
  received = true;
  producer.join();
  // The server counts a frame when its write completes, which may be just
  // after the client has read it.
  for (int i = 0; i < 200 && server_->stats().messages_sent == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const fx::WsServerStats stats = server_->stats();
  ASSERT_GE(stats.messages_sent, 1u);
  EXPECT_GE(stats.delay_p50_ms, 30.0);
  EXPECT_GE(stats.delay_p99_ms, stats.delay_p50_ms);
  EXPECT_GE(stats.delay_max_ms, stats.delay_p99_ms);

  // A frame whose content arrived 10 s before Publish: the maximum becomes
  // the last bin's 100 ms, whatever the machine's speed.
  const uint64_t sent = stats.messages_sent;
  Publish(0, 2, "{}", std::chrono::steady_clock::now() - std::chrono::seconds(10));
  for (;;) {  // the frames published before it may come first
    const std::string m = client.Read();
    if (m.front() != '{' && ReadLe(m, 5, 8) == 2) break;
  }
  for (int i = 0; i < 200 && server_->stats().messages_sent <= sent; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const fx::WsServerStats late = server_->stats();
  ASSERT_GT(late.messages_sent, sent);
  EXPECT_DOUBLE_EQ(late.delay_max_ms, 100.0);
}

TEST_F(WsServerTest, AClientThatStopsReadingLosesItsOldestMessagesOnly) {
  Start(32);
  TestClient slow(server_->port(), "foxglove.websocket.v1"), fast(server_->port(), "foxglove.websocket.v1");
  for (TestClient* c : {&slow, &fast}) {
    c->ReadJson();  // serverInfo
    c->ReadJson();  // advertise
    c->Send({{"op", "subscribe"}, {"subscriptions", {{{"id", 1}, {"channelId", 1}}}}});
  }
  PublishUntilReceived(slow);  // from here on `slow` reads nothing
  PublishUntilReceived(fast);

  // 40 MiB in 64 KiB messages: far more than the kernel buffers of the slow
  // connection hold, so its queue overflows.
  constexpr int kMessages = 640;
  auto fast_reader = std::async(std::launch::async, [&fast] {
    for (;;) {
      const std::string m = fast.Read();
      if (m.size() > 13 && m.substr(13, 5) == "last!") return true;
    }
  });
  const std::string body(64 * 1024, 'x');
  for (int i = 0; i < kMessages; ++i) {
    Publish(1, static_cast<uint64_t>(i), body);
    if (i % 16 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));  // let the fast one keep up
  }
  Publish(1, kMessages, "last!");
  const bool got_last = fast_reader.wait_for(std::chrono::seconds(30)) == std::future_status::ready;
  if (!got_last) fast.Shutdown();  // unblock the reader before failing
  EXPECT_TRUE(got_last) << "the client that reads did not get the newest message";
  EXPECT_GT(server_->stats().messages_dropped, 0u);
  fast_reader.wait();

  // Reading again, the slow client finds one warning, then the newest message.
  int warnings = 0;
  for (;;) {
    const std::string m = slow.Read();
    if (m.front() == '{') {
      const json j = json::parse(m);
      EXPECT_EQ(j["op"], "status");
      EXPECT_EQ(j["message"], "Send buffer limit reached");
      ++warnings;
    }
    if (m.size() > 13 && m.substr(13, 5) == "last!") break;
  }
  EXPECT_EQ(warnings, 1);
}

}  // namespace
