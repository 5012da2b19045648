// The gRPC service (callback API); the server that hosts it is server.hpp's.
#pragma once

#include "locaid/v1/localization.grpc.pb.h"
#include "server/config.hpp"
#include "server/metrics.hpp"
#include "server/pose_encodings.hpp"
#include "server/session.hpp"
#include "server/session_registry.hpp"
#include "pipeline/live_frame_source.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/run_assembly.hpp"

#include <grpcpp/grpcpp.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>

namespace locaid::server {

// Something that streams to a client and can be woken by the hub or ended by
// the server. Reached through a Waker so callbacks never touch a deleted
// reactor.
class StreamTarget {
 public:
  virtual ~StreamTarget() = default;
  virtual void Wake() = 0;
  virtual void Abort(const grpc::Status& status) = 0;
  virtual void Resume() {}
};

struct Waker {
  std::mutex mu;
  StreamTarget* target = nullptr;
  void Wake() {
    std::lock_guard lock(mu);
    if (target) target->Wake();
  }
  void Resume() {
    std::lock_guard lock(mu);
    if (target) target->Resume();
  }
};

// What the stream reactors (stream_reactors.cpp) need of the service: stream
// registration (so shutdown can end every stream), live sessions for a push
// stream, and the subscriber queue size. LocalizationService implements it
// privately: none of it is public API.
class ReactorHost {
 public:
  virtual void Register(const std::shared_ptr<Waker>& waker) = 0;
  virtual void Unregister(const std::shared_ptr<Waker>& waker) = 0;
  // The live session a PushSensorData stream attaches to (or starts).
  virtual grpc::Status StartLive(const locaid::v1::PushStart& start, std::shared_ptr<Session>* session,
                                 pipeline::LiveFrameSource** live) = 0;
  virtual size_t subscriber_queue_size() const = 0;

 protected:
  ~ReactorHost() = default;
};

// StreamPoses is served through the raw (ByteBuffer) callback method so one
// serialization per pose serves every subscriber; its request and response
// bytes are the proto messages of localization.proto (the API is unchanged).
class LocalizationService final
    : public locaid::v1::Localization::WithRawCallbackMethod_StreamPoses<locaid::v1::Localization::CallbackService>,
      private ReactorHost {
 public:
  LocalizationService(ServerConfig config, pipeline::EstimatorMaker make_estimator);
  ~LocalizationService() override;

  grpc::ServerUnaryReactor* StartSession(grpc::CallbackServerContext* ctx,
                                         const locaid::v1::StartSessionRequest* req,
                                         locaid::v1::Session* resp) override;
  grpc::ServerUnaryReactor* GetSession(grpc::CallbackServerContext* ctx,
                                       const locaid::v1::GetSessionRequest* req,
                                       locaid::v1::Session* resp) override;
  grpc::ServerUnaryReactor* ListSessions(grpc::CallbackServerContext* ctx,
                                         const locaid::v1::ListSessionsRequest* req,
                                         locaid::v1::ListSessionsResponse* resp) override;
  grpc::ServerUnaryReactor* StopSession(grpc::CallbackServerContext* ctx,
                                        const locaid::v1::StopSessionRequest* req,
                                        locaid::v1::Session* resp) override;
  grpc::ServerUnaryReactor* GetStats(grpc::CallbackServerContext* ctx,
                                     const locaid::v1::GetStatsRequest* req,
                                     locaid::v1::SessionStats* resp) override;
  // Raw StreamPoses: request bytes = StreamPosesRequest, written messages =
  // PoseUpdate bytes.
  grpc::ServerWriteReactor<grpc::ByteBuffer>* StreamPoses(grpc::CallbackServerContext* ctx,
                                                          const grpc::ByteBuffer* request) override;
  grpc::ServerUnaryReactor* InjectOutage(grpc::CallbackServerContext* ctx,
                                         const locaid::v1::InjectOutageRequest* req,
                                         locaid::v1::Session* resp) override;
  grpc::ServerUnaryReactor* SetScenario(grpc::CallbackServerContext* ctx,
                                        const locaid::v1::SetScenarioRequest* req,
                                        locaid::v1::Session* resp) override;
  grpc::ServerUnaryReactor* InjectCameraFault(grpc::CallbackServerContext* ctx,
                                              const locaid::v1::InjectCameraFaultRequest* req,
                                              locaid::v1::Session* resp) override;
  grpc::ServerBidiReactor<locaid::v1::PushRequest, locaid::v1::PushResponse>* PushSensorData(
      grpc::CallbackServerContext* ctx) override;

  // Stops every session and ends every open stream with UNAVAILABLE.
  void BeginShutdown();
  // Joins every session thread (the registry's, then what the reaper holds)
  // and the reaper's thread.
  void JoinSessions();
  // Waits until every stream has finished (its status delivered) or the
  // deadline passes; true when none is left.
  bool WaitForStreams(std::chrono::steady_clock::time_point deadline);

  // Everything /metrics serves, read now (server/metrics.hpp).
  std::vector<prometheus::MetricFamily> CollectMetrics() const;
  // StartSession for the server itself (a session started at boot): the same
  // checks and status codes, no caller to authorize.
  grpc::Status StartLocal(const locaid::v1::StartSessionRequest& req, std::string* id) { return DoStart(req, id); }

 private:
  // ReactorHost.
  void Register(const std::shared_ptr<Waker>& waker) override;
  void Unregister(const std::shared_ptr<Waker>& waker) override;
  grpc::Status StartLive(const locaid::v1::PushStart& start, std::shared_ptr<Session>* session,
                         pipeline::LiveFrameSource** live) override;
  size_t subscriber_queue_size() const override { return config_.queue_size; }

  grpc::Status Authorize(const grpc::CallbackServerContext* ctx) const;
  grpc::Status DoStart(const locaid::v1::StartSessionRequest& req, std::string* id);
  grpc::Status SessionOptionsFromRequest(const locaid::v1::StartSessionRequest& req, SessionOptions* options,
                                         pipeline::RunOptions* run) const;
  // Rendered on the session thread (a DeferredRunLoop): checked here, started at once.
  grpc::Status StartSynthetic(const locaid::v1::SyntheticSource& s, SessionOptions options, pipeline::RunOptions run,
                              std::string* id);
  grpc::Status ResolveScenario(const locaid::v1::Scenario& s, sim::Scenario* out, std::string* name) const;
  // A control of a running session (InjectOutage, InjectCameraFault): the
  // session found and active (else NOT_FOUND / FAILED_PRECONDITION naming
  // `rpc`), the request turned into a command by `to_command` (its
  // INVALID_ARGUMENT returned as is), the command posted, the session in `resp`.
  grpc::ServerUnaryReactor* PostControl(grpc::CallbackServerContext* ctx, const std::string& session_id,
                                        const char* rpc,
                                        const std::function<grpc::Status(Session::Command*)>& to_command,
                                        locaid::v1::Session* resp);

  const ServerConfig config_;
  const pipeline::EstimatorMaker make_estimator_;
  SessionReaper reaper_;  // before sessions_: outlives the registry
  SessionRegistry sessions_{config_, reaper_};
  std::mutex mu_;  // streams_
  std::set<std::shared_ptr<Waker>> streams_;
  std::condition_variable streams_cv_;  // streams_ became empty
  std::atomic<bool> shutting_down_{false};
};

}  // namespace locaid::server
