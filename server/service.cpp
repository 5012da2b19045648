#include "server/service.hpp"

#include "kitti/dataset.hpp"
#include "kitti/raw_drive.hpp"
#include "server/frame_source.hpp"
#include "server/synthetic_drive.hpp"

#include <google/protobuf/io/coded_stream.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>

#include <cstdio>
#include <random>
#include <sstream>
#include <grpcpp/support/proto_buffer_reader.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

// Every status leaves the server through Bounded: a message echoing a huge
// input (a 1 MiB session id, a 31 MiB path) would trip the client's metadata
// limit and reach it as RESOURCE_EXHAUSTED instead of the real code.
constexpr size_t kMaxStatusMessageBytes = 1024;
Status Bounded(const Status& s) {
  if (s.error_message().size() <= kMaxStatusMessageBytes) return s;
  return {s.error_code(), s.error_message().substr(0, kMaxStatusMessageBytes) + "... (message cut)"};
}

constexpr double kMinPlaybackRate = 1e-3, kMaxPlaybackRate = 1e3;

// Controls of a session's pipeline apply only while it runs (or starts).
Status RequireActive(const Session& session, const char* rpc) {
  const auto state = session.state();
  if (state == v1::SESSION_STATE_RUNNING || state == v1::SESSION_STATE_STARTING) return Status::OK;
  return {StatusCode::FAILED_PRECONDITION, std::string(rpc) + ": session '" + session.id() + "' is " +
                                               v1::SessionState_Name(state) + "; only a running session takes it"};
}

// An input echoed in a message: quoted, cut to 200 bytes (with its size).
std::string Quoted(const std::string& input) {
  constexpr size_t kMax = 200;
  if (input.size() <= kMax) return "'" + input + "'";
  return "'" + input.substr(0, kMax) + "...' (" + std::to_string(input.size()) + " bytes)";
}

grpc::ServerUnaryReactor* Reply(grpc::CallbackServerContext* ctx, const Status& status) {
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(Bounded(status));
  return reactor;
}

Status Invalid(const std::string& msg) { return {StatusCode::INVALID_ARGUMENT, msg}; }

// The service's name for grpc.health.v1 (besides "" for the whole server).
const std::string kServiceName = v1::Localization::service_full_name();

// "s" + 12 random hex digits (48 bits from std::random_device): unique across
// server restarts, so an id kept by a client from before a restart can never
// name another session (ids counting from s1 did).
std::string RandomSessionId() {
  static std::mutex mu;
  static std::random_device device;
  std::lock_guard lock(mu);
  const uint64_t bits = (static_cast<uint64_t>(device()) << 32 | device()) & 0xffffffffffffULL;
  char buf[16];
  std::snprintf(buf, sizeof(buf), "s%012llx", static_cast<unsigned long long>(bits));
  return buf;
}

// ------------------------------------------------------- shared stream ---

// A server stream that writes hub items (and, for PushSensorData, control
// messages): one write in flight at a time, woken by the hub (through a Waker
// registered with the service, so shutdown can abort it), finished exactly
// once (after the write in flight, if any). Derived classes say what to write
// next in NextLocked(); everything else (wake, abort, write completion,
// cancel, unsubscribe, delete) is here, shared by PoseWriter and PushReactor.
template <typename Reactor, typename Msg>
class HubStream : public Reactor, public StreamTarget {
 public:
  void Wake() override {
    std::lock_guard lock(mu_);
    WriteNextLocked();
  }
  void Abort(const Status& status) override {
    std::lock_guard lock(mu_);
    FinishLocked(status);
  }
  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mu_);
    writing_ = false;
    if (!ok) {
      FinishLocked(Status(StatusCode::UNAVAILABLE, "write failed (client gone)"));
      return;
    }
    if (finish_) {
      FinishLocked(*finish_);
      return;
    }
    WriteNextLocked();
  }
  void OnCancel() override {
    std::lock_guard lock(mu_);
    FinishLocked(Status::CANCELLED);
  }
  void OnDone() override {
    {
      std::lock_guard lock(waker_->mu);
      waker_->target = nullptr;
    }
    if (session_) session_->hub().Unsubscribe(sub_);
    OnStreamEnded();
    service_->Unregister(waker_);
    delete this;
  }

 protected:
  enum class Next { kWrite, kIdle, kEnd };

  explicit HubStream(LocalizationService* service) : service_(service), waker_(std::make_shared<Waker>()) {
    waker_->target = this;
    service_->Register(waker_);
  }

  // With mu_ held: fills *out and returns kWrite, or sets *end and returns
  // kEnd, or returns kIdle (nothing to write until the next wake).
  virtual Next NextLocked(Msg* out, Status* end) = 0;
  // Called once from OnDone() after the hub subscription is dropped.
  virtual void OnStreamEnded() {}

  // Subscribes this stream to `session`'s hub (the wake goes through the
  // Waker so it never reaches a deleted reactor).
  void Subscribe(std::shared_ptr<Session> session, size_t queue_size, bool from_start, std::string peer) {
    session_ = std::move(session);
    std::weak_ptr<Waker> weak = waker_;
    sub_ = session_->hub().Subscribe(
        queue_size, from_start,
        [weak] {
          if (auto w = weak.lock()) w->Wake();
        },
        std::move(peer));
  }

  // The next hub item of this stream: kWrite with *item and the subscriber's
  // drop count, kEnd with the end status (OK, or ABORTED when the session
  // failed), kIdle while the queue is empty. With mu_ held, after Subscribe().
  Next PopLocked(Hub::Item* item, uint64_t* dropped, Status* end) {
    switch (sub_->Pop(item, dropped)) {
      case Hub::Subscriber::PopResult::kItem:
        return Next::kWrite;
      case Hub::Subscriber::PopResult::kEnd:
        *end = session_->state() == v1::SESSION_STATE_FAILED
                   ? Status(StatusCode::ABORTED,
                            "session " + session_->id() + " failed: " + session_->ToProto().error())
                   : Status::OK;
        return Next::kEnd;
      case Hub::Subscriber::PopResult::kEmpty:
        break;
    }
    return Next::kIdle;
  }

  void WriteNextLocked() {
    if (!open_locked() || writing_) return;
    Status end;
    switch (NextLocked(&out_, &end)) {
      case Next::kWrite:
        writing_ = true;
        this->StartWrite(&out_);
        return;
      case Next::kEnd:
        FinishLocked(end);
        return;
      case Next::kIdle:
        return;
    }
  }
  // Finish once; with a write in flight, after it completes.
  void FinishLocked(const Status& status) {
    if (finished_) return;
    if (writing_) {
      if (!finish_) finish_ = status;
      return;
    }
    finished_ = true;
    this->Finish(Bounded(status));
  }
  bool open_locked() const { return !finished_ && !finish_; }

  LocalizationService* const service_;
  const std::shared_ptr<Waker> waker_;
  std::shared_ptr<Session> session_;  // set by Subscribe()
  Hub::SubscriberPtr sub_;
  std::mutex mu_;

 private:
  Msg out_;  // the message being written (alive until OnWriteDone)
  bool writing_ = false, finished_ = false;
  std::optional<Status> finish_;
};

