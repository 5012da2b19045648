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
    std::exception_ptr a, b;
    try {
      first();
    } catch (...) {
      a = std::current_exception();
    }
    try {
      second();
    } catch (...) {
      b = std::current_exception();
    }
    if (a) std::rethrow_exception(a);
    if (b) std::rethrow_exception(b);
  }
  // The sequential runner (no state; shared).
  static const PairRunner& Sequential() {
    static const PairRunner runner;
    return runner;
  }
};

}  // namespace locaid
