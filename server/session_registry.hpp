// The server's sessions by id: admission (max_sessions,
// max_concurrent_renders), lookup, the PushSensorData attachment of live
// sessions, pruning of ended sessions (max_ended_sessions,
// ended_session_ttl_s) and closing for shutdown. Thread-safe; sessions taken
// out (removed, pruned) go to the SessionReaper, which joins them off the
// calling (gRPC) thread.
#pragma once

#include "pipeline/frame_loop.hpp"
#include "pipeline/live_frame_source.hpp"
#include "server/config.hpp"
#include "server/pose_encodings.hpp"
#include "server/session.hpp"
#include "server/session_reaper.hpp"

#include <grpcpp/grpcpp.h>

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace locaid::server {

class SessionRegistry {
 public:
  SessionRegistry(const ServerConfig& config, SessionReaper& reaper) : config_(config), reaper_(reaper) {}

  // Admits and starts a session with a fresh random id; prunes ended ones
  // first. RESOURCE_EXHAUSTED beyond max_sessions running (or
  // max_concurrent_renders preparing, or, with max_cpu_cores, beyond the
  // measured CPU of the real-time sessions), UNAVAILABLE once closed.
  grpc::Status Add(SessionOptions options, std::unique_ptr<pipeline::RunLoop> pipeline,
                   pipeline::LiveFrameSource* live, std::string* id);
  // INVALID_ARGUMENT for an empty id, NOT_FOUND for an unknown one.
  grpc::Status Find(const std::string& id, std::shared_ptr<Session>* out,
                    std::shared_ptr<PoseEncodings>* encodings = nullptr) const;
  // Attaches a PushSensorData stream to live session `id`: NOT_FOUND, or
  // FAILED_PRECONDITION when it is not live, already has a stream, or (with
  // require_running) is not running.
  grpc::Status AttachPush(const std::string& id, bool require_running, std::shared_ptr<Session>* session,
                          pipeline::LiveFrameSource** live);
  // Takes session `id` out (exactly once, whoever races) and retires it.
  void Remove(const std::string& id);
  // Every session, ended ones beyond the limits pruned first.
  std::vector<std::shared_ptr<Session>> List();
  // Sessions preparing their input, listed or taken out, as admission counts
  // them against max_concurrent_renders (metrics).
  size_t Preparing() const;
  // Every session as it is (metrics).
  std::vector<std::shared_ptr<Session>> Snapshot() const;
  // Refuses new sessions from now on and returns every session.
  std::vector<std::shared_ptr<Session>> Close();

 private:
  struct Entry {
    std::shared_ptr<Session> session;
    pipeline::LiveFrameSource* live = nullptr;  // owned by the session's pipeline
    bool push_attached = false;
    std::shared_ptr<PoseEncodings> encodings = std::make_shared<PoseEncodings>();
  };
  // The real-time sessions' CPU: measured cores (sessions running >= 5 s),
  // plus the estimate for younger ones; the estimate per session at rate 1.
  struct LoadEstimate {
    double cores = 0, per_unit_rate = 0;
    int measured = 0;
  };
  LoadEstimate RealTimeLoadLocked() const;
  // RESOURCE_EXHAUSTED when max_cpu_cores is set and a real-time session
  // would take the real-time load beyond it (mu_ held).
  grpc::Status AdmitByCpuLocked(const SessionOptions& options) const;
  // Sessions preparing their input (max_concurrent_renders): the listed ones
  // and those taken out whose render has not reached a cancellation point yet
  // (mu_ held; forgets the retired ones that are done).
  size_t PreparingLocked() const;
  // Hands a session taken out to the reaper, remembering it while it renders
  // (mu_ held).
  void RetireLocked(std::shared_ptr<Session> session);
  // Takes the ended sessions beyond the limits out and retires them (mu_ held).
  void PruneEndedLocked();
  std::vector<std::shared_ptr<Session>> AllLocked() const;

  const ServerConfig& config_;
  SessionReaper& reaper_;
  mutable std::mutex mu_;
  std::map<std::string, Entry> sessions_;
  // Taken out while preparing: at most the sessions the registry listed
  // (max_sessions + max_ended_sessions); the done ones go at every Add.
  mutable std::vector<std::weak_ptr<Session>> retired_preparing_;
  bool closed_ = false;
};

}  // namespace locaid::server