// ------------------------------------------------------------ StreamPoses --

// Raw (ByteBuffer) writer: every pose is serialized once per session
// (PoseEncodings) and each subscriber's message is that shared slice plus,
// when it has lost items, a few bytes for dropped_for_subscriber. The bytes
// on the wire are an ordinary PoseUpdate.
class PoseWriter final : public HubStream<grpc::ServerWriteReactor<grpc::ByteBuffer>, grpc::ByteBuffer> {
 public:
  PoseWriter(LocalizationService* service, std::shared_ptr<Session> session,
             std::shared_ptr<PoseEncodings> encodings, bool from_start, std::string peer, size_t queue_size)
      : HubStream(service), encodings_(std::move(encodings)) {
    Subscribe(std::move(session), queue_size, from_start, std::move(peer));
    Wake();
  }

 private:
  Next NextLocked(grpc::ByteBuffer* out, Status* end) override {
    Hub::Item item;
    uint64_t dropped = 0;
    const Next next = PopLocked(&item, &dropped, end);
    if (next == Next::kWrite) *out = EncodePoseForSubscriber(encodings_->Get(item), dropped);
    return next;
  }

  const std::shared_ptr<PoseEncodings> encodings_;
};

// --------------------------------------------------------- PushSensorData --

class PushReactor final : public HubStream<grpc::ServerBidiReactor<v1::PushRequest, v1::PushResponse>,
                                           v1::PushResponse> {
 public:
  PushReactor(LocalizationService* service, std::string peer) : HubStream(service), peer_(std::move(peer)) {
    StartRead(&req_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {  // client half-closed (or went away)
      std::lock_guard lock(mu_);
      reads_done_ = true;
      if (live_) {
        live_->CloseInput();
      } else {
        FinishLocked(Invalid("stream closed before a 'start' message"));
      }
      return;
    }
    if (!session_) {
      OnStart();
      return;
    }
    switch (req_.item_case()) {
      case v1::PushRequest::kFrame: {
        const v1::StereoFrame& f = req_.frame();
        const int64_t index = frames_++;
        if (f.encoding() != v1::IMAGE_ENCODING_PNG && f.encoding() != v1::IMAGE_ENCODING_GRAY8) {
          Reject("frame", index, "encoding: must be IMAGE_ENCODING_PNG or IMAGE_ENCODING_GRAY8");
          break;
        }
        LiveItem item;
        item.kind = LiveItem::Kind::kFrame;
        item.t_ns = f.t_ns();
        item.png = f.encoding() == v1::IMAGE_ENCODING_PNG;
        if (item.png) {
          // A PNG declaring another size than the session camera is never
          // decoded (a small file can declare 30000x30000 px): the stream
          // ends with INVALID_ARGUMENT naming both sizes.
          std::string mismatch = PngSizeMismatch(f.left(), live_->camera(), "left");
          if (mismatch.empty()) mismatch = PngSizeMismatch(f.right(), live_->camera(), "right");
          if (!mismatch.empty()) {
            // Nothing more is read; the frames before this one are still in
            // the pipeline: their poses are delivered first, then the stream
            // ends with this status instead of OK.
            std::lock_guard lock(mu_);
            end_status_ = Invalid("frame " + std::to_string(index) + ": " + mismatch);
            reads_done_ = true;
            live_->CloseInput();
            return;
          }
        }
        item.left = std::move(*req_.mutable_frame()->mutable_left());
        item.right = std::move(*req_.mutable_frame()->mutable_right());
        PushToSession(std::move(item));
        return;
      }
      case v1::PushRequest::kOxts: {
        LiveItem item;
        item.kind = LiveItem::Kind::kOxts;
        item.t_ns = req_.oxts().t_ns();
        item.oxts_line = req_.oxts().line();
        ++oxts_;
        PushToSession(std::move(item));
        return;
      }
      case v1::PushRequest::kStart:
        Reject("start", 0, "the stream already has a session; 'start' must be the first message only");
        break;
      case v1::PushRequest::ITEM_NOT_SET:
        Reject("empty", 0, "message without frame or oxts");
        break;
    }
    StartReadIfOpen();
  }

  void Resume() override { StartReadIfOpen(); }

 private:
  void OnStreamEnded() override {
    if (live_ && !reads_done_) live_->CloseInput();
  }

  void OnStart() {
    if (req_.item_case() != v1::PushRequest::kStart) {
      std::lock_guard lock(mu_);
      FinishLocked(Invalid("first message must be 'start' (got " +
                           std::string(req_.item_case() == v1::PushRequest::kFrame ? "frame" : "oxts") + ")"));
      return;
    }
    std::shared_ptr<Session> session;
    LiveFrameSource* live = nullptr;
    const Status status = service_->StartLive(req_.start(), &session, &live);
    std::lock_guard lock(mu_);
    if (!status.ok()) {
      FinishLocked(status);
      return;
    }
    live_ = live;
    Subscribe(std::move(session), service_->config().queue_size, false, peer_);
    v1::PushResponse first;
    *first.mutable_session() = session_->ToProto();
    control_.push_back(std::move(first));
    WriteNextLocked();
    if (open_locked()) StartRead(&req_);
  }

  void PushToSession(LiveItem item) {
    std::weak_ptr<Waker> weak = waker_;
    const bool room = live_->Push(std::move(item), [weak] {
      if (auto w = weak.lock()) w->Resume();
    });
    if (room) StartReadIfOpen();
  }

  void StartReadIfOpen() {
    std::lock_guard lock(mu_);
    if (open_locked() && !reads_done_) StartRead(&req_);
  }

  void Reject(const std::string& kind, int64_t index, const std::string& reason) {
    v1::PushResponse r;
    r.mutable_rejected()->set_kind(kind);
    r.mutable_rejected()->set_index(index);
    r.mutable_rejected()->set_reason(reason);
    std::lock_guard lock(mu_);
    if (control_.size() < 64) control_.push_back(std::move(r));
    WriteNextLocked();
  }

  // Control messages (session, rejections) first, then poses.
  Next NextLocked(v1::PushResponse* out, Status* end) override {
    if (!control_.empty()) {
      *out = std::move(control_.front());
      control_.pop_front();
      return Next::kWrite;
    }
    if (!sub_) return Next::kIdle;
    Hub::Item item;
    uint64_t dropped = 0;
    const Next next = PopLocked(&item, &dropped, end);
    if (next == Next::kWrite) {
      out->Clear();
      *out->mutable_pose() = *item;
      out->mutable_pose()->set_dropped_for_subscriber(dropped);
    }
    if (next == Next::kEnd && end->ok() && !end_status_.ok()) *end = end_status_;
    return next;
  }

  const std::string peer_;
  v1::PushRequest req_;
  LiveFrameSource* live_ = nullptr;
  std::deque<v1::PushResponse> control_;
  bool reads_done_ = false;
  Status end_status_;  // replaces OK at the end of the stream (a refused frame)
  int64_t frames_ = 0, oxts_ = 0;
};

bool Finite(double x) { return std::isfinite(x); }

Status ParseLiveSource(const v1::LiveSource& l, LiveCameraSetup* out) {
  for (const auto& [name, v] : {std::pair{"fx", l.fx()}, {"fy", l.fy()}, {"baseline_m", l.baseline_m()}}) {
    if (!Finite(v) || v <= 0) return Invalid(std::string("live.") + name + ": must be finite and > 0, got " + std::to_string(v));
  }
  for (const auto& [name, v] : {std::pair{"cx", l.cx()}, {"cy", l.cy()}}) {
    if (!Finite(v)) return Invalid(std::string("live.") + name + ": must be finite");
  }
  if (l.width() < 16 || l.height() < 16 || l.width() > 8192 || l.height() > 8192) {
    return Invalid("live.width/height: must be in [16, 8192], got " + std::to_string(l.width()) + "x" +
                   std::to_string(l.height()));
  }
  out->camera = kitti::StereoCamera{l.fx(), l.fy(), l.cx(), l.cy(), l.baseline_m(), l.width(), l.height()};
  if (l.t_cam0_imu_size() == 0) {
    out->T_cam0_imu = KittiRigTcam0Imu();
  } else if (l.t_cam0_imu_size() == 12) {
    Eigen::Matrix<double, 3, 4> m;
    for (int i = 0; i < 12; ++i) {
      if (!Finite(l.t_cam0_imu(i))) return Invalid("live.T_cam0_imu[" + std::to_string(i) + "]: not finite");
      m(i / 4, i % 4) = l.t_cam0_imu(i);
    }
    const Eigen::Matrix3d R = m.leftCols<3>();
    if ((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0) {
      return Invalid("live.T_cam0_imu: rotation part is not orthonormal");
    }
    out->T_cam0_imu.linear() = R;
    out->T_cam0_imu.translation() = m.col(3);
  } else {
    return Invalid("live.T_cam0_imu: expected 0 or 12 values, got " + std::to_string(l.t_cam0_imu_size()));
  }
  return Status::OK;
}


}  // namespace

// ------------------------------------------------------- pose encodings --

grpc::Slice PoseEncodings::Get(const Hub::Item& item) {
  const uint64_t seq = item->sequence();
  const size_t slot = static_cast<size_t>(seq % kSlots);
  {
    std::lock_guard lock(mu_);
    if (items_[slot] == item) return slices_[slot];
  }
  const std::string bytes = item->SerializeAsString();
  grpc::Slice slice(bytes);
  std::lock_guard lock(mu_);
  if (seq + kSlots > newest_) {  // recent: cache it (a replay of old history does not evict live items)
    newest_ = std::max(newest_, seq);
    items_[slot] = item;
    slices_[slot] = slice;
  }
  return slice;
}

grpc::ByteBuffer EncodePoseForSubscriber(const grpc::Slice& encoded, uint64_t dropped) {
  if (dropped == 0) return grpc::ByteBuffer(&encoded, 1);
  using google::protobuf::io::CodedOutputStream;
  uint8_t tail[16];
  uint8_t* end = CodedOutputStream::WriteTagToArray(
      static_cast<uint32_t>(v1::PoseUpdate::kDroppedForSubscriberFieldNumber) << 3, tail);  // varint wire type
  end = CodedOutputStream::WriteVarint64ToArray(dropped, end);
  const grpc::Slice slices[2] = {encoded, grpc::Slice(tail, static_cast<size_t>(end - tail))};
  return grpc::ByteBuffer(slices, 2);
}

// -------------------------------------------------------------- service --

LocalizationService::LocalizationService(ServerConfig config, EstimatorFactory estimator_factory)
    : config_(std::move(config)), estimator_factory_(std::move(estimator_factory)) {
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

Status LocalizationService::FindSession(const std::string& id, std::shared_ptr<Session>* out,
                                        std::shared_ptr<PoseEncodings>* encodings) const {
  if (id.empty()) return Invalid("session_id: required");
  std::lock_guard lock(mu_);
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return {StatusCode::NOT_FOUND, "session " + Quoted(id) + " not found"};
  *out = it->second.session;
  if (encodings) *encodings = it->second.encodings;
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

Status LocalizationService::ResolveScenario(const v1::Scenario& s, fusion::Scenario* out, std::string* name) const {
  try {
    switch (s.kind_case()) {
      case v1::Scenario::kYaml:
        *out = ScenarioFromYaml(s.yaml());
        *name = out->name.empty() ? "yaml" : out->name;
        break;
      case v1::Scenario::kName:
        *out = ScenarioFromName(s.name());
        *name = s.name();
        break;
      case v1::Scenario::KIND_NOT_SET:
        *out = ScenarioFromName(config_.default_scenario);
        *name = config_.default_scenario;
        break;
    }
  } catch (const std::exception& e) {
    return Invalid(std::string("scenario: ") + e.what());
  }
  return Status::OK;
}

std::vector<prometheus::MetricFamily> LocalizationService::CollectMetrics() const {
  std::vector<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, e] : sessions_) sessions.push_back(e.session);
  }
  std::vector<SessionMetrics> snapshots;
  ServerFigures figures;
  for (const auto& s : sessions) {
    snapshots.emplace_back(s->id(), s->Metrics());
    figures.render_queue += snapshots.back().second.state == v1::SESSION_STATE_STARTING ? 1 : 0;
  }
  figures.max_concurrent_renders = config_.max_concurrent_renders;
  figures.rendered_drive_bytes = DirectoryBytes(SyntheticRoot(config_.work_dir).string());
  figures.resident_memory_bytes = ResidentMemoryBytes();
  return BuildMetricFamilies(snapshots, figures);
}

