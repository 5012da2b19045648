// PoseHub alone: ordering, no loss for subscribers that keep up, newest-kept
// drops for slow ones, bounded memory, history, close, concurrent use.
#include "server/pose_hub.hpp"
#include "server/service.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <thread>

namespace locaid::server {
namespace {

using IntHub = PoseHub<int>;

std::vector<int> Drain(const IntHub::SubscriberPtr& sub) {
  std::vector<int> out;
  IntHub::Item item;
  uint64_t dropped = 0;
  while (sub->Pop(&item, &dropped) == IntHub::Subscriber::PopResult::kItem) out.push_back(*item);
  return out;
}

TEST(PoseHub, SubscriberThatKeepsUpGetsEverythingInOrder) {
  IntHub hub(/*history_capacity=*/0);
  auto sub = hub.Subscribe(/*queue_capacity=*/4, false, nullptr);
  std::vector<int> got;
  for (int i = 0; i < 100; ++i) {
    hub.Publish(std::make_shared<const int>(i));
    for (int v : Drain(sub)) got.push_back(v);
  }
  ASSERT_EQ(got.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(got[static_cast<size_t>(i)], i);
  EXPECT_EQ(sub->info().dropped, 0u);
  EXPECT_EQ(sub->info().delivered, 100u);
}

TEST(PoseHub, SlowSubscriberKeepsNewestAndCountsDropsWithoutAffectingOthers) {
  IntHub hub(0);
  constexpr size_t kCapacity = 4;
  constexpr int kCount = 50;
  auto slow = hub.Subscribe(kCapacity, false, nullptr);
  auto fast = hub.Subscribe(kCapacity, false, nullptr);
  std::vector<int> fast_got;
  for (int i = 0; i < kCount; ++i) {
    hub.Publish(std::make_shared<const int>(i));
    for (int v : Drain(fast)) fast_got.push_back(v);
    EXPECT_LE(slow->info().queued, kCapacity);  // memory bounded
  }
  EXPECT_EQ(fast_got.size(), static_cast<size_t>(kCount));
  EXPECT_EQ(fast->info().dropped, 0u);
  EXPECT_EQ(slow->info().dropped, static_cast<uint64_t>(kCount) - kCapacity);
  const std::vector<int> newest = Drain(slow);
  ASSERT_EQ(newest.size(), kCapacity);
  for (size_t i = 0; i < kCapacity; ++i) EXPECT_EQ(newest[i], kCount - static_cast<int>(kCapacity) + static_cast<int>(i));
  EXPECT_EQ(hub.stats().dropped_total, static_cast<uint64_t>(kCount) - kCapacity);
}

TEST(PoseHub, FromStartReplaysBoundedHistory) {
  constexpr size_t kHistory = 10;
  IntHub hub(kHistory);
  for (int i = 0; i < 25; ++i) hub.Publish(std::make_shared<const int>(i));
  auto late = hub.Subscribe(2, /*from_start=*/true, nullptr);
  auto now = hub.Subscribe(2, /*from_start=*/false, nullptr);
  hub.Publish(std::make_shared<const int>(25));
  const std::vector<int> got = Drain(late);
  ASSERT_EQ(got.size(), kHistory + 1);
  EXPECT_EQ(got.front(), 25 - static_cast<int>(kHistory));
  EXPECT_EQ(got.back(), 25);
  EXPECT_EQ(late->info().dropped, 0u);
  EXPECT_EQ(Drain(now), std::vector<int>{25});
  EXPECT_EQ(hub.stats().history, kHistory);
}

TEST(PoseHub, CloseEndsAfterDrainAndLateSubscribersSeeEnd) {
  IntHub hub(5);
  int wakes = 0;
  auto sub = hub.Subscribe(8, false, [&] { ++wakes; });
  hub.Publish(std::make_shared<const int>(1));
  hub.Close();
  hub.Publish(std::make_shared<const int>(2));  // ignored after close
  EXPECT_EQ(wakes, 2);                          // one publish, one close
  IntHub::Item item;
  EXPECT_EQ(sub->Pop(&item, nullptr), IntHub::Subscriber::PopResult::kItem);
  EXPECT_EQ(*item, 1);
  EXPECT_EQ(sub->Pop(&item, nullptr), IntHub::Subscriber::PopResult::kEnd);
  auto late = hub.Subscribe(8, true, nullptr);
  EXPECT_EQ(late->Pop(&item, nullptr), IntHub::Subscriber::PopResult::kItem);
  EXPECT_EQ(late->Pop(&item, nullptr), IntHub::Subscriber::PopResult::kEnd);
}

// Consumers on their own threads, woken through the callback; one subscriber
// never reads. Queues are large enough for the consumers to keep up however
// the threads are scheduled, so they must receive every item in order; the
// stalled one must stay at its capacity.
TEST(PoseHub, ConcurrentConsumersLoseNothingWhileStalledOneStaysBounded) {
  constexpr int kItems = 5000;
  constexpr int kConsumers = 4;
  constexpr size_t kStalledCapacity = 16;
  IntHub hub(100);
  struct Consumer {
    std::mutex mu;
    std::condition_variable cv;
    bool signalled = false;
    IntHub::SubscriberPtr sub;
    std::vector<int> got;
  };
  std::vector<std::unique_ptr<Consumer>> consumers;
  for (int c = 0; c < kConsumers; ++c) {
    auto consumer = std::make_unique<Consumer>();
    Consumer* raw = consumer.get();
    raw->sub = hub.Subscribe(kItems, false, [raw] {
      std::lock_guard lock(raw->mu);
      raw->signalled = true;
      raw->cv.notify_one();
    });
    consumers.push_back(std::move(consumer));
  }
  auto stalled = hub.Subscribe(kStalledCapacity, false, nullptr);
  std::vector<std::thread> threads;
  for (auto& consumer : consumers) {
    threads.emplace_back([c = consumer.get()] {
      for (;;) {
        IntHub::Item item;
        const auto r = c->sub->Pop(&item, nullptr);
        if (r == IntHub::Subscriber::PopResult::kEnd) return;
        if (r == IntHub::Subscriber::PopResult::kItem) {
          c->got.push_back(*item);
          continue;
        }
        std::unique_lock lock(c->mu);
        c->cv.wait_for(lock, std::chrono::milliseconds(20), [c] { return c->signalled; });
        c->signalled = false;
      }
    });
  }
  // A subscriber that joins and leaves repeatedly while publishing.
  std::thread churn([&hub] {
    for (int i = 0; i < 200; ++i) {
      auto s = hub.Subscribe(2, i % 2 == 0, nullptr);
      hub.Unsubscribe(s);
    }
  });
  for (int i = 0; i < kItems; ++i) hub.Publish(std::make_shared<const int>(i));
  hub.Close();
  churn.join();
  for (auto& t : threads) t.join();
  for (auto& consumer : consumers) {
    ASSERT_EQ(consumer->got.size(), static_cast<size_t>(kItems));
    for (int i = 0; i < kItems; ++i) ASSERT_EQ(consumer->got[static_cast<size_t>(i)], i);
    EXPECT_EQ(consumer->sub->info().dropped, 0u);
  }
  EXPECT_EQ(stalled->info().queued, kStalledCapacity);
  EXPECT_EQ(stalled->info().dropped, static_cast<uint64_t>(kItems) - kStalledCapacity);
  EXPECT_EQ(hub.stats().published, static_cast<uint64_t>(kItems));
}

}  // namespace
}  // namespace locaid::server

namespace locaid::server {
namespace {

// With the fan-out thread, wakes run on another thread than the producer, a
// wake that blocks does not block Publish(), and a consumer that drains on
// every wake still gets every item in order once the hub is closed.
TEST(PoseHub, FanoutThreadWakesOffTheProducerAndLosesNothing) {
  IntHub hub(0);
  hub.StartFanoutThread();
  const auto producer = std::this_thread::get_id();
  std::mutex mu;
  std::condition_variable cv;
  bool release = false, blocked_seen = false;
  std::atomic<bool> woken_on_producer{false};
  // Subscriber A: its wake blocks until released (a stuck writer).
  auto stuck = hub.Subscribe(2, false, [&] {
    if (std::this_thread::get_id() == producer) woken_on_producer = true;
    std::unique_lock lock(mu);
    blocked_seen = true;
    cv.notify_all();
    cv.wait(lock, [&] { return release; });
  });
  // Subscriber B: drains on every wake.
  std::vector<int> got;
  bool ended = false;
  IntHub::SubscriberPtr fast;
  fast = hub.Subscribe(1000, false, [&] {
    if (std::this_thread::get_id() == producer) woken_on_producer = true;
    IntHub::Item item;
    uint64_t dropped = 0;
    for (;;) {
      const auto r = fast->Pop(&item, &dropped);
      if (r == IntHub::Subscriber::PopResult::kItem) got.push_back(*item);
      if (r == IntHub::Subscriber::PopResult::kEnd) ended = true;
      if (r != IntHub::Subscriber::PopResult::kItem) break;
    }
  });
  hub.Publish(std::make_shared<const int>(0));
  {
    std::unique_lock lock(mu);
    ASSERT_TRUE(cv.wait_for(lock, std::chrono::seconds(30), [&] { return blocked_seen; }));
  }
  // The fan-out thread is now stuck in A's wake; publishing must not block.
  constexpr int kItems = 500;
  for (int i = 1; i < kItems; ++i) hub.Publish(std::make_shared<const int>(i));
  hub.Close();
  EXPECT_EQ(stuck->info().queued, 2u);  // bounded: the newest two
  EXPECT_EQ(stuck->info().dropped, static_cast<uint64_t>(kItems - 2));
  {
    std::lock_guard lock(mu);
    release = true;
  }
  cv.notify_all();
  hub.StopFanoutThread();  // last wake round after Close
  EXPECT_FALSE(woken_on_producer.load());
  ASSERT_TRUE(ended);
  ASSERT_EQ(got.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) EXPECT_EQ(got[static_cast<size_t>(i)], i);
  EXPECT_EQ(fast->info().dropped, 0u);
}


// Several fan-out workers: every subscriber is woken by exactly one worker
// (id % workers), so subscribers leaving mid-stream never make another one
// miss its wakes; every remaining subscriber gets every item in order.
TEST(PoseHub, FanoutWorkersLoseNoWakeWhenSubscribersLeave) {
  constexpr size_t kWorkers = 3;
  constexpr int kSubscribers = 10, kItems = 300;
  IntHub hub(0);
  hub.StartFanoutThread(kWorkers);
  EXPECT_EQ(hub.fanout_threads(), kWorkers);
  struct Consumer {
    IntHub::SubscriberPtr sub;
    std::mutex mu;
    std::vector<int> got;
    bool ended = false;
  };
  std::vector<std::unique_ptr<Consumer>> consumers;
  for (int i = 0; i < kSubscribers; ++i) consumers.push_back(std::make_unique<Consumer>());
  for (auto& c : consumers) {
    Consumer* cp = c.get();
    c->sub = hub.Subscribe(kItems, false, [cp] {
      std::lock_guard lock(cp->mu);
      IntHub::Item item;
      uint64_t dropped = 0;
      for (;;) {
        const auto r = cp->sub->Pop(&item, &dropped);
        if (r == IntHub::Subscriber::PopResult::kItem) cp->got.push_back(*item);
        if (r == IntHub::Subscriber::PopResult::kEnd) cp->ended = true;
        if (r != IntHub::Subscriber::PopResult::kItem) break;
      }
    });
  }
  for (int i = 0; i < kItems; ++i) {
    if (i == kItems / 3) hub.Unsubscribe(consumers[1]->sub);  // ids shift in the subscriber list
    if (i == kItems / 2) hub.Unsubscribe(consumers[4]->sub);
    hub.Publish(std::make_shared<const int>(i));
  }
  hub.Close();
  hub.StopFanoutThread();  // last round: every remaining subscriber sees the end
  for (int k = 0; k < kSubscribers; ++k) {
    if (k == 1 || k == 4) continue;
    Consumer& c = *consumers[static_cast<size_t>(k)];
    std::lock_guard lock(c.mu);
    EXPECT_TRUE(c.ended) << "subscriber " << k;
    ASSERT_EQ(c.got.size(), static_cast<size_t>(kItems)) << "subscriber " << k;
    for (int i = 0; i < kItems; ++i) EXPECT_EQ(c.got[static_cast<size_t>(i)], i) << "subscriber " << k;
  }
}

std::string Bytes(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  EXPECT_TRUE(buffer.Dump(&slices).ok());
  std::string out;
  for (const grpc::Slice& s : slices) out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

locaid::v1::PoseUpdate SamplePose(uint64_t sequence) {
  locaid::v1::PoseUpdate p;
  p.set_session_id("s7");
  p.set_sequence(sequence);
  p.set_frame_index(static_cast<int64_t>(sequence) + 3);
  p.mutable_position_enu_m()->set_x(1.5);
  p.mutable_position_enu_m()->set_z(-2.25);
  for (int i = 0; i < 36; ++i) p.add_covariance(0.01 * i);
  p.set_published_unix_ns(1'700'000'000'123'456'789LL);
  return p;
}

// One serialization per pose serves every subscriber: the bytes parse back to
// the same PoseUpdate, with dropped_for_subscriber set per subscriber.
TEST(PoseEncodings, SharedBytesParseBackWithThePerSubscriberDropCount) {
  PoseEncodings encodings;
  auto item = std::make_shared<const locaid::v1::PoseUpdate>(SamplePose(5));
  const grpc::Slice a = encodings.Get(item);
  const grpc::Slice b = encodings.Get(item);
  EXPECT_EQ(a.begin(), b.begin()) << "second subscriber must reuse the cached serialization";
  for (uint64_t dropped : {uint64_t{0}, uint64_t{1}, uint64_t{300}, uint64_t{1} << 40}) {
    locaid::v1::PoseUpdate parsed;
    ASSERT_TRUE(parsed.ParseFromString(Bytes(EncodePoseForSubscriber(a, dropped)))) << dropped;
    locaid::v1::PoseUpdate expected = *item;
    expected.set_dropped_for_subscriber(dropped);
    EXPECT_EQ(parsed.SerializeAsString(), expected.SerializeAsString()) << "dropped " << dropped;
    EXPECT_EQ(parsed.dropped_for_subscriber(), dropped);
  }
}

// A from-start replay of old history is serialized per call and does not
// evict the live poses from the cache.
TEST(PoseEncodings, OldHistoryDoesNotEvictLivePoses) {
  PoseEncodings encodings;
  const uint64_t live_seq = 10 * PoseEncodings::kSlots;
  auto live = std::make_shared<const locaid::v1::PoseUpdate>(SamplePose(live_seq));
  auto old = std::make_shared<const locaid::v1::PoseUpdate>(SamplePose(live_seq - PoseEncodings::kSlots));
  const grpc::Slice l1 = encodings.Get(live);
  const grpc::Slice o1 = encodings.Get(old);  // same slot, too old to be cached
  const grpc::Slice o2 = encodings.Get(old);
  const grpc::Slice l2 = encodings.Get(live);
  EXPECT_EQ(l1.begin(), l2.begin());
  EXPECT_NE(o1.begin(), o2.begin());
  EXPECT_EQ(Bytes(EncodePoseForSubscriber(o1, 0)), old->SerializeAsString());
}

}  // namespace
}  // namespace locaid::server
