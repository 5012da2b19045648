// The Localization service's handlers (one per RPC, reading like a table of
// contents), authorization and stream bookkeeping for shutdown. Sessions are
// kept by session_registry.cpp, requests translated in session_requests.cpp,
// streams served by stream_reactors.cpp, the server built in server.cpp, the
// shared statuses in status.cpp.
#include "server/service.hpp"

#include "server/metrics.hpp"
#include "server/camera_fault_request.hpp"
#include "server/outage_request.hpp"
#include "server/status.hpp"
#include "server/stream_reactors.hpp"
#include "server/synthetic_drive.hpp"

#include <grpcpp/support/proto_buffer_reader.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

namespace locaid::server {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

LocalizationService::LocalizationService(ServerConfig config, pipeline::EstimatorMaker make_estimator)
    : config_(std::move(config)), make_estimator_(std::move(make_estimator)) {
  reaper_.Start();
  if (const size_t stale = RemoveStaleSyntheticDrives(config_.work_dir); stale > 0 && config_.log_shutdown) {
    std::cout << "locaid-server: removed " << stale << " synthetic drive(s) left by an earlier server in "
              << SyntheticRoot(config_.work_dir).string() << std::endl;
  }
}

LocalizationService::~LocalizationService() {
  BeginShutdown();
  JoinSessions();
}

Status LocalizationService::Authorize(const grpc::CallbackServerContext* ctx) const {
  if (config_.token.empty()) return Status::OK;
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return {StatusCode::UNAUTHENTICATED, "missing 'authorization: Bearer <token>' metadata"};
  const std::string value(it->second.data(), it->second.size());
  if (value != "Bearer " + config_.token) return {StatusCode::UNAUTHENTICATED, "invalid bearer token"};
  return Status::OK;
}

void LocalizationService::Register(const std::shared_ptr<Waker>& waker) {
  std::lock_guard lock(mu_);
  streams_.insert(waker);
}

void LocalizationService::Unregister(const std::shared_ptr<Waker>& waker) {
  std::lock_guard lock(mu_);
  streams_.erase(waker);
  if (streams_.empty()) streams_cv_.notify_all();
}

bool LocalizationService::WaitForStreams(std::chrono::steady_clock::time_point deadline) {
  std::unique_lock lock(mu_);
  return streams_cv_.wait_until(lock, deadline, [this] { return streams_.empty(); });
}

std::vector<prometheus::MetricFamily> LocalizationService::CollectMetrics() const {
  const std::vector<std::shared_ptr<Session>> sessions = sessions_.Snapshot();
  std::vector<SessionMetrics> snapshots;
  ServerFigures figures;
  for (const auto& s : sessions) {
    snapshots.emplace_back(s->id(), s->Metrics());
    const auto& m = snapshots.back().second;
    if (s->realtime()) figures.realtime_cpu_cores += m.stats.cpu_cores();
  }
  figures.render_queue = sessions_.Preparing();
  figures.max_concurrent_renders = config_.max_concurrent_renders;
  figures.max_cpu_cores = config_.max_cpu_cores;
  figures.rendered_drive_bytes = DirectoryBytes(SyntheticRoot(config_.work_dir).string());
  figures.resident_memory_bytes = ResidentMemoryBytes();
  return BuildMetricFamilies(snapshots, figures);
}

grpc::ServerUnaryReactor* LocalizationService::StartSession(grpc::CallbackServerContext* ctx,
                                                            const v1::StartSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::string id;
  Status s = DoStart(*req, &id);
  if (s.ok()) {
    std::shared_ptr<Session> session;
    s = sessions_.Find(id, &session);
    if (s.ok()) *resp = session->ToProto();
  }
  return Reply(ctx, s);
}

grpc::ServerUnaryReactor* LocalizationService::GetSession(grpc::CallbackServerContext* ctx,
                                                          const v1::GetSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = sessions_.Find(req->session_id(), &session);
  if (s.ok()) *resp = session->ToProto();
  return Reply(ctx, s);
}

grpc::ServerUnaryReactor* LocalizationService::ListSessions(grpc::CallbackServerContext* ctx,
                                                            const v1::ListSessionsRequest*,
                                                            v1::ListSessionsResponse* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  for (const auto& s : sessions_.List()) *resp->add_sessions() = s->ToProto();
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::StopSession(grpc::CallbackServerContext* ctx,
                                                           const v1::StopSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = sessions_.Find(req->session_id(), &session);
  if (!s.ok()) return Reply(ctx, s);
  // No join here: the reaper finishes the session off this thread, so
  // concurrent stops (and a stop during shutdown) all answer at once.
  session->Stop();
  *resp = session->ToProto();
  if (req->remove()) {
    sessions_.Remove(req->session_id());
  } else {
    reaper_.Retire(session);
  }
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::GetStats(grpc::CallbackServerContext* ctx,
                                                        const v1::GetStatsRequest* req, v1::SessionStats* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = sessions_.Find(req->session_id(), &session);
  if (s.ok()) *resp = session->Stats();
  return Reply(ctx, s);
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* LocalizationService::StreamPoses(grpc::CallbackServerContext* ctx,
                                                                            const grpc::ByteBuffer* request) {
  auto fail = [](const Status& s) {
    class Failed : public grpc::ServerWriteReactor<grpc::ByteBuffer> {
     public:
      explicit Failed(const Status& s) { Finish(Bounded(s)); }
      void OnDone() override { delete this; }
    };
    return new Failed(s);
  };
  if (Status s = Authorize(ctx); !s.ok()) return fail(s);
  if (shutting_down_) return fail(Status(StatusCode::UNAVAILABLE, "server is shutting down"));
  v1::StreamPosesRequest req;
  {
    grpc::ByteBuffer copy(*request);  // the reader consumes the buffer
    grpc::ProtoBufferReader reader(&copy);
    if (!req.ParseFromZeroCopyStream(&reader)) {
      return fail(Invalid("StreamPosesRequest: cannot parse the request message"));
    }
  }
  if (const std::string bad = CheckSmoothingLag(req.smoothing_lag_s()); !bad.empty()) return fail(Invalid(bad));
  std::shared_ptr<Session> session;
  std::shared_ptr<PoseEncodings> encodings;
  if (Status s = sessions_.Find(req.session_id(), &session, &encodings); !s.ok()) return fail(s);
  if (req.queue_size() > config_.max_queue_size) {
    return fail(Invalid("queue_size: " + std::to_string(req.queue_size()) + " exceeds the server's max_queue_size " +
                        std::to_string(config_.max_queue_size)));
  }
  if (session->subscriber_count() >= config_.max_subscribers_per_session) {
    return fail(Status(StatusCode::RESOURCE_EXHAUSTED, "session " + Quoted(req.session_id()) + " has " +
                                                           std::to_string(config_.max_subscribers_per_session) +
                                                           " subscribers (max_subscribers_per_session)"));
  }
  const size_t queue = req.queue_size() == 0 ? config_.queue_size : req.queue_size();
  return NewPoseWriter(this, std::move(session), std::move(encodings), req.from_start(), ctx->peer(), queue,
                       req.smoothing_lag_s());
}

grpc::ServerUnaryReactor* LocalizationService::PostControl(
    grpc::CallbackServerContext* ctx, const std::string& session_id, const char* rpc,
    const std::function<Status(Session::Command*)>& to_command, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  if (Status s = sessions_.Find(session_id, &session); !s.ok()) return Reply(ctx, s);
  if (Status s = RequireActive(*session, rpc); !s.ok()) return Reply(ctx, s);
  Session::Command command;
  if (Status s = to_command(&command); !s.ok()) return Reply(ctx, s);
  session->Post(std::move(command));
  *resp = session->ToProto();
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::InjectOutage(grpc::CallbackServerContext* ctx,
                                                            const v1::InjectOutageRequest* req, v1::Session* resp) {
  return PostControl(
      ctx, req->session_id(), "InjectOutage",
      [req](Session::Command* command) { return OutageCommandFromProto(*req, command); }, resp);
}

grpc::ServerUnaryReactor* LocalizationService::InjectCameraFault(grpc::CallbackServerContext* ctx,
                                                                 const v1::InjectCameraFaultRequest* req,
                                                                 v1::Session* resp) {
  return PostControl(
      ctx, req->session_id(), "InjectCameraFault",
      [req](Session::Command* command) { return CameraFaultCommandFromProto(*req, command); }, resp);
}

grpc::ServerUnaryReactor* LocalizationService::SetScenario(grpc::CallbackServerContext* ctx,
                                                           const v1::SetScenarioRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  if (Status s = sessions_.Find(req->session_id(), &session); !s.ok()) return Reply(ctx, s);
  if (Status s = RequireActive(*session, "SetScenario"); !s.ok()) return Reply(ctx, s);
  if (req->scenario().kind_case() == v1::Scenario::KIND_NOT_SET) return Reply(ctx, Invalid("scenario: required"));
  sim::Scenario scenario;
  std::string name;
  if (Status s = ResolveScenario(req->scenario(), &scenario, &name); !s.ok()) return Reply(ctx, s);
  session->Post([scenario](pipeline::RunLoop& p) { p.SetScenario(scenario); });
  session->set_scenario_name(name);
  *resp = session->ToProto();
  return Reply(ctx, Status::OK);
}

grpc::ServerBidiReactor<v1::PushRequest, v1::PushResponse>* LocalizationService::PushSensorData(
    grpc::CallbackServerContext* ctx) {
  if (Status s = Authorize(ctx); !s.ok() || shutting_down_) {
    class Failed : public grpc::ServerBidiReactor<v1::PushRequest, v1::PushResponse> {
     public:
      explicit Failed(const Status& s) { Finish(Bounded(s)); }
      void OnDone() override { delete this; }
    };
    return new Failed(s.ok() ? Status(StatusCode::UNAVAILABLE, "server is shutting down") : s);
  }
  return NewPushReactor(this, ctx->peer());
}

void LocalizationService::BeginShutdown() {
  shutting_down_ = true;
  const std::vector<std::shared_ptr<Session>> sessions = sessions_.Close();
  std::vector<std::shared_ptr<Waker>> streams;
  {
    std::lock_guard lock(mu_);
    streams.assign(streams_.begin(), streams_.end());
  }
  // Streams first: a stopped session closes its hub, and a stream that saw
  // the end before its Abort would finish with OK instead of UNAVAILABLE.
  for (const auto& w : streams) {
    std::lock_guard lock(w->mu);
    if (w->target) w->target->Abort(Status(StatusCode::UNAVAILABLE, "server shutting down"));
  }
  for (const auto& s : sessions) s->Stop();
}

void LocalizationService::JoinSessions() {
  for (const auto& s : sessions_.Snapshot()) s->Join();
  reaper_.Stop();
}

}  // namespace locaid::server