std::vector<std::shared_ptr<Session>> LocalizationService::PruneEndedLocked() {
  const int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::system_clock::now().time_since_epoch()).count();
  const auto ttl_ns = static_cast<int64_t>(config_.ended_session_ttl_s * 1e9);
  std::vector<std::pair<int64_t, std::string>> ended;  // (ended at, id)
  std::vector<std::shared_ptr<Session>> pruned;
  for (const auto& [id, e] : sessions_) {
    const int64_t at = e.session->ended_unix_ns();
    if (at > 0) ended.emplace_back(at, id);
  }
  std::sort(ended.begin(), ended.end());
  for (size_t i = 0; i < ended.size(); ++i) {
    const bool too_many = ended.size() - i > config_.max_ended_sessions;
    if (!too_many && now - ended[i].first <= ttl_ns) continue;
    pruned.push_back(sessions_.at(ended[i].second).session);
    sessions_.erase(ended[i].second);
  }
  return pruned;
}

Status LocalizationService::AddSession(SessionOptions options, std::unique_ptr<SessionPipeline> pipeline,
                                       LiveFrameSource* live, std::string* id) {
  std::vector<std::shared_ptr<Session>> pruned;  // destroyed after the lock
  std::lock_guard lock(mu_);
  pruned = PruneEndedLocked();
  if (shutting_down_) return {StatusCode::UNAVAILABLE, "server is shutting down"};
  size_t active = 0;
  for (const auto& [k, e] : sessions_) {
    const auto st = e.session->state();
    active += (st == v1::SESSION_STATE_RUNNING || st == v1::SESSION_STATE_STARTING) ? 1 : 0;
  }
  if (active >= config_.max_sessions) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "max_sessions (" + std::to_string(config_.max_sessions) + ") sessions are running; stop one first"};
  }
  if (!pipeline->ready()) {  // it prepares its input (renders) first
    size_t preparing = 0;
    for (const auto& [k, e] : sessions_) preparing += e.session->state() == v1::SESSION_STATE_STARTING ? 1 : 0;
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

Status LocalizationService::DoStart(const v1::StartSessionRequest& req, std::string* id) {
  // Pacing divides the sensor time by the rate: outside [1e-3, 1e3] it
  // overflows or is meaningless (1e-300 played at full speed).
  const double rate = req.playback_rate();
  if (!Finite(rate) || (rate != 0 && (rate < kMinPlaybackRate || rate > kMaxPlaybackRate))) {
    std::ostringstream got;
    got << rate;
    return Invalid("playback_rate: must be 0 (as fast as possible) or in [0.001, 1000], got " + got.str());
  }
  SessionOptions options;
  options.playback_rate = req.playback_rate();
  options.vo_method = req.vo_method().empty() ? config_.default_vo_method : req.vo_method();
  options.history_size = req.history_size() == 0 ? config_.history_size
                                                  : std::min<size_t>(req.history_size(), config_.max_history_size);
  EstimatorSetup setup;
  setup.vo_method = options.vo_method;
  if (Status s = ResolveScenario(req.scenario(), &setup.scenario, &options.scenario); !s.ok()) return s;

  std::unique_ptr<FrameSource> source;
  LiveFrameSource* live = nullptr;
  try {
    switch (req.source_case()) {
      case v1::StartSessionRequest::kKitti: {
        const auto& k = req.kitti();
        if (k.path().empty()) return Invalid("kitti.path: required");
        if (k.path().size() > PATH_MAX) {
          return Invalid("kitti.path: " + std::to_string(k.path().size()) + " bytes, longer than PATH_MAX (" +
                         std::to_string(PATH_MAX) + ")");
        }
        std::error_code ec;
        if (!std::filesystem::exists(k.path(), ec)) return Invalid("kitti.path " + Quoted(k.path()) + ": does not exist");
        if (!std::filesystem::is_directory(k.path(), ec)) {
          return Invalid("kitti.path " + Quoted(k.path()) + ": not a directory");
        }
        if (k.first_frame() < 0) return Invalid("kitti.first_frame: must be >= 0");
        if (k.last_frame() > 0 && k.last_frame() < k.first_frame()) {
          return Invalid("kitti.last_frame " + std::to_string(k.last_frame()) + ": before first_frame " +
                         std::to_string(k.first_frame()) + " (last_frame <= 0 plays to the end)");
        }
        // A bad OXTS file mid-drive is skipped and counted (DatasetFrameSource
        // reports it as bad OXTS lines), not a refused drive.
        kitti::RawDriveOptions open_options;
        open_options.skip_bad_oxts = true;
        auto dataset = kitti::OpenDataset(k.path(), open_options);
        if (dataset->size() == 0) return {StatusCode::FAILED_PRECONDITION, "kitti.path " + Quoted(k.path()) + ": no frames"};
        if (static_cast<size_t>(k.first_frame()) >= dataset->size()) {
          return Invalid("kitti.first_frame " + std::to_string(k.first_frame()) + ": the drive has " +
                         std::to_string(dataset->size()) + " frames");
        }
        // A drive without stereo pairs (no image_01/, say) would "finish"
        // with no poses: refuse it now.
        const size_t last = k.last_frame() <= 0 ? dataset->size() - 1
                                                : std::min(dataset->size() - 1, static_cast<size_t>(k.last_frame()));
        bool any_stereo = false;
        for (size_t i = static_cast<size_t>(k.first_frame()); i <= last && !any_stereo; ++i)
          any_stereo = dataset->has_stereo(i);
        if (!any_stereo) {
          return {StatusCode::FAILED_PRECONDITION, "kitti.path " + Quoted(k.path()) + ": no frame in [" +
                                                       std::to_string(k.first_frame()) + ", " + std::to_string(last) +
                                                       "] has both a left and a right image (image_00/, image_01/)"};
        }
        options.source = "kitti:" + k.path();
        source = std::make_unique<DatasetFrameSource>(std::move(dataset), k.first_frame(),
                                                      k.last_frame() <= 0 ? -1 : k.last_frame());
        break;
      }
      case v1::StartSessionRequest::kSynthetic: {
        const auto& s = req.synthetic();
        const size_t frames = s.frames() == 0 ? config_.synthetic_default_frames : s.frames();
        if (frames < 2 || frames > config_.max_synthetic_frames) {
          return Invalid("synthetic.frames: must be in [2, max_synthetic_frames=" +
                         std::to_string(config_.max_synthetic_frames) + "], got " + std::to_string(frames));
        }
        try {
          ValidateSyntheticRequest(s.seed(), frames, s.options_yaml(), config_.max_synthetic_frames);
        } catch (const SyntheticError& e) {
          return Invalid(e.what());
        }
        options.source = "synthetic:seed=" + std::to_string(s.seed()) + ",frames=" + std::to_string(frames);
        // Rendered on the session thread (can take seconds); failures fail the session.
        // Each session renders its own folder and deletes it when its
        // pipeline ends, so rendered drives never outlive their sessions.
        const std::filesystem::path drive_dir = SyntheticRoot(config_.work_dir) / RandomSessionId();
        auto factory = [drive_dir, seed = s.seed(), frames, yaml = s.options_yaml(), setup,
                        make = estimator_factory_](const std::atomic<bool>& cancel) mutable
            -> std::unique_ptr<SessionPipeline> {
          auto src = std::make_unique<DatasetFrameSource>(
              MakeSyntheticDrive(drive_dir, seed, frames, yaml, &cancel), 0, -1);
          setup.camera = src->camera();
          setup.T_cam0_imu = src->T_cam0_imu();
          if (src->duration_s() > 0) setup.scenario = PlaceScenarioOutages(setup.scenario, src->duration_s());
          return std::make_unique<SourcePipeline>(std::move(src), make(setup));
        };
        auto remove_drive = [drive_dir] {
          std::error_code ec;
          std::filesystem::remove_all(drive_dir, ec);
        };
        return AddSession(std::move(options),
                          std::make_unique<DeferredPipeline>(std::move(factory), static_cast<int64_t>(frames),
                                                             std::move(remove_drive)),
                          nullptr, id);
      }
      case v1::StartSessionRequest::kLive: {
        LiveCameraSetup cam;
        if (Status st = ParseLiveSource(req.live(), &cam); !st.ok()) return st;
        auto src = std::make_unique<LiveFrameSource>(cam);
        live = src.get();
        options.source = "live";
        source = std::move(src);
        break;
      }
      case v1::StartSessionRequest::SOURCE_NOT_SET:
        return Invalid("source: one of kitti, synthetic or live is required");
    }
  } catch (const kitti::Error& e) {
    return {StatusCode::FAILED_PRECONDITION, std::string("cannot open input: ") + e.what()};
  } catch (const SyntheticError& e) {
    return {StatusCode::FAILED_PRECONDITION, std::string("synthetic drive: ") + e.what()};
  } catch (const std::invalid_argument& e) {
    return Invalid(e.what());
  }
  setup.camera = source->camera();
  setup.T_cam0_imu = source->T_cam0_imu();
  // Scenarios like "tunnel-30s" place their outage relative to the drive.
  if (source->duration_s() > 0) setup.scenario = PlaceScenarioOutages(setup.scenario, source->duration_s());
  std::unique_ptr<FrameEstimator> estimator;
  try {
    estimator = estimator_factory_(setup);
  } catch (const std::exception& e) {
    return Invalid(std::string("vo_method/scenario: ") + e.what());
  }
  return AddSession(std::move(options), std::make_unique<SourcePipeline>(std::move(source), std::move(estimator)),
                    live, id);
}

Status LocalizationService::StartLive(const v1::PushStart& start, std::shared_ptr<Session>* session,
                                      LiveFrameSource** live) {
  if (!start.session_id().empty()) {
    std::lock_guard lock(mu_);
    auto it = sessions_.find(start.session_id());
    if (it == sessions_.end()) return {StatusCode::NOT_FOUND, "session " + Quoted(start.session_id()) + " not found"};
    if (!it->second.live) {
      return {StatusCode::FAILED_PRECONDITION, "session " + Quoted(start.session_id()) + " is not a live session"};
    }
    if (it->second.live_attached) {
      return {StatusCode::FAILED_PRECONDITION,
              "session " + Quoted(start.session_id()) + " already has a PushSensorData stream"};
    }
    if (it->second.session->state() != v1::SESSION_STATE_RUNNING) {
      return {StatusCode::FAILED_PRECONDITION, "session " + Quoted(start.session_id()) + " is not running"};
    }
    it->second.live_attached = true;
    *session = it->second.session;
    *live = it->second.live;
    return Status::OK;
  }
  v1::StartSessionRequest req;
  *req.mutable_live() = start.live();
  *req.mutable_scenario() = start.scenario();
  req.set_vo_method(start.vo_method());
  req.set_history_size(start.history_size());
  std::string id;
  if (Status s = DoStart(req, &id); !s.ok()) return s;
  std::lock_guard lock(mu_);
  auto& e = sessions_.at(id);
  e.live_attached = true;
  *session = e.session;
  *live = e.live;
  return Status::OK;
}

grpc::ServerUnaryReactor* LocalizationService::StartSession(grpc::CallbackServerContext* ctx,
                                                            const v1::StartSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::string id;
  Status s = DoStart(*req, &id);
  if (s.ok()) {
    std::shared_ptr<Session> session;
    s = FindSession(id, &session);
    if (s.ok()) *resp = session->ToProto();
  }
  return Reply(ctx, s);
}

grpc::ServerUnaryReactor* LocalizationService::GetSession(grpc::CallbackServerContext* ctx,
                                                          const v1::GetSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = FindSession(req->session_id(), &session);
  if (s.ok()) *resp = session->ToProto();
  return Reply(ctx, s);
}

grpc::ServerUnaryReactor* LocalizationService::ListSessions(grpc::CallbackServerContext* ctx,
                                                            const v1::ListSessionsRequest*,
                                                            v1::ListSessionsResponse* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::vector<std::shared_ptr<Session>> all, pruned;
  {
    std::lock_guard lock(mu_);
    pruned = PruneEndedLocked();
    for (const auto& [id, e] : sessions_) all.push_back(e.session);
  }
  for (const auto& s : all) *resp->add_sessions() = s->ToProto();
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::StopSession(grpc::CallbackServerContext* ctx,
                                                           const v1::StopSessionRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = FindSession(req->session_id(), &session);
  if (!s.ok()) return Reply(ctx, s);
  session->Stop();
  session->Join();
  *resp = session->ToProto();
  if (req->remove()) {
    std::lock_guard lock(mu_);
    sessions_.erase(req->session_id());
  }
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::GetStats(grpc::CallbackServerContext* ctx,
                                                        const v1::GetStatsRequest* req, v1::SessionStats* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  Status s = FindSession(req->session_id(), &session);
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
  std::shared_ptr<Session> session;
  std::shared_ptr<PoseEncodings> encodings;
  if (Status s = FindSession(req.session_id(), &session, &encodings); !s.ok()) return fail(s);
  if (req.queue_size() > config_.max_queue_size) {
    return fail(Invalid("queue_size: " + std::to_string(req.queue_size()) + " exceeds the server's max_queue_size " +
                        std::to_string(config_.max_queue_size)));
  }
  if (session->hub().subscriber_count() >= config_.max_subscribers_per_session) {
    return fail(Status(StatusCode::RESOURCE_EXHAUSTED, "session " + Quoted(req.session_id()) + " has " +
                                                           std::to_string(config_.max_subscribers_per_session) +
                                                           " subscribers (max_subscribers_per_session)"));
  }
  const size_t queue = req.queue_size() == 0 ? config_.queue_size : req.queue_size();
  return new PoseWriter(this, std::move(session), std::move(encodings), req.from_start(), ctx->peer(), queue);
}

grpc::ServerUnaryReactor* LocalizationService::InjectOutage(grpc::CallbackServerContext* ctx,
                                                            const v1::InjectOutageRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  if (Status s = FindSession(req->session_id(), &session); !s.ok()) return Reply(ctx, s);
  if (Status s = RequireActive(*session, "InjectOutage"); !s.ok()) return Reply(ctx, s);
  const double start_s = req->start_s(), duration_s = req->duration_s();
  if (!Finite(start_s) || !Finite(duration_s) || duration_s < 0) {
    return Reply(ctx, Invalid("start_s/duration_s: must be finite, duration_s >= 0"));
  }
  switch (req->action()) {
    case v1::InjectOutageRequest::START_NOW:
      session->Post([duration_s](SessionPipeline& p) { p.StartOutageNow(duration_s); });
      break;
    case v1::InjectOutageRequest::STOP_NOW:
      session->Post([](SessionPipeline& p) { p.StopOutage(); });
      break;
    case v1::InjectOutageRequest::WINDOW:
      if (start_s < 0 || duration_s <= 0) {
        return Reply(ctx, Invalid("WINDOW: start_s must be >= 0 and duration_s > 0"));
      }
      session->Post([start_s, duration_s](SessionPipeline& p) { p.AddOutageWindow(start_s, duration_s); });
      break;
    default:
      return Reply(ctx, Invalid("action: must be START_NOW, STOP_NOW or WINDOW"));
  }
  *resp = session->ToProto();
  return Reply(ctx, Status::OK);
}

grpc::ServerUnaryReactor* LocalizationService::SetScenario(grpc::CallbackServerContext* ctx,
                                                           const v1::SetScenarioRequest* req, v1::Session* resp) {
  if (Status s = Authorize(ctx); !s.ok()) return Reply(ctx, s);
  std::shared_ptr<Session> session;
  if (Status s = FindSession(req->session_id(), &session); !s.ok()) return Reply(ctx, s);
  if (Status s = RequireActive(*session, "SetScenario"); !s.ok()) return Reply(ctx, s);
  if (req->scenario().kind_case() == v1::Scenario::KIND_NOT_SET) return Reply(ctx, Invalid("scenario: required"));
  fusion::Scenario scenario;
  std::string name;
  if (Status s = ResolveScenario(req->scenario(), &scenario, &name); !s.ok()) return Reply(ctx, s);
  session->Post([scenario](SessionPipeline& p) { p.SetScenario(scenario); });
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
  return new PushReactor(this, ctx->peer());
}

void LocalizationService::BeginShutdown() {
  shutting_down_ = true;
  std::vector<std::shared_ptr<Session>> sessions;
  std::vector<std::shared_ptr<Waker>> streams;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, e] : sessions_) sessions.push_back(e.session);
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
  std::vector<std::shared_ptr<Session>> sessions;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, e] : sessions_) sessions.push_back(e.session);
  }
  for (const auto& s : sessions) s->Join();
}

