#include "server/pair_helper.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <ctime>

namespace locaid::server {
namespace {

int64_t ThreadCpuNs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

PairHelper::PairHelper(int nice) : thread_([this, nice] { Loop(nice); }) {}

PairHelper::~PairHelper() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void PairHelper::Loop(int nice) {
  if (nice > 0) (void)setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice);
  std::unique_lock lock(mu_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || state_ == State::kQueued; });
    if (state_ != State::kQueued) return;  // stopping, nothing queued
    state_ = State::kRunning;
    const std::function<void()>* job = job_;
    lock.unlock();
    const int64_t cpu0 = ThreadCpuNs();
    const std::exception_ptr error = Capture(*job);
    cpu_ns_ += ThreadCpuNs() - cpu0;
    lock.lock();
    job_error_ = error;
    state_ = State::kIdle;
    done_.notify_all();
  }
}

void PairHelper::Run(const std::function<void()>& first, const std::function<void()>& second) const {
  {
    std::lock_guard lock(mu_);
    job_ = &second;
    job_error_ = nullptr;
    state_ = State::kQueued;
  }
  wake_.notify_one();
  const std::exception_ptr first_error = Capture(first);
  std::exception_ptr second_error;
  bool run_here = false;
  {
    std::unique_lock lock(mu_);
    if (state_ == State::kQueued) {  // the helper has not begun: take the job back
      state_ = State::kIdle;
      run_here = true;
    } else {
      done_.wait(lock, [this] { return state_ == State::kIdle; });
      second_error = job_error_;
    }
    job_ = nullptr;
  }
  if (run_here) second_error = Capture(second);
  RethrowFirst(first_error, second_error);
}

}  // namespace locaid::server
