// Helpers for the end-to-end foxglove tests: the real locaid-foxglove as a
// child process, a free loopback port, node scripts run with their output
// parsed as JSON, and synthetic sessions on the real server. Builds on the
// server tests' ChildProcess / ServerProcess (tests/server/test_support.hpp).
#pragma once

#include "free_port.hpp"
#include "needs_tool.hpp"
#include "server/logged_process.hpp"
#include "server/test_support.hpp"

#include <nlohmann/json.hpp>

#include <netinet/in.h>
#include <sys/socket.h>

namespace locaid::foxglove::testing {

namespace v1 = locaid::v1;
namespace st = locaid::server::testing;
using nlohmann::json;

inline bool HaveNode() { return test_support::HaveCommand("node"); }

using test_support::FreeLoopbackPort;

// locaid-foxglove against a server port; its stderr log in `dir`/bridge.err.
class BridgeProcess : public st::LoggedProcess {
 public:
  BridgeProcess(const std::filesystem::path& dir, int server_port, int ws_port,
                const std::vector<std::string>& extra_args = {})
      : st::LoggedProcess("locaid-foxglove", Args(server_port, ws_port, extra_args), dir, "bridge") {}

 private:
  static std::vector<std::string> Args(int server_port, int ws_port, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"--server", "127.0.0.1:" + std::to_string(server_port), "--listen",
                                     "127.0.0.1:" + std::to_string(ws_port)};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
};

struct NodeRun {
  int exit_code = -1;
  json out;          // stdout parsed as JSON (discarded when it is not JSON)
  std::string text;  // stdout and stderr, for failure messages
};

// Runs `node script args...` and parses what it prints.
inline NodeRun RunNode(const std::filesystem::path& script, const std::vector<std::string>& args) {
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "literal" + string.
  std::string command = "node";
  command.append(" ").append(st::ShellQuote(script.string()));
  for (const auto& a : args) command.append(" ").append(st::ShellQuote(a));
  const st::CliResult r = st::RunShell(command);
  return {r.exit_code, json::parse(r.out, nullptr, false), r.out + r.err};
}

// StartSession{synthetic{seed, frames}} at `rate` (0: as fast as possible),
// returned once its drive is rendered (the session is past STARTING): how
// long a render takes depends on the machine, so the tests' bounded waits for
// what the bridge does start from there. The wait itself is only a guard
// against a hang.
inline std::string StartSynthetic(v1::Localization::Stub* stub, uint64_t seed, uint32_t frames, double rate) {
  v1::StartSessionRequest req;
  req.mutable_synthetic()->set_seed(seed);
  req.mutable_synthetic()->set_frames(frames);
  req.set_playback_rate(rate);
  grpc::ClientContext ctx;
  st::SetDeadline(&ctx, 30);
  v1::Session session;
  const grpc::Status s = stub->StartSession(&ctx, req, &session);
  EXPECT_TRUE(s.ok()) << s.error_message();
  if (!s.ok()) return session.id();
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(300);
  while (session.state() == v1::SESSION_STATE_STARTING && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    session = st::GetSession(stub, session.id());
  }
  EXPECT_NE(session.state(), v1::SESSION_STATE_STARTING) << session.id() << ": the render never ended";
  return session.id();
}

// Waits (bounded) until the session is FINISHED; returns its poses published.
inline uint64_t WaitFinished(v1::Localization::Stub* stub, const std::string& id, double timeout_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  v1::Session s = st::GetSession(stub, id);
  while (s.state() != v1::SESSION_STATE_FINISHED && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    s = st::GetSession(stub, id);
  }
  EXPECT_EQ(s.state(), v1::SESSION_STATE_FINISHED) << s.error();
  return s.stats().poses_published();
}

}  // namespace locaid::foxglove::testing
