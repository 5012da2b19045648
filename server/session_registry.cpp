#include "server/session_registry.hpp"

#include "server/status.hpp"
#include "server/synthetic_drive.hpp"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <utility>

namespace locaid::server {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

Status SessionRegistry::Add(SessionOptions options, std::unique_ptr<pipeline::RunLoop> pipeline,
                            pipeline::LiveFrameSource* live, std::string* id) {
  std::lock_guard lock(mu_);
  PruneEndedLocked();
  if (closed_) return {StatusCode::UNAVAILABLE, "server is shutting down"};
  size_t active = 0;
  for (const auto& [k, e] : sessions_) {
    const auto st = e.session->state();
    active += (st == v1::SESSION_STATE_RUNNING || st == v1::SESSION_STATE_STARTING) ? 1 : 0;
  }
  if (active >= config_.max_sessions) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "max_sessions (" + std::to_string(config_.max_sessions) + ") sessions are running; stop one first"};
  }
  options.live = live != nullptr;
  options.behind_threshold_s = config_.behind_threshold_s;
  if (Status s = AdmitByCpuLocked(options); !s.ok()) return s;
  if (!pipeline->ready()) {  // it prepares its input (renders) first
    const size_t preparing = PreparingLocked();
    if (preparing >= config_.max_concurrent_renders) {
      return {StatusCode::RESOURCE_EXHAUSTED, std::to_string(preparing) +
                                                  " sessions are preparing their input (max_concurrent_renders); "
                                                  "retry when one is RUNNING"};
    }
  }
  do options.id = RandomSessionId();
  while (sessions_.count(options.id) > 0);
  *id = options.id;
  auto session = std::make_shared<Session>(std::move(options), std::move(pipeline));
  sessions_[*id] = Entry{session, live, false};  // encodings: its default (a fresh cache)
  session->Start();
  return Status::OK;
}

Status SessionRegistry::AdmitByCpuLocked(const SessionOptions& options) const {
  const bool realtime = options.live || options.playback_rate > 0;
  if (config_.max_cpu_cores <= 0 || !realtime) return Status::OK;
  const LoadEstimate load = RealTimeLoadLocked();
  const double rate = options.live ? 1.0 : options.playback_rate;
  const double need = load.per_unit_rate * rate;
  if (load.cores + need <= config_.max_cpu_cores) return Status::OK;
  std::ostringstream msg;
  msg.precision(3);
  msg << "max_cpu_cores (" << config_.max_cpu_cores << "): the real-time sessions use " << load.cores
      << " cores and this one needs about " << need << " (" << load.per_unit_rate << " per session at real time, "
      << (load.measured > 0 ? "measured on " + std::to_string(load.measured) + " session(s)" : std::string("the prior"))
      << "); stop a session, lower its playback_rate, or run it unpaced (playback_rate 0)";
  return {StatusCode::RESOURCE_EXHAUSTED, msg.str()};
}

SessionRegistry::LoadEstimate SessionRegistry::RealTimeLoadLocked() const {
  // Sessions younger than the CPU window have no full measurement yet: they
  // count with the estimate, so sessions started together are not all admitted.
  constexpr double kMatureS = 5.0;
  LoadEstimate load;
  double per_rate_sum = 0;
  std::vector<const Session*> young;
  for (const auto& [k, e] : sessions_) {
    const Session& s = *e.session;
    const auto st = s.state();
    if (!s.realtime() || (st != v1::SESSION_STATE_RUNNING && st != v1::SESSION_STATE_STARTING)) continue;
    if (s.age_s() < kMatureS || s.preparing()) {
      young.push_back(&s);
      continue;
    }
    const double cores = s.cpu_cores();
    load.cores += cores;
    per_rate_sum += cores / (s.options().live ? 1.0 : s.options().playback_rate);
    ++load.measured;
  }
  load.per_unit_rate = load.measured > 0 ? per_rate_sum / load.measured : config_.session_cpu_cores_prior;
  for (const Session* s : young) load.cores += load.per_unit_rate * (s->options().live ? 1.0 : s->options().playback_rate);
  return load;
}