// --------------------------------------------------------------- server --

UnixPathState InspectUnixSocketPath(const std::string& path) {
  const std::string where = "listen_unix '" + path + "': ";
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return UnixPathState::kAbsent;
    throw std::runtime_error(where + "cannot examine the path: " + std::strerror(errno));
  }
  if (!S_ISSOCK(st.st_mode)) {
    const char* kind = S_ISREG(st.st_mode)   ? "a regular file"
                       : S_ISDIR(st.st_mode) ? "a directory"
                       : S_ISLNK(st.st_mode) ? "a symbolic link"
                                             : "not a socket";
    throw std::runtime_error(where + "exists and is " + kind + ", not a socket; not replacing it");
  }
  // A socket file: stale when connecting is refused. Non-blocking, so a live
  // server with a full accept backlog answers EAGAIN instead of blocking us.
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error(where + "socket(): " + std::strerror(errno));
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), std::min(path.size(), sizeof(addr.sun_path) - 1));
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  const int err = rc == 0 ? 0 : errno;
  ::close(fd);
  if (err == ECONNREFUSED) return UnixPathState::kStaleSocket;
  if (err == ENOENT) return UnixPathState::kAbsent;  // removed meanwhile
  if (err == 0 || err == EAGAIN || err == EINPROGRESS) {
    throw std::runtime_error(where + "another process is listening on this socket (another locaid-server?); "
                             "stop it or choose another path");
  }
  throw std::runtime_error(where + "cannot tell whether the existing socket is in use: connect(): " +
                           std::strerror(err));
}

