// SessionFollower: the gRPC side of the bridges (locaid-foxglove,
// locaid-ros2). Streams the poses of one session (--session) or of the newest
// live session, and keeps doing so across server restarts and new sessions.
// Run() blocks on the caller's thread; while it streams the newest session a
// short-lived watcher thread polls ListSessions.
//
//  - Without a fixed session it follows the newest session (by creation time)
//    that is STARTING or RUNNING: a STARTING one is rendering its drive and
//    becomes RUNNING, and subscribing early means no pose is missed. It polls
//    ListSessions every poll_s and switches as soon as a newer one exists.
//  - StreamPoses asks for from_start, so a viewer gets the session's history.
//    After a reconnection the history is streamed again; poses whose sequence
//    was already delivered are skipped, so the viewer sees each pose once.
//  - When the server is unreachable it retries with backoff (0.5 s doubling
//    to 5 s, reset once a call succeeds).
#pragma once

#include "locaid/v1/localization.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

namespace locaid::connection {

namespace v1 = locaid::v1;

struct FollowerOptions {
  std::shared_ptr<grpc::Channel> channel;
  std::string token;    // bearer token; empty: none
  std::string session;  // fixed session id; empty: follow the newest live one
  double smoothing_lag_s = 0;  // > 0: the session's lagged (smoothed) stream (StreamPosesRequest)
  double poll_s = 1.0;
  double backoff_min_s = 0.5, backoff_max_s = 5.0;
  double call_timeout_s = 5.0;       // deadline of ListSessions
  double stream_timeout_s = 86400;   // deadline of one StreamPoses call (then it reconnects)
  std::function<void(const std::string&)> log = [](const std::string&) {};
};

class SessionFollower {
 public:
  // on_session(id) runs before the first pose of a newly followed session;
  // on_pose(pose) for every pose, in order. Both on the Run() thread.
  SessionFollower(FollowerOptions options, std::function<void(const std::string&)> on_session,
                  std::function<void(const v1::PoseUpdate&)> on_pose);

  // Follows sessions until Stop().
  void Run();
  // From any thread: ends Run() promptly (cancels the open stream).
  void Stop();

 private:
  // The session to stream now (empty: none live). Fixed session: no RPC.
  grpc::Status Pick(std::string* id);
  // One StreamPoses call; a watcher cancels it when a newer session starts.
  grpc::Status Stream(const std::string& id);
  void Prepare(grpc::ClientContext* ctx, double timeout_s) const;
  // Sleeps up to `seconds`, waking early on Stop(); false once stopping.
  bool Wait(double seconds);
  bool stopping();

  FollowerOptions options_;
  std::unique_ptr<v1::Localization::Stub> stub_;
  std::function<void(const std::string&)> on_session_;
  std::function<void(const v1::PoseUpdate&)> on_pose_;

  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  grpc::ClientContext* stream_ctx_ = nullptr;  // the open stream, for Stop()

  // Run() thread only.
  std::string current_;
  bool current_done_ = false;        // its stream ended for good (finished, not found, failed)
  int64_t last_sequence_ = -1;       // of the current session
  bool switching_ = false;           // the watcher cancelled the stream for a newer session
};

}  // namespace locaid::connection
