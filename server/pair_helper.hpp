// A session's decode helper: a PairRunner (core/pair_runner.hpp) with one
// thread of its own that runs a frame's second image job while the session's
// thread runs the first. If the helper has not started the job by the time
// the first one is done (all cores busy), the session's thread takes it back
// and runs it itself: one frame then uses two cores when they are free and
// never waits for a helper that has no core. The thread starts in the
// constructor and is joined by the destructor; it inherits nothing: a batch
// session asks for its nice value (server/session.hpp, kBatchNice).
#pragma once

#include "core/pair_runner.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>

namespace locaid::server {

class PairHelper final : public PairRunner {
 public:
  // nice > 0: the helper thread lowers its priority to it (Linux, per thread).
  explicit PairHelper(int nice = 0);
  ~PairHelper() override;
  PairHelper(const PairHelper&) = delete;
  PairHelper& operator=(const PairHelper&) = delete;

  // One caller at a time (the session's thread).
  void Run(const std::function<void()>& first, const std::function<void()>& second) const override;
  // CPU time the helper thread spent on jobs so far (any thread): the
  // session counts it as its own (SessionStats.cpu_cores).
  double cpu_seconds() const { return static_cast<double>(cpu_ns_.load()) * 1e-9; }

 private:
  enum class State { kIdle, kQueued, kRunning };
  void Loop(int nice);

  mutable std::mutex mu_;
  mutable std::condition_variable wake_, done_;
  mutable State state_ = State::kIdle;
  mutable const std::function<void()>* job_ = nullptr;
  mutable std::exception_ptr job_error_;
  bool stop_ = false;
  std::atomic<int64_t> cpu_ns_{0};
  std::thread thread_;
};

}  // namespace locaid::server