LocalizationServer::LocalizationServer(ServerConfig config, EstimatorFactory estimator_factory)
    : config_(std::move(config)) {
  ValidateConfig(&config_);
  service_ = std::make_unique<LocalizationService>(config_, std::move(estimator_factory));
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (!config_.tls_cert_file.empty()) {
    auto read = [](const std::string& path) {
      std::ifstream in(path);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({read(config_.tls_key_file), read(config_.tls_cert_file)});
    creds = grpc::SslServerCredentials(ssl);
  } else {
    creds = grpc::InsecureServerCredentials();
  }
  builder.AddListeningPort(config_.listen, creds, &port_);
  int unix_port = 0;  // gRPC sets 1 once the socket is bound
  if (!config_.listen_unix.empty()) {
    // gRPC 1.51 itself unlinks a socket file before bind (any socket, even a
    // live one) and refuses (EADDRINUSE) anything else; the inspection above
    // it makes "live socket" and "not a socket" clear errors, and removes a
    // stale socket here so the behaviour does not depend on gRPC's.
    if (InspectUnixSocketPath(config_.listen_unix) == UnixPathState::kStaleSocket) {
      if (::unlink(config_.listen_unix.c_str()) != 0 && errno != ENOENT) {
        throw std::runtime_error("listen_unix '" + config_.listen_unix +
                                 "': cannot remove the stale socket file: " + std::strerror(errno));
      }
      replaced_stale_socket_ = true;
    }
    builder.AddListeningPort("unix:" + config_.listen_unix, creds, &unix_port);
  }
  builder.RegisterService(service_.get());
  builder.SetMaxReceiveMessageSize(static_cast<int>(config_.max_receive_mb * 1024 * 1024));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, static_cast<int>(config_.keepalive_time_s * 1000));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, static_cast<int>(config_.keepalive_timeout_s * 1000));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 5000);
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) {
    if (port_ != 0 && !config_.listen_unix.empty() && unix_port == 0) {
      throw std::runtime_error("listen_unix '" + config_.listen_unix +
                               "': cannot bind (the directory is not writable, or see gRPC's message above)");
    }
    throw std::runtime_error("listen " + config_.listen + ": cannot bind");
  }
  if (!config_.listen_unix.empty()) {
    // Owner and group may connect (connecting needs write permission on the
    // socket file); until this chmod the file has 0777 & ~umask. gRPC
    // removes the file again when the server shuts down (UnixSocketTest
    // checks it).
    if (::chmod(config_.listen_unix.c_str(), 0660) != 0) {
      const std::string reason = std::strerror(errno);
      server_->Shutdown(std::chrono::system_clock::now());
      throw std::runtime_error("listen_unix '" + config_.listen_unix + "': cannot make the socket file 0660: " +
                               reason);
    }
  }
  // Health answers for the server ("") and for the service by its full name.
  server_->GetHealthCheckService()->SetServingStatus(true);
  server_->GetHealthCheckService()->SetServingStatus(kServiceName, true);
  if (!config_.metrics_listen.empty()) {
    LocalizationService* service = service_.get();
    metrics_ = std::make_unique<MetricsExporter>(config_.metrics_listen, [service] { return service->CollectMetrics(); });
  }
  if (!config_.port_file.empty()) {
    std::ofstream(config_.port_file) << port_ << "\n";
  }
}

