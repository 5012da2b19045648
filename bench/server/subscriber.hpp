// A StreamPoses subscriber for the server benchmarks (callback client): it
// records, per received pose, the delay from its published_unix_ns to
// receipt on this host's clock, or (stalled) never reads.
#pragma once

#include "locaid/v1/localization.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

namespace locaid::bench {

class Subscriber : public grpc::ClientReadReactor<locaid::v1::PoseUpdate> {
 public:
  Subscriber(locaid::v1::Localization::Stub* stub, const std::string& id, uint32_t queue, bool stalled) : stalled_(stalled) {
    req_.set_session_id(id);
    req_.set_queue_size(queue);
    stub->async()->StreamPoses(&ctx_, &req_, this);
    if (!stalled_) StartRead(&msg_);
    StartCall();
  }
  void OnReadDone(bool ok) override {
    if (!ok) return;
    delays_us_.push_back(static_cast<float>((std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count() - msg_.published_unix_ns()) * 1e-3));
    ++received_;
    last_dropped_ = msg_.dropped_for_subscriber();
    StartRead(&msg_);
  }
  void OnDone(const grpc::Status&) override {
    std::lock_guard lock(mu_);
    done_ = true;
    cv_.notify_all();
  }
  void Cancel() { ctx_.TryCancel(); }
  void Wait() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return done_; });
  }
  std::vector<float> delays_us_;
  uint64_t received_ = 0, last_dropped_ = 0;

 private:
  bool stalled_;
  grpc::ClientContext ctx_;
  locaid::v1::StreamPosesRequest req_;
  locaid::v1::PoseUpdate msg_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool done_ = false;
};

}  // namespace locaid::bench
