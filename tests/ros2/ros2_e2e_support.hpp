// The end-to-end fixture of the locaid-ros2 tests: the real locaid-server,
// the real locaid-ros2 (child processes; their logs in the test's folder) and
// a Fast DDS peer in the test process, all on loopback in a domain of the
// test's own. Builds on the server tests' processes (server/test_support.hpp).
#pragma once

#include "fast_peer.hpp"
#include "server/logged_process.hpp"
#include "server/test_support.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <csignal>
#include <memory>
#include <string>
#include <vector>

namespace locaid::ros2::testing {

namespace st = locaid::server::testing;
namespace fs = std::filesystem;
using nlohmann::json;

// locaid-ros2 against the server; its log and --stats-json in `dir`.
class Ros2Process : public st::LoggedProcess {
 public:
  Ros2Process(const fs::path& dir, int server_port, uint32_t domain, const std::vector<std::string>& extra)
      : st::LoggedProcess("locaid-ros2", Args(dir, server_port, domain, extra), dir, "ros2"),
        stats_(dir / "ros2_stats.json") {}
  // The --stats-json file as last written (null before the first write).
  json Stats() const { return json::parse(st::Slurp(stats_), nullptr, false); }
  // SIGTERM, then the exit code (-1: it did not end within the time).
  int Stop(double timeout_s = 30) {
    process().Signal(SIGTERM);
    return process().Wait(timeout_s) ? process().exit_code() : -1;
  }

 private:
  static std::vector<std::string> Args(const fs::path& dir, int server_port, uint32_t domain,
                                       const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"--server", "127.0.0.1:" + std::to_string(server_port), "--domain",
                                     std::to_string(domain), "--stats-json", (dir / "ros2_stats.json").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
  fs::path stats_;
};

class Ros2Car : public ::testing::Test {
 protected:
  void SetUp() override {
    loopback_ = std::make_unique<DdsLoopback>(dir_.path());
    fast_ = std::make_unique<FastPeer>(loopback_->domain, loopback_->fastdds);
    server_ = std::make_unique<st::ServerProcess>(dir_ / "server");
    ASSERT_GT(server_->port(), 0) << server_->log();
    stub_ = v1::Localization::NewStub(server_->NewChannel());
  }
  void TearDown() override {
    ros2_.reset();
    fast_.reset();  // its readers and writers go with its participant
  }
  void StartRos2(const std::vector<std::string>& extra) {
    ros2_ = std::make_unique<Ros2Process>(dir_.path(), server_->port(), loopback_->domain, extra);
  }
  // The newest live session's id, waiting (bounded) for one.
  std::string WaitSession(double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < until) {
      grpc::ClientContext ctx;
      st::SetDeadline(&ctx, 5);
      v1::ListSessionsResponse r;
      if (stub_->ListSessions(&ctx, {}, &r).ok()) {
        for (const auto& s : r.sessions())
          if (s.state() == v1::SESSION_STATE_RUNNING) return s.id();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return "";
  }

  test_support::ScopedTempDir dir_{"ros2_e2e"};
  std::unique_ptr<DdsLoopback> loopback_;
  std::unique_ptr<FastPeer> fast_;
  std::unique_ptr<st::ServerProcess> server_;
  std::unique_ptr<v1::Localization::Stub> stub_;
  std::unique_ptr<Ros2Process> ros2_;
};

}  // namespace locaid::ros2::testing