LocalizationServer::~LocalizationServer() { Shutdown(); }

void LocalizationServer::Shutdown() {
  std::call_once(shutdown_once_, [this] {
    const auto t0 = std::chrono::steady_clock::now();
    auto ms = [&t0] {
      return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    };
    server_->GetHealthCheckService()->SetServingStatus(false);
    server_->GetHealthCheckService()->SetServingStatus(kServiceName, false);
    metrics_.reset();  // its threads stop before the sessions go
    service_->BeginShutdown();
    // Every stream was just told to end with UNAVAILABLE; once all have
    // delivered that status nothing is left to wait for, so idle client
    // connections (which grpc::Server::Shutdown(deadline) would wait on for
    // the whole grace time) are cut at once.
    const auto grace = std::chrono::milliseconds(static_cast<int64_t>(config_.shutdown_grace_s * 1000));
    const bool streams_done = service_->WaitForStreams(std::chrono::steady_clock::now() + grace);
    server_->Shutdown(streams_done ? std::chrono::system_clock::now()
                                   : std::chrono::system_clock::now() + std::chrono::milliseconds(100));
    const double grpc_ms = ms();
    service_->JoinSessions();
    if (config_.log_shutdown) {
      std::fprintf(stderr, "locaid-server: shutdown: rpcs done after %.0f ms, sessions joined after %.0f ms\n",
                   grpc_ms, ms());
    }
  });
}

void LocalizationServer::Wait() { server_->Wait(); }

}  // namespace locaid::server
