// A FrameSource read ahead on a thread of its own, so decoding and
// rectifying the next frames overlaps VO on the current one (locaid-replay).
// The thread starts in the constructor and is joined by the destructor; at
// most `depth` items wait between the two.
#pragma once

#include "pipeline/frame_source.hpp"

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

namespace locaid::pipeline {

class PrefetchSource final : public FrameSource {
 public:
  PrefetchSource(std::unique_ptr<FrameSource> inner, size_t depth)
      : inner_(std::move(inner)), depth_(depth < 1 ? 1 : depth), reader_([this] { Read(); }) {}
  ~PrefetchSource() override {
    {
      std::lock_guard lock(mu_);
      stop_ = true;
    }
    not_full_.notify_all();
    reader_.join();
  }
  PrefetchSource(const PrefetchSource&) = delete;
  PrefetchSource& operator=(const PrefetchSource&) = delete;

  // Rethrows what the inner source threw, once the items before it are taken.
  SourceItem Next() override {
    std::unique_lock lock(mu_);
    not_empty_.wait(lock, [&] { return !queue_.empty() || failure_; });
    if (queue_.empty()) std::rethrow_exception(failure_);
    SourceItem item = std::move(queue_.front());
    // kEnd stays queued: every later Next() returns it too.
    if (item.kind == SourceItem::Kind::kEnd) return item;
    queue_.pop_front();
    not_full_.notify_one();
    return item;
  }
  int64_t total_frames() const override { return inner_->total_frames(); }
  double duration_s() const override { return inner_->duration_s(); }
  const StereoCamera& camera() const override { return inner_->camera(); }
  Eigen::Isometry3d T_cam0_imu() const override { return inner_->T_cam0_imu(); }

 private:
  void Read() {
    for (;;) {
      SourceItem item;
      try {
        item = inner_->Next();
      } catch (...) {
        std::lock_guard lock(mu_);
        failure_ = std::current_exception();
        not_empty_.notify_one();
        return;
      }
      const bool end = item.kind == SourceItem::Kind::kEnd;
      std::unique_lock lock(mu_);
      not_full_.wait(lock, [&] { return queue_.size() < depth_ || stop_; });
      if (stop_) return;
      queue_.push_back(std::move(item));
      not_empty_.notify_one();
      if (end) return;
    }
  }

  std::unique_ptr<FrameSource> inner_;
  const size_t depth_;
  std::mutex mu_;
  std::condition_variable not_full_, not_empty_;
  std::deque<SourceItem> queue_;
  bool stop_ = false;
  std::exception_ptr failure_;
  std::thread reader_;  // last: starts once the rest is built
};

}  // namespace locaid::pipeline
