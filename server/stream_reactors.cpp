#include "server/stream_reactors.hpp"

#include "pipeline/live_frame_source.hpp"
#include "server/push_requests.hpp"
#include "server/status.hpp"

#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

std::string ItemName(v1::PushRequest::ItemCase c) {
  switch (c) {
    case v1::PushRequest::kStart: return "start";
    case v1::PushRequest::kFrame: return "frame";
    case v1::PushRequest::kOxts: return "oxts";
    case v1::PushRequest::kImu: return "imu";
    case v1::PushRequest::kGps: return "gps";
    case v1::PushRequest::kSpeed: return "speed";
    case v1::PushRequest::ITEM_NOT_SET: break;
  }
  return "an empty message";
}

// ------------------------------------------------------- shared stream ---

// A server stream that writes hub items (and, for PushSensorData, control
// messages): one write in flight at a time, woken by the hub (through a Waker
// registered with the service, so shutdown can abort it), finished exactly
// once (after the write in flight, if any). Derived classes say what to write
// next in NextLocked(); everything else (wake, abort, write completion,
// cancel, unsubscribe, delete) is here, shared by PoseWriter and PushReactor.
// Made by New() only: other threads (the hub's wakes, shutdown's Abort) reach
// a stream once it is fully constructed, never while its constructor runs.
template <typename Reactor, typename Msg>
class HubStream : public Reactor, public StreamTarget {
 public:
  template <typename Derived, typename... Args>
  static Derived* New(ReactorHost* service, Args&&... args) {
    auto* stream = new Derived(service, std::forward<Args>(args)...);
    {
      std::lock_guard lock(stream->waker_->mu);
      stream->waker_->target = stream;
    }
    service->Register(stream->waker_);
    stream->Wake();  // what the constructor queued (a pose already in the hub)
    return stream;
  }

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
    // gRPC runs OnDone after every other reaction has returned, an ordering it
    // keeps with its own locks, which a ThreadSanitizer build of this server
    // cannot see (Debian's gRPC is not instrumented). Taking mu_, which every
    // reaction that touches the stream's state holds, makes that ordering
    // visible, so TSan reports only real races here.
    { std::lock_guard lock(mu_); }
    {
      std::lock_guard lock(waker_->mu);
      waker_->target = nullptr;
    }
    if (hub_) hub_->Unsubscribe(sub_);
    OnStreamEnded();
    service_->Unregister(waker_);
    delete this;
  }

 protected:
  enum class Next { kWrite, kIdle, kEnd };

  explicit HubStream(ReactorHost* service) : service_(service), waker_(std::make_shared<Waker>()) {}

  // With mu_ held: fills *out and returns kWrite, or sets *end and returns
  // kEnd, or returns kIdle (nothing to write until the next wake).
  virtual Next NextLocked(Msg* out, Status* end) = 0;
  // Called once from OnDone() after the hub subscription is dropped.
  virtual void OnStreamEnded() {}

  // Subscribes this stream to `session`'s hub.
  void Subscribe(std::shared_ptr<Session> session, size_t queue_size, bool from_start, std::string peer) {
    session_ = std::move(session);
    hub_ = std::shared_ptr<Hub>(session_, &session_->hub());  // kept alive by the session
    sub_ = hub_->Subscribe(queue_size, from_start, WakeCallback(), std::move(peer));
  }
  // Subscribes this stream to lag `lag_s` of `session` (its lagged streams);
  // the channel, or null with *refused saying why not.
  std::shared_ptr<LaggedStreams::Channel> SubscribeLagged(std::shared_ptr<Session> session, double lag_s,
                                                          size_t queue_size, bool from_start, std::string peer,
                                                          std::string* refused) {
    session_ = std::move(session);
    LaggedStreams::Subscription s =
        session_->lagged().Subscribe(lag_s, queue_size, from_start, WakeCallback(), std::move(peer));
    *refused = std::move(s.refused);
    if (!s.channel) return nullptr;
    hub_ = s.channel->hub;
    sub_ = std::move(s.subscriber);
    return s.channel;
  }
  // The hub's wake of this stream: through the Waker, so it never reaches a
  // deleted reactor.
  std::function<void()> WakeCallback() const {
    std::weak_ptr<Waker> weak = waker_;
    return [weak] {
      if (auto w = weak.lock()) w->Wake();
    };
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

  ReactorHost* const service_;
  const std::shared_ptr<Waker> waker_;
  std::shared_ptr<Session> session_;  // set by Subscribe() / SubscribeLagged()
  std::shared_ptr<Hub> hub_;          // the hub sub_ is of
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
// on the wire are an ordinary PoseUpdate. With a smoothing lag it writes the
// lag's poses (LaggedStreams), serialized once per lag.
class PoseWriter final : public HubStream<grpc::ServerWriteReactor<grpc::ByteBuffer>, grpc::ByteBuffer> {
 public:
  PoseWriter(ReactorHost* service, std::shared_ptr<Session> session,
             std::shared_ptr<PoseEncodings> encodings, bool from_start, std::string peer, size_t queue_size,
             double smoothing_lag_s)
      : HubStream(service), encodings_(std::move(encodings)) {
    if (smoothing_lag_s <= 0) {
      Subscribe(std::move(session), queue_size, from_start, std::move(peer));
      return;
    }
    std::string refused;
    const auto channel =
        SubscribeLagged(std::move(session), smoothing_lag_s, queue_size, from_start, std::move(peer), &refused);
    if (channel) {
      encodings_ = channel->encodings;
    } else {
      refused_ = Status(StatusCode::RESOURCE_EXHAUSTED, refused);
    }
  }

 private:
  Next NextLocked(grpc::ByteBuffer* out, Status* end) override {
    if (!sub_) {  // a lag the session could not take
      *end = refused_;
      return Next::kEnd;
    }
    Hub::Item item;
    uint64_t dropped = 0;
    const Next next = PopLocked(&item, &dropped, end);
    if (next == Next::kWrite) *out = EncodePoseForSubscriber(encodings_->Get(item), dropped);
    return next;
  }

  std::shared_ptr<PoseEncodings> encodings_;
  Status refused_;
};

// --------------------------------------------------------- PushSensorData --

class PushReactor final : public HubStream<grpc::ServerBidiReactor<v1::PushRequest, v1::PushResponse>,
                                           v1::PushResponse> {
 public:
  PushReactor(ReactorHost* service, std::string peer) : HubStream(service), peer_(std::move(peer)) {
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
        const int64_t index = frames_++;
        FrameTranslation frame = FrameItemFromProto(req_.mutable_frame(), live_->camera());
        if (!frame.rejected.empty()) {
          Reject("frame", index, frame.rejected);
          break;
        }
        if (!frame.fatal.empty()) {
          // Nothing more is read; the frames before this one are still in
          // the pipeline: their poses are delivered first, then the stream
          // ends with this status instead of OK.
          std::lock_guard lock(mu_);
          end_status_ = Invalid("frame " + std::to_string(index) + ": " + frame.fatal);
          reads_done_ = true;
          live_->CloseInput();
          return;
        }
        PushToSession(std::move(frame.item));
        return;
      }
      case v1::PushRequest::kOxts:
        ++oxts_;
        PushToSession(OxtsItemFromProto(req_.oxts()));
        return;
      case v1::PushRequest::kImu:
      case v1::PushRequest::kGps: {
        const bool imu = req_.item_case() == v1::PushRequest::kImu;
        const int64_t index = imu ? imu_++ : gps_++;
        pipeline::LiveItem item;
        const std::string error = imu ? ImuItemFromProto(req_.imu(), &item) : GpsItemFromProto(req_.gps(), &item);
        if (!error.empty()) {
          Reject(imu ? "imu" : "gps", index, error);
          break;
        }
        PushToSession(std::move(item));
        return;
      }
      case v1::PushRequest::kSpeed: {
        const int64_t index = speed_++;
        pipeline::LiveItem item;
        if (const std::string error = SpeedItemFromProto(req_.speed(), &item); !error.empty()) {
          Reject("speed", index, error);
          break;
        }
        PushToSession(std::move(item));
        return;
      }
      case v1::PushRequest::kStart:
        Reject("start", 0, "the stream already has a session; 'start' must be the first message only");
        break;
      case v1::PushRequest::ITEM_NOT_SET:
        Reject("empty", 0, "message without frame, oxts, imu, gps or speed");
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
      FinishLocked(Invalid("first message must be 'start' (got " + ItemName(req_.item_case()) + ")"));
      return;
    }
    std::shared_ptr<Session> session;
    pipeline::LiveFrameSource* live = nullptr;
    const Status status = service_->StartLive(req_.start(), &session, &live);
    std::lock_guard lock(mu_);
    if (!status.ok()) {
      FinishLocked(status);
      return;
    }
    live_ = live;
    Subscribe(std::move(session), service_->subscriber_queue_size(), false, peer_);
    v1::PushResponse first;
    *first.mutable_session() = session_->ToProto();
    control_.push_back(std::move(first));
    WriteNextLocked();
    if (open_locked()) StartRead(&req_);
  }

  void PushToSession(pipeline::LiveItem item) {
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
  pipeline::LiveFrameSource* live_ = nullptr;
  std::deque<v1::PushResponse> control_;
  bool reads_done_ = false;
  Status end_status_;  // replaces OK at the end of the stream (a refused frame)
  int64_t frames_ = 0, oxts_ = 0, imu_ = 0, gps_ = 0, speed_ = 0;
};

}  // namespace

grpc::ServerWriteReactor<grpc::ByteBuffer>* NewPoseWriter(ReactorHost* service,
                                                          std::shared_ptr<Session> session,
                                                          std::shared_ptr<PoseEncodings> encodings, bool from_start,
                                                          std::string peer, size_t queue_size,
                                                          double smoothing_lag_s) {
  return PoseWriter::New<PoseWriter>(service, std::move(session), std::move(encodings), from_start, std::move(peer),
                                     queue_size, smoothing_lag_s);
}

grpc::ServerBidiReactor<v1::PushRequest, v1::PushResponse>* NewPushReactor(ReactorHost* service,
                                                                            std::string peer) {
  return PushReactor::New<PushReactor>(service, std::move(peer));
}

}  // namespace locaid::server
