// The session's decode helper (server/pair_helper.hpp): both jobs run exactly
// once, the second on the helper's thread while the first runs, and errors
// come back in the order a sequential run reports them.
#include "server/pair_helper.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <ctime>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace locaid::server {
namespace {

TEST(PairHelper, TheSecondJobRunsOnTheHelperWhileTheFirstRuns) {
  const PairHelper helper;
  std::mutex mu;
  std::condition_variable cv;
  bool second_running = false;
  std::thread::id second_thread;
  bool first_saw_second = false;
  helper.Run(
      [&] {
        // Waits for the second job to be under way: only possible if it runs elsewhere.
        std::unique_lock lock(mu);
        first_saw_second = cv.wait_for(lock, std::chrono::seconds(60), [&] { return second_running; });
      },
      [&] {
        std::lock_guard lock(mu);
        second_running = true;
        second_thread = std::this_thread::get_id();
        cv.notify_all();
      });
  EXPECT_TRUE(first_saw_second) << "the second job did not run while the first ran";
  EXPECT_NE(second_thread, std::this_thread::get_id());
}

TEST(PairHelper, EachJobRunsExactlyOnceOverManyFrames) {
  const PairHelper helper;
  int first = 0;
  std::atomic<int> second{0};
  for (int i = 0; i < 2000; ++i) helper.Run([&] { ++first; }, [&] { ++second; });
  EXPECT_EQ(first, 2000);
  EXPECT_EQ(second.load(), 2000);
}

TEST(PairHelper, CountsTheCpuItsThreadSpentOnJobs) {
  const PairHelper helper;
  std::mutex mu;
  std::condition_variable cv;
  bool started = false;
  // The second job burns 20 ms of its thread's CPU; the first waits until
  // it has begun, so the helper (not this thread) runs it.
  helper.Run(
      [&] {
        std::unique_lock lock(mu);
        cv.wait_for(lock, std::chrono::seconds(60), [&] { return started; });
      },
      [&] {
        {
          std::lock_guard lock(mu);
          started = true;
        }
        cv.notify_all();
        timespec t0{}, t{};
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t0);
        do clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
        while ((t.tv_sec - t0.tv_sec) * 1e9 + (t.tv_nsec - t0.tv_nsec) < 20e6);
      });
  EXPECT_GE(helper.cpu_seconds(), 0.02);
}

TEST(PairHelper, ErrorsComeBackFirstJobFirst) {
  const PairHelper helper;
  const auto fail = [](const char* what) { return [what] { throw std::runtime_error(what); }; };
  const auto ok = [] {};
  const auto message = [&](const std::function<void()>& a, const std::function<void()>& b) -> std::string {
    try {
      helper.Run(a, b);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message(fail("left"), ok), "left");
  EXPECT_EQ(message(ok, fail("right")), "right");
  EXPECT_EQ(message(fail("left"), fail("right")), "left");
  EXPECT_EQ(message(ok, ok), "");
  // The sequential default agrees.
  std::string sequential;
  try {
    PairRunner::Sequential().Run(fail("left"), fail("right"));
  } catch (const std::runtime_error& e) {
    sequential = e.what();
  }
  EXPECT_EQ(sequential, "left");
}

}  // namespace
}  // namespace locaid::server
