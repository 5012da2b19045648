// Two independent jobs of one frame (decoding and rectifying its left and
// right image) and who runs them. Libraries take a PairRunner and never start
// threads: the default runs the two one after the other on the calling
// thread; the server gives each session a helper thread that runs the second
// while the session's thread runs the first (server/pair_helper.hpp), so one
// frame uses two cores when they are free and costs nothing extra when not.
#pragma once

#include <exception>
#include <functional>

namespace locaid {

class PairRunner {
 public:
  virtual ~PairRunner() = default;
  // Runs both jobs and returns when both have ended. If either threw, the
  // first job's exception is rethrown, else the second's (the order a
  // sequential run reports them in).
  virtual void Run(const std::function<void()>& first, const std::function<void()>& second) const {
    const std::exception_ptr a = Capture(first);
    RethrowFirst(a, Capture(second));
  }
  // The sequential runner (no state; shared).
  static const PairRunner& Sequential() {
    static const PairRunner runner;
    return runner;
  }

 protected:
  // Runs `job`; what it threw, or null.
  static std::exception_ptr Capture(const std::function<void()>& job) noexcept {
    try {
      job();
    } catch (...) {
      return std::current_exception();
    }
    return nullptr;
  }
  // Rethrows the first job's exception, else the second's.
  static void RethrowFirst(const std::exception_ptr& first, const std::exception_ptr& second) {
    if (first) std::rethrow_exception(first);
    if (second) std::rethrow_exception(second);
  }
};

}  // namespace locaid
