#include "connection/session_follower.hpp"

#include "connection/connection.hpp"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <thread>

namespace locaid::connection {
namespace {

bool Live(v1::SessionState s) { return s == v1::SESSION_STATE_STARTING || s == v1::SESSION_STATE_RUNNING; }

std::string Describe(const grpc::Status& s) {
  const std::string name = connection::StatusCodeName(s.error_code());
  return s.error_message().empty() ? name : name + ": " + s.error_message();
}

// Waits between failed attempts: min, 2 min, 4 min ... capped at max.
class Backoff {
 public:
  Backoff(double min_s, double max_s) : min_s_(min_s), max_s_(max_s), next_s_(min_s) {}
  double Next() {
    const double d = next_s_;
    next_s_ = std::min(next_s_ * 2, max_s_);
    return d;
  }
  void Reset() { next_s_ = min_s_; }

 private:
  double min_s_, max_s_, next_s_;
};

std::string Seconds(double s) {
  std::ostringstream out;
  out << s << " s";
  return out.str();
}

}  // namespace

SessionFollower::SessionFollower(FollowerOptions options, std::function<void(const std::string&)> on_session,
                                 std::function<void(const v1::PoseUpdate&)> on_pose)
    : options_(std::move(options)),
      stub_(v1::Localization::NewStub(options_.channel)),
      on_session_(std::move(on_session)),
      on_pose_(std::move(on_pose)) {}

void SessionFollower::Run() {
  Backoff backoff(options_.backoff_min_s, options_.backoff_max_s);
  bool said_waiting = false;
  while (!stopping()) {
    std::string target;
    const grpc::Status picked = Pick(&target);
    if (!picked.ok()) {
      const double wait_s = backoff.Next();
      options_.log("ListSessions failed: " + Describe(picked) + "; retrying in " + Seconds(wait_s));
      Wait(wait_s);
      continue;
    }
    if (options_.session.empty()) backoff.Reset();  // the server answered
    if (target.empty() || (target == current_ && current_done_)) {
      if (target.empty() && !said_waiting) options_.log("no live session; checking every " + Seconds(options_.poll_s));
      said_waiting = true;
      Wait(options_.poll_s);
      continue;
    }
    said_waiting = false;
    if (target != current_) {
      current_ = target;
      current_done_ = false;
      last_sequence_ = -1;
      options_.log("following session " + target);
      on_session_(target);
    }
    const int64_t sequence_before = last_sequence_;
    const grpc::Status s = Stream(target);
    if (stopping()) break;
    if (last_sequence_ != sequence_before) backoff.Reset();  // the stream delivered
    bool switching = false;
    {
      std::lock_guard lock(mu_);
      std::swap(switching, switching_);
    }
    if (switching) {
      options_.log("session " + target + ": a newer session started; switching");
    } else if (s.ok()) {
      options_.log("session " + target + " ended (stream OK after sequence " + std::to_string(last_sequence_) + ")");
      current_done_ = true;
    } else if (s.error_code() == grpc::UNAVAILABLE || s.error_code() == grpc::DEADLINE_EXCEEDED ||
               s.error_code() == grpc::CANCELLED) {
      const double wait_s = backoff.Next();
      options_.log("stream of " + target + " lost: " + Describe(s) + "; reconnecting in " + Seconds(wait_s));
      Wait(wait_s);
    } else {
      // NOT_FOUND (removed), ABORTED (failed), UNAUTHENTICATED...: retrying
      // the same call would give the same answer.
      options_.log("stream of " + target + " ended: " + Describe(s));
      current_done_ = true;
      Wait(options_.poll_s);
    }
  }
}

grpc::Status SessionFollower::Pick(std::string* id) {
  if (!options_.session.empty()) {
    *id = options_.session;
    return grpc::Status::OK;
  }
  grpc::ClientContext ctx;
  Prepare(&ctx, options_.call_timeout_s);
  v1::ListSessionsResponse response;
  const grpc::Status s = stub_->ListSessions(&ctx, {}, &response);
  if (!s.ok()) return s;
  const v1::Session* newest = nullptr;
  for (const auto& session : response.sessions()) {
    if (Live(session.state()) && (!newest || session.created_unix_ns() > newest->created_unix_ns())) newest = &session;
  }
  id->clear();
  if (newest) *id = newest->id();
  return s;
}

grpc::Status SessionFollower::Stream(const std::string& id) {
  grpc::ClientContext ctx;
  Prepare(&ctx, options_.stream_timeout_s);
  bool done = false;
  {
    std::lock_guard lock(mu_);
    if (stopping_) return grpc::Status::CANCELLED;
    stream_ctx_ = &ctx;
  }
  // Following the newest session: look for a newer one while this streams.
  std::thread watcher;
  if (options_.session.empty()) {
    watcher = std::thread([&] {
      std::unique_lock lock(mu_);
      while (!done && !stopping_) {
        cv_.wait_for(lock, std::chrono::duration<double>(options_.poll_s));
        if (done || stopping_) break;
        lock.unlock();
        std::string newest;
        const bool newer = Pick(&newest).ok() && !newest.empty() && newest != id;
        lock.lock();
        if (newer && !done) {
          switching_ = true;
          ctx.TryCancel();
          break;
        }
      }
    });
  }
  v1::StreamPosesRequest request;
  request.set_session_id(id);
  request.set_from_start(true);
  request.set_smoothing_lag_s(options_.smoothing_lag_s);
  auto reader = stub_->StreamPoses(&ctx, request);
  v1::PoseUpdate pose;
  while (reader->Read(&pose)) {
    const auto sequence = static_cast<int64_t>(pose.sequence());
    if (sequence <= last_sequence_) continue;  // replayed history after a reconnection
    last_sequence_ = sequence;
    on_pose_(pose);
  }
  const grpc::Status status = reader->Finish();
  {
    std::lock_guard lock(mu_);
    done = true;
    stream_ctx_ = nullptr;
  }
  cv_.notify_all();
  if (watcher.joinable()) watcher.join();
  return status;
}

void SessionFollower::Prepare(grpc::ClientContext* ctx, double timeout_s) const {
  ctx->set_deadline(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000)));
  if (!options_.token.empty()) ctx->AddMetadata("authorization", "Bearer " + options_.token);
}

void SessionFollower::Stop() {
  std::lock_guard lock(mu_);
  stopping_ = true;
  if (stream_ctx_) stream_ctx_->TryCancel();
  cv_.notify_all();
}

bool SessionFollower::Wait(double seconds) {
  std::unique_lock lock(mu_);
  cv_.wait_for(lock, std::chrono::duration<double>(seconds), [this] { return stopping_; });
  return !stopping_;
}

bool SessionFollower::stopping() {
  std::lock_guard lock(mu_);
  return stopping_;
}

}  // namespace locaid::connection
