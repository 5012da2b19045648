// Fan-out of one producer's messages to many subscribers.
//
// One bounded queue per subscriber. Publish() never waits for a subscriber:
// when a queue is full its OLDEST item is dropped and that subscriber's drop
// counter grows, so a slow subscriber always gets the newest items and never
// slows the producer or the other subscribers. Items are shared (one
// allocation per publish, whatever the number of subscribers), so memory is
// bounded by history_capacity + sum(queue capacities) pointers.
//
// A subscriber is woken through its `wake` callback after every push and on
// Close(); the callback must be cheap and must not call back into the hub
// while holding locks the hub could wait on (it is called with no hub lock
// held). Thread-safe: one producer thread, any number of consumer threads.
//
// With StartFanoutThread() the wakes are not called by Publish()/Close() but
// by fan-out worker threads owned by the hub (one per core by default, joined
// by StopFanoutThread() or the destructor): the producer then does O(1) work
// per subscriber under the subscriber's short lock (push one shared
// pointer), and the wake callbacks (which start gRPC writes, a syscall each)
// run off the producer thread, split across the workers by subscriber id.
// Wakes are coalesced: a subscriber woken once after several publishes pulls
// all queued items.
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace locaid::server {

struct SubscriberInfo {
  uint64_t id = 0;
  std::string peer;
  uint64_t delivered = 0;  // items popped by the consumer
  uint64_t dropped = 0;    // items dropped because the queue was full
  size_t queued = 0;
  size_t capacity = 0;     // queue length beyond which the oldest item is dropped
};

struct HubStats {
  uint64_t published = 0;
  size_t history = 0;
  uint64_t dropped_total = 0;  // includes subscribers that have left
  std::vector<SubscriberInfo> subscribers;
};

template <typename T>
class PoseHub {
 public:
  using Item = std::shared_ptr<const T>;

  class Subscriber {
   public:
    enum class PopResult { kItem, kEmpty, kEnd };
    // kItem: *out is the oldest queued item and *dropped the number of items
    // this subscriber has lost so far. kEnd: the hub is closed and the queue
    // drained. kEmpty: wait for the next wake.
    PopResult Pop(Item* out, uint64_t* dropped) {
      std::lock_guard lock(mu_);
      if (queue_.empty()) return closed_ ? PopResult::kEnd : PopResult::kEmpty;
      *out = std::move(queue_.front());
      queue_.pop_front();
      ++delivered_;
      if (dropped) *dropped = dropped_;
      return PopResult::kItem;
    }
    uint64_t id() const { return id_; }
    SubscriberInfo info() const {
      std::lock_guard lock(mu_);
      return {id_, peer_, delivered_, dropped_, queue_.size(), capacity_};
    }

   private:
    friend class PoseHub;
    Subscriber(uint64_t id, std::string peer, size_t capacity, std::function<void()> wake)
        : id_(id), peer_(std::move(peer)), capacity_(capacity), wake_(std::move(wake)) {}
    // Returns the number of items dropped by this push (0 or 1).
    uint64_t Push(const Item& item) {
      std::lock_guard lock(mu_);
      if (closed_) return 0;
      uint64_t lost = 0;
      if (queue_.size() >= capacity_) {
        queue_.pop_front();
        ++dropped_;
        lost = 1;
      }
      queue_.push_back(item);
      return lost;
    }
    void MarkClosed() {
      std::lock_guard lock(mu_);
      closed_ = true;
    }
    void Wake() const {
      if (wake_) wake_();
    }

    const uint64_t id_;
    const std::string peer_;
    const size_t capacity_;
    const std::function<void()> wake_;
    mutable std::mutex mu_;
    std::deque<Item> queue_;
    uint64_t delivered_ = 0, dropped_ = 0;
    bool closed_ = false;
  };
  using SubscriberPtr = std::shared_ptr<Subscriber>;

  explicit PoseHub(size_t history_capacity) : history_capacity_(history_capacity) {}
  PoseHub(const PoseHub&) = delete;
  PoseHub& operator=(const PoseHub&) = delete;
  ~PoseHub() { StopFanoutThread(); }

  // Starts the fan-out threads (see the file comment): `threads` workers
  // (0 = DefaultFanoutThreads()), subscriber id % threads picks the worker
  // that wakes it. Call once, before the first Publish().
  void StartFanoutThread(size_t threads = 0) {
    std::lock_guard lock(fan_mu_);
    if (!fan_threads_.empty()) return;
    if (threads == 0) threads = DefaultFanoutThreads();
    fan_stop_ = false;
    fan_pending_.assign(threads, false);
    for (size_t w = 0; w < threads; ++w) fan_threads_.emplace_back([this, w, threads] { FanoutLoop(w, threads); });
  }
  // Runs a last wake round for what is pending and joins the threads.
  void StopFanoutThread() {
    std::vector<std::thread> threads;
    {
      std::lock_guard lock(fan_mu_);
      if (fan_threads_.empty()) return;
      fan_stop_ = true;
      threads.swap(fan_threads_);
    }
    fan_cv_.notify_all();
    for (std::thread& t : threads) t.join();
    std::lock_guard lock(fan_mu_);
    fan_pending_.clear();
  }
  // One worker per core, at most 4: a wake starts a gRPC write (a syscall
  // per subscriber), so a round over N subscribers is split across cores.
  static size_t DefaultFanoutThreads() {
    return std::clamp<size_t>(std::thread::hardware_concurrency(), 1, 4);
  }
  size_t fanout_threads() const {
    std::lock_guard lock(fan_mu_);
    return fan_threads_.size();
  }

  // Registers a subscriber with a queue of `queue_capacity` (>= 1) items.
  // from_start: the queue is first filled with the history (its capacity
  // grows by the history size so nothing of it is dropped at once). On a
  // closed hub the subscriber gets the history (if asked) and then kEnd.
  SubscriberPtr Subscribe(size_t queue_capacity, bool from_start, std::function<void()> wake,
                          std::string peer = {}) {
    queue_capacity = std::max<size_t>(queue_capacity, 1);
    std::lock_guard lock(mu_);
    const size_t extra = from_start ? history_.size() : 0;
    SubscriberPtr sub(new Subscriber(next_id_++, std::move(peer), queue_capacity + extra, std::move(wake)));
    if (from_start) {
      for (const Item& item : history_) sub->queue_.push_back(item);
    }
    if (closed_) {
      sub->closed_ = true;
    } else {
      subscribers_.push_back(sub);
    }
    return sub;
  }

  void Unsubscribe(const SubscriberPtr& sub) {
    if (!sub) return;
    std::lock_guard lock(mu_);
    auto it = std::find(subscribers_.begin(), subscribers_.end(), sub);
    if (it != subscribers_.end()) {
      dropped_departed_ += (*it)->info().dropped;
      subscribers_.erase(it);
    }
  }

  // Appends to the history and to every subscriber queue, then wakes them.
  void Publish(Item item) {
    std::vector<SubscriberPtr> targets;
    {
      std::lock_guard lock(mu_);
      if (closed_) return;
      ++published_;
      if (history_capacity_ > 0) {
        if (history_.size() >= history_capacity_) history_.pop_front();
        history_.push_back(item);
      }
      targets = subscribers_;
    }
    for (const SubscriberPtr& sub : targets) sub->Push(item);
    WakeAll(targets);
  }

  // No more items: subscribers drain their queues, then Pop() returns kEnd.
  void Close() {
    std::vector<SubscriberPtr> targets;
    {
      std::lock_guard lock(mu_);
      if (closed_) return;
      closed_ = true;
      targets = subscribers_;
    }
    for (const SubscriberPtr& sub : targets) sub->MarkClosed();
    WakeAll(targets);
  }

  bool closed() const {
    std::lock_guard lock(mu_);
    return closed_;
  }

  size_t subscriber_count() const {
    std::lock_guard lock(mu_);
    return subscribers_.size();
  }

  HubStats stats() const {
    std::lock_guard lock(mu_);
    HubStats s;
    s.published = published_;
    s.history = history_.size();
    s.dropped_total = dropped_departed_;
    for (const SubscriberPtr& sub : subscribers_) {
      s.subscribers.push_back(sub->info());
      s.dropped_total += s.subscribers.back().dropped;
    }
    return s;
  }

 private:
  void WakeAll(const std::vector<SubscriberPtr>& targets) {
    {
      std::lock_guard lock(fan_mu_);
      if (!fan_threads_.empty() && !fan_stop_) {
        std::fill(fan_pending_.begin(), fan_pending_.end(), true);
        fan_cv_.notify_all();
        return;
      }
    }
    for (const SubscriberPtr& sub : targets) sub->Wake();
  }

  // Worker `w` of `n`: wakes the subscribers whose id % n == w (ids are
  // stable, so a subscriber leaving never makes another one miss a round).
  void FanoutLoop(size_t w, size_t n) {
    std::vector<SubscriberPtr> targets;
    for (;;) {
      bool stop = false;
      {
        std::unique_lock lock(fan_mu_);
        fan_cv_.wait(lock, [&] { return fan_pending_[w] || fan_stop_; });
        fan_pending_[w] = false;
        stop = fan_stop_;
      }
      targets.clear();
      {
        std::lock_guard lock(mu_);
        for (const SubscriberPtr& sub : subscribers_) {
          if (sub->id_ % n == w) targets.push_back(sub);
        }
      }
      for (const SubscriberPtr& sub : targets) sub->Wake();
      if (stop) return;
    }
  }

  const size_t history_capacity_;
  mutable std::mutex mu_;
  std::deque<Item> history_;
  std::vector<SubscriberPtr> subscribers_;
  uint64_t next_id_ = 1;
  uint64_t published_ = 0;
  uint64_t dropped_departed_ = 0;
  bool closed_ = false;
  // Fan-out thread state (fan_mu_ is never held while calling a wake).
  mutable std::mutex fan_mu_;
  std::condition_variable fan_cv_;
  std::vector<std::thread> fan_threads_;
  std::vector<bool> fan_pending_;  // one flag per worker
  bool fan_stop_ = false;
};

}  // namespace locaid::server