size_t SessionRegistry::PreparingLocked() const {
  // A stopped session's render ends at its next cancellation point: it counts
  // until then, listed or already taken out, so the bound holds for the render
  // threads themselves.
  size_t n = 0;
  for (const auto& [k, e] : sessions_) n += e.session->preparing() ? 1 : 0;
  std::erase_if(retired_preparing_, [&n](const std::weak_ptr<Session>& w) {
    const std::shared_ptr<Session> s = w.lock();
    if (!s || !s->preparing()) return true;
    ++n;
    return false;
  });
  return n;
}

void SessionRegistry::RetireLocked(std::shared_ptr<Session> session) {
  if (session->preparing()) retired_preparing_.push_back(session);
  reaper_.Retire(std::move(session));
}

void SessionRegistry::PruneEndedLocked() {
  const int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::system_clock::now().time_since_epoch()).count();
  const auto ttl_ns = static_cast<int64_t>(config_.ended_session_ttl_s * 1e9);
  std::vector<std::pair<int64_t, std::string>> ended;  // (ended at, id)
  for (const auto& [id, e] : sessions_) {
    const int64_t at = e.session->ended_unix_ns();
    if (at > 0) ended.emplace_back(at, id);
  }
  std::sort(ended.begin(), ended.end());
  for (size_t i = 0; i < ended.size(); ++i) {
    const bool too_many = ended.size() - i > config_.max_ended_sessions;
    if (!too_many && now - ended[i].first <= ttl_ns) continue;
    RetireLocked(sessions_.at(ended[i].second).session);
    sessions_.erase(ended[i].second);
  }
}

Status SessionRegistry::Find(const std::string& id, std::shared_ptr<Session>* out,
                             std::shared_ptr<PoseEncodings>* encodings) const {
  if (id.empty()) return Invalid("session_id: required");
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return {StatusCode::NOT_FOUND, "session " + Quoted(id) + " not found"};
  *out = it->second.session;
  if (encodings) *encodings = it->second.encodings;
  return Status::OK;
}

Status SessionRegistry::AttachPush(const std::string& id, bool require_running, std::shared_ptr<Session>* session,
                                   pipeline::LiveFrameSource** live) {
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return {StatusCode::NOT_FOUND, "session " + Quoted(id) + " not found"};
  Entry& e = it->second;
  if (!e.live) return {StatusCode::FAILED_PRECONDITION, "session " + Quoted(id) + " is not a live session"};
  if (e.push_attached) {
    return {StatusCode::FAILED_PRECONDITION, "session " + Quoted(id) + " already has a PushSensorData stream"};
  }
  if (require_running && e.session->state() != v1::SESSION_STATE_RUNNING) {
    return {StatusCode::FAILED_PRECONDITION, "session " + Quoted(id) + " is not running"};
  }
  e.push_attached = true;
  *session = e.session;
  *live = e.live;
  return Status::OK;
}

void SessionRegistry::Remove(const std::string& id) {
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return;
  RetireLocked(std::move(it->second.session));
  sessions_.erase(it);
}

std::vector<std::shared_ptr<Session>> SessionRegistry::List() {
  std::lock_guard lock(mu_);
  PruneEndedLocked();
  return AllLocked();
}

size_t SessionRegistry::Preparing() const {
  std::lock_guard lock(mu_);
  return PreparingLocked();
}

std::vector<std::shared_ptr<Session>> SessionRegistry::Snapshot() const {
  std::lock_guard lock(mu_);
  return AllLocked();
}

std::vector<std::shared_ptr<Session>> SessionRegistry::Close() {
  std::lock_guard lock(mu_);
  closed_ = true;
  return AllLocked();
}

std::vector<std::shared_ptr<Session>> SessionRegistry::AllLocked() const {
  std::vector<std::shared_ptr<Session>> all;
  all.reserve(sessions_.size());
  for (const auto& [id, e] : sessions_) all.push_back(e.session);
  return all;
}

}  // namespace locaid::server
