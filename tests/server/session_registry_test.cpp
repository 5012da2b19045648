// SessionRegistry's render bound (max_concurrent_renders) holds for the render
// threads themselves: a session taken out (StopSession with remove) while its
// input is still being prepared keeps counting until its preparation ends,
// because a render stops only at its next cancellation point.
#include "server/deferred_run_loop.hpp"
#include "server/session_reaper.hpp"
#include "server/session_registry.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace locaid::server {
namespace {

// A preparation step with no cancellation point inside (like building the
// textures of a synthetic drive): it returns only when the test opens the gate.
class Gate {
 public:
  void Open() {
    {
      std::lock_guard lock(mu_);
      open_ = true;
    }
    cv_.notify_all();
  }
  void Wait() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return open_; });
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool open_ = false;
};

std::unique_ptr<pipeline::RunLoop> PreparingRunLoop(Gate& gate) {
  return std::make_unique<DeferredRunLoop>(
      [&gate](const std::atomic<bool>& cancel) -> std::unique_ptr<pipeline::RunLoop> {
        gate.Wait();
        if (cancel) throw std::runtime_error("cancelled");  // its first cancellation point
        throw std::runtime_error("the test never lets a preparation finish");
      },
      100);
}

class SessionRegistryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_.max_concurrent_renders = 1;
    reaper_.Start();
  }
  void TearDown() override {
    first_.Open();
    second_.Open();
    reaper_.Stop();
  }
  grpc::Status Add(Gate& gate, std::string* id) {
    SessionOptions options;
    options.source = "synthetic:seed=1";
    return registry_.Add(options, PreparingRunLoop(gate), nullptr, id);
  }

  Gate first_, second_;  // first: outlive the sessions waiting on them
  ServerConfig config_;
  SessionReaper reaper_;
  SessionRegistry registry_{config_, reaper_};
};

TEST_F(SessionRegistryTest, RemovedSessionStillPreparingCountsUntilItsPreparationEnds) {
  std::string a, b;
  ASSERT_TRUE(Add(first_, &a).ok());
  const grpc::Status busy = Add(second_, &b);
  EXPECT_EQ(busy.error_code(), grpc::RESOURCE_EXHAUSTED) << busy.error_message();

  std::shared_ptr<Session> removed;
  ASSERT_TRUE(registry_.Find(a, &removed).ok());
  removed->Stop();
  registry_.Remove(a);  // what StopSession with remove does
  EXPECT_TRUE(registry_.List().empty());
  ASSERT_TRUE(removed->preparing()) << "the stopped session's preparation has no cancellation point yet";
  EXPECT_EQ(registry_.Preparing(), 1u) << "locaid_render_queue counts what admission counts";
  const grpc::Status still = Add(second_, &b);
  EXPECT_EQ(still.error_code(), grpc::RESOURCE_EXHAUSTED)
      << "a removed session still preparing must count against max_concurrent_renders: " << still.error_message();
  EXPECT_NE(still.error_message().find("max_concurrent_renders"), std::string::npos) << still.error_message();

  first_.Open();  // its preparation reaches the cancellation point and ends
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);  // a hang, not a speed
  while (removed->preparing() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_FALSE(removed->preparing());
  EXPECT_EQ(registry_.Preparing(), 0u);
  removed.reset();
  const grpc::Status admitted = Add(second_, &b);
  EXPECT_TRUE(admitted.ok()) << admitted.error_message();
}

TEST_F(SessionRegistryTest, StoppedButListedSessionStillPreparingCounts) {
  std::string a, b;
  ASSERT_TRUE(Add(first_, &a).ok());
  std::shared_ptr<Session> stopped;
  ASSERT_TRUE(registry_.Find(a, &stopped).ok());
  stopped->Stop();  // StopSession without remove: listed, STOPPED, still preparing
  EXPECT_EQ(stopped->state(), locaid::v1::SESSION_STATE_STOPPED);
  const grpc::Status busy = Add(second_, &b);
  EXPECT_EQ(busy.error_code(), grpc::RESOURCE_EXHAUSTED) << busy.error_message();
}

}  // namespace
}  // namespace locaid::server
