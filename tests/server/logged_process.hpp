// A locaid program a test runs as a child process (locaid-foxglove,
// locaid-ros2), its stdout and stderr in files of the test's folder, and
// bounded waits for what its log says.
#pragma once

#include "test_support.hpp"

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace locaid::server::testing {

class LoggedProcess {
 public:
  // build/bin/<program> with `args`; its stderr in `dir`/<stem>.err, stdout in .out.
  LoggedProcess(const std::string& program, const std::vector<std::string>& args, const std::filesystem::path& dir,
                const std::string& stem)
      : err_(dir / (stem + ".err")) {
    std::filesystem::create_directories(dir);
    std::vector<std::string> argv = {std::string(LOCAID_BIN_DIR) + "/" + program};
    argv.insert(argv.end(), args.begin(), args.end());
    child_ = std::make_unique<ChildProcess>(argv, ChildProcess::Options{dir / (stem + ".out"), err_, 0});
  }
  ChildProcess& process() { return *child_; }
  std::string log() const { return Slurp(err_); }
  // Waits (bounded) until the log holds `text`.
  bool WaitForLog(const std::string& text, double timeout_s) { return WaitForLogCount(text, 1, timeout_s); }
  // Waits (bounded) until the log holds `text` at least `count` times; false
  // when the time is up or the program ended.
  bool WaitForLogCount(const std::string& text, int count, double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      const std::string l = log();
      int seen = 0;
      for (size_t at = l.find(text); at != std::string::npos; at = l.find(text, at + text.size())) ++seen;
      if (seen >= count) return true;
      if (std::chrono::steady_clock::now() >= until || child_->Wait(0)) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

 private:
  std::filesystem::path err_;
  std::unique_ptr<ChildProcess> child_;
};

}  // namespace locaid::server::testing
