// Finishes sessions off the gRPC threads: StopSession, removal and pruning
// hand a session here, and the reaper's one thread joins it (Session::Join:
// the session thread, then the hub's fan-out threads) and drops the
// reference. So no RPC handler ever waits for a session's frame, render or
// threads, whoever stops it and however many stop it at once.
//
// Threading: Start() and Stop() from the server's own code (LocalizationService
// starts it, JoinSessions() stops it, draining what is queued); Retire() from
// any thread. Bound: one entry per session, and a session is queued at most
// once, so the queue never holds more than the server's sessions
// (max_sessions + max_ended_sessions).
#pragma once

#include "server/session.hpp"

#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>

namespace locaid::server {

class SessionReaper {
 public:
  SessionReaper() = default;
  ~SessionReaper() { Stop(); }
  SessionReaper(const SessionReaper&) = delete;
  SessionReaper& operator=(const SessionReaper&) = delete;

  void Start();
  // Queues `session` to be joined and released (a second Retire of the same
  // session is a no-op). After Stop() the session is joined by whoever holds
  // the last reference (shutdown, on the main thread).
  void Retire(std::shared_ptr<Session> session);
  // Joins every queued session, then the reaper's thread. Idempotent.
  void Stop();

 private:
  void Run();

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Session>> queue_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace locaid::server
