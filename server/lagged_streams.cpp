#include "server/lagged_streams.hpp"

#include "output/pose_message.hpp"
#include "server/pose_encodings.hpp"
#include "server/session.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <sstream>
#include <system_error>
#include <utility>

namespace locaid::server {
namespace {

// The smoothing thread runs at the nice of the thread that starts it plus
// kBatchNice: the causal stream's threads win the CPU, yet the smoothing
// still gets its share on a busy machine (SCHED_IDLE would starve it there
// until its backlog bound drops poses).
void LowerThisThreadsPriority() {
  errno = 0;
  const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
  if (errno == 0 && base < 19)
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), std::min(19, base + kBatchNice));
}

// Waits until every subscriber of `hub` has room for one more pose; sets
// *patient false (and returns) after kFlushPatienceS without any of them
// taking a pose.
void WaitForRoom(const Hub& hub, bool* patient) {
  using Clock = std::chrono::steady_clock;
  uint64_t delivered = 0;
  auto progress = Clock::now();
  for (bool first = true;; first = false) {
    const HubStats h = hub.stats();
    bool room = true;
    uint64_t now_delivered = 0;
    for (const SubscriberInfo& i : h.subscribers) {
      room = room && i.queued < i.capacity;
      now_delivered += i.delivered;
    }
    if (room) return;
    if (first || now_delivered != delivered) {
      delivered = now_delivered;
      progress = Clock::now();
    } else if (Clock::now() - progress > std::chrono::duration<double>(kFlushPatienceS)) {
      *patient = false;
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

}  // namespace

std::string CheckSmoothingLag(double lag_s) {
  if (lag_s >= 0 && lag_s <= kMaxSmoothingLagS) return "";  // false for NaN
  std::ostringstream msg;
  msg << "smoothing_lag_s must be in [0, " << kMaxSmoothingLagS << "] s (got " << lag_s
      << "); 0 is the causal stream";
  return msg.str();
}

pipeline::EstimatorMaker RecordEstimator(pipeline::EstimatorMaker make, std::shared_ptr<EstimatorHandle> handle) {
  return [make = std::move(make), handle = std::move(handle)](const pipeline::EstimatorInputs& in) {
    std::unique_ptr<pipeline::Estimator> made = make(in);
    handle->estimator = made.get();
    handle->localizer = dynamic_cast<pipeline::Localizer*>(made.get());
    return made;
  };
}

LaggedStreams::LaggedStreams(std::string session_id, size_t history_size)
    : session_id_(std::move(session_id)), history_size_(history_size) {}

LaggedStreams::~LaggedStreams() { Close(); }

// ------------------------------------------------------------ any thread --

LaggedStreams::Subscription LaggedStreams::Subscribe(double lag_s, size_t queue_size, bool from_start,
                                                     std::function<void()> wake, std::string peer) {
  std::lock_guard lock(mu_);
  std::shared_ptr<Channel> channel;
  for (const auto& c : channels_)
    if (c->lag_s == lag_s) channel = c;
  if (!channel) {
    auto made = std::make_shared<Channel>();
    made->lag_s = lag_s;
    made->hub = std::make_shared<Hub>(history_size_);
    made->encodings = std::make_shared<PoseEncodings>();
    made->id_base = ++channels_made_ << 40;  // the causal hub's ids stay below 2^40
    if (finished_) {
      made->hub->Close();  // the session has ended: the subscriber gets the end at once
    } else {
      if (channels_.size() >= kMaxLagsPerSession) {
        std::vector<double> lags;
        for (const auto& c : channels_) lags.push_back(c->lag_s);
        std::sort(lags.begin(), lags.end());
        std::ostringstream msg;
        msg << "session " << session_id_ << " already smooths " << kMaxLagsPerSession << " distinct lags (";
        for (size_t i = 0; i < lags.size(); ++i) msg << (i ? ", " : "") << lags[i] << " s";
        msg << "), the most a session keeps; subscribe with one of them";
        return {nullptr, nullptr, msg.str()};
      }
      try {
        made->hub->StartFanoutThread(1);
        if (!worker_.joinable()) {
          worker_ = std::thread([this] {
            LowerThisThreadsPriority();
            Run();
          });
        }
      } catch (const std::system_error& e) {
        made->hub->StopFanoutThread();
        return {nullptr, nullptr, std::string("cannot start the smoothing thread: ") + e.what()};
      }
      channels_.push_back(made);
      changed_ = true;
    }
    channel = std::move(made);
  }
  Hub::SubscriberPtr sub = channel->hub->Subscribe(queue_size, from_start, std::move(wake), std::move(peer));
  return {std::move(channel), std::move(sub), ""};
}

size_t LaggedStreams::subscriber_count() const {
  std::lock_guard lock(mu_);
  size_t n = 0;
  for (const auto& c : channels_) n += c->hub->subscriber_count();
  return n;
}

HubStats LaggedStreams::stats() const {
  std::lock_guard lock(mu_);
  HubStats out;
  out.dropped_total = dropped_departed_;
  for (const auto& c : channels_) {
    HubStats h = c->hub->stats();
    out.dropped_total += h.dropped_total;
    for (SubscriberInfo& i : h.subscribers) {
      i.id += c->id_base;
      out.subscribers.push_back(std::move(i));
    }
  }
  return out;
}

void LaggedStreams::Close() {
  std::thread worker;
  std::vector<std::shared_ptr<Channel>> channels;
  {
    std::lock_guard lock(mu_);
    finished_ = true;
    worker = std::move(worker_);
    channels = channels_;
  }
  if (worker.joinable()) {
    {
      std::lock_guard lock(queue_mu_);
      stop_ = true;
    }
    queue_cv_.notify_all();
    worker.join();  // after what is queued (the flush)
  }
  for (const auto& c : channels) {
    c->hub->Close();
    c->hub->StopFanoutThread();
  }
}

// -------------------------------------------------------- stepping thread --

void LaggedStreams::BeforeStep(const EstimatorHandle* estimator) {
  if (changed_.load(std::memory_order_relaxed) || (!active_.empty() && !log_)) Sync(estimator);
  stepped_generation_ = log_ ? log_generation_ : 0;
}

void LaggedStreams::OnPose(const pipeline::StepResult& step, double latency_ms, const Hub::Item& causal,
                           const EstimatorHandle* estimator) {
  if (active_.empty() && !changed_.load(std::memory_order_relaxed)) return;  // no lagged subscriber
  if (!active_.empty()) DropIdleLags();
  Sync(estimator);
  if (active_.empty()) return;
  if (!enu_ && estimator && estimator->estimator && estimator->estimator->enu().has_origin())
    enu_ = std::make_shared<const fusion::EnuFrame>(estimator->estimator->enu());
  WorkItem w;
  w.kind = WorkItem::Kind::kPose;
  w.frame = std::make_shared<const Frame>(Frame{step, latency_ms, causal, enu_});
  // The step's epoch is of the log it ran with; a log attached since is a new chain.
  w.frame_epoch = log_ && stepped_generation_ == log_generation_ ? step.frame.epoch : -1;
  if (log_ && log_->open()) {
    w.epoch = *log_->open();
    w.has_open = true;
  }
  if (Push(std::move(w)) > kMaxSmoothingBacklogS) StartOver();
}

void LaggedStreams::Finish() {
  WorkItem w;
  w.kind = WorkItem::Kind::kFlush;
  {
    std::lock_guard lock(mu_);
    finished_ = true;
    if (!worker_.joinable()) return;  // never had a lagged subscriber
    w.lags = channels_;
  }
  if (log_ && log_->open()) {
    w.epoch = *log_->open();
    w.has_open = true;
  }
  Push(std::move(w));
  Detach();
  active_.clear();
}

void LaggedStreams::Sync(const EstimatorHandle* estimator) {
  // A drive rendered on the session thread builds its estimator at the first
  // step: until then the lags wait (the layout and the log need it).
  if (estimator && !estimator->estimator) return;
  pipeline::Localizer* localizer = estimator ? estimator->localizer : nullptr;
  if (changed_.exchange(false)) {
    std::vector<std::shared_ptr<Channel>> now;
    {
      std::lock_guard lock(mu_);
      now = channels_;
    }
    if (now != active_) {
      active_ = std::move(now);
      if (localizer) layout_ = localizer->ekf().error_layout();
      Push(LagsItem(WorkItem::Kind::kLags));
    }
  }
  if (active_.empty()) {
    Detach();
  } else if (!log_ && localizer) {
    log_ = std::make_unique<fusion::EpochLog>([this](fusion::Epoch&& e) {
      WorkItem item;
      item.kind = WorkItem::Kind::kEpoch;
      item.epoch = std::move(e);
      Push(std::move(item));
    });
    localizer->set_epoch_log(log_.get());
    attached_ = localizer;
    ++log_generation_;
  }
}

void LaggedStreams::DropIdleLags() {
  std::vector<std::shared_ptr<Channel>> idle;
  {
    std::lock_guard lock(mu_);
    for (const auto& c : channels_) {
      if (c->hub->subscriber_count() > 0) continue;
      idle.push_back(c);
      dropped_departed_ += c->hub->stats().dropped_total;
    }
    if (idle.empty()) return;
    std::erase_if(channels_, [&](const std::shared_ptr<Channel>& c) {
      return std::find(idle.begin(), idle.end(), c) != idle.end();
    });
  }
  changed_ = true;
  // The smoothing thread closes the lags it runs when it hears of it; one
  // that never reached it (its subscriber left at once) is closed here.
  for (const auto& c : idle) {
    if (std::find(active_.begin(), active_.end(), c) != active_.end()) continue;
    c->hub->Close();
    c->hub->StopFanoutThread();
  }
}

void LaggedStreams::Detach() {
  if (attached_) attached_->set_epoch_log(nullptr);
  attached_ = nullptr;
  log_.reset();
}

void LaggedStreams::StartOver() {
  {
    std::lock_guard lock(queue_mu_);
    queue_.clear();
    queued_pose_t_ns_.clear();
  }
  Detach();  // the next step attaches a new log
  Push(LagsItem(WorkItem::Kind::kStartOver));
}

double LaggedStreams::Push(WorkItem item) {
  double backlog_s = 0;
  bool was_empty = false;
  {
    std::lock_guard lock(queue_mu_);
    if (item.kind == WorkItem::Kind::kPose) {
      const int64_t t_ns = item.frame->step.frame.pose.t_ns;
      queued_pose_t_ns_.push_back(t_ns);
      backlog_s = static_cast<double>(t_ns - queued_pose_t_ns_.front()) * 1e-9;
    }
    was_empty = queue_.empty();
    queue_.push_back(std::move(item));
  }
  if (was_empty) queue_cv_.notify_one();  // the thread waits only on an empty queue
  return backlog_s;
}

LaggedStreams::WorkItem LaggedStreams::LagsItem(WorkItem::Kind kind) const {
  WorkItem w;
  w.kind = kind;
  w.lags = active_;
  w.layout = layout_;
  return w;
}

// ------------------------------------------------------- smoothing thread --

void LaggedStreams::Run() {
  for (;;) {
    WorkItem item;
    {
      std::unique_lock lock(queue_mu_);
      queue_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;
      item = std::move(queue_.front());
      queue_.pop_front();
      if (item.kind == WorkItem::Kind::kPose && !queued_pose_t_ns_.empty()) queued_pose_t_ns_.pop_front();
    }
    Apply(item);
    if (item.kind == WorkItem::Kind::kFlush) return;
  }
}

void LaggedStreams::Apply(WorkItem& item) {
  using Kind = WorkItem::Kind;
  const fusion::Epoch* open = item.has_open ? &item.epoch : nullptr;
  switch (item.kind) {
    case Kind::kEpoch:
      for (Lag& lag : lags_) lag.smoother.AddEpoch(item.epoch);
      return;
    case Kind::kPose:
      if (item.frame->enu) worker_enu_ = item.frame->enu;
      for (Lag& lag : lags_) {
        lag.frames.push_back(item.frame);
        Release(lag, lag.smoother.AddPose(item.frame->step.frame.pose, item.frame_epoch, open));
      }
      return;
    case Kind::kLags:
    case Kind::kStartOver: {
      const auto wanted = [&](const Lag& lag) {
        return std::find(item.lags.begin(), item.lags.end(), lag.channel) != item.lags.end();
      };
      for (Lag& lag : lags_) {
        if (wanted(lag)) continue;
        lag.channel->hub->Close();  // no subscriber left, none can come (out of the channel list)
        lag.channel->hub->StopFanoutThread();
      }
      std::erase_if(lags_, [&](const Lag& lag) { return !wanted(lag); });
      for (Lag& lag : lags_) {
        if (item.kind != Kind::kStartOver) continue;
        lag.smoother = fusion::FixedLagSmoother(lag.channel->lag_s, item.layout);
        lag.frames.clear();
      }
      for (const auto& c : item.lags) {
        const bool known = std::any_of(lags_.begin(), lags_.end(), [&](const Lag& l) { return l.channel == c; });
        if (!known) lags_.push_back(Lag{c, fusion::FixedLagSmoother(c->lag_s, item.layout), {}});
      }
      return;
    }
    case Kind::kFlush:
      for (Lag& lag : lags_) Release(lag, lag.smoother.Flush(open), /*at_end=*/true);
      lags_.clear();
      for (const auto& c : item.lags) {  // every channel, also those that never had a pose
        c->hub->Close();
        c->hub->StopFanoutThread();
      }
      return;
  }
}

void LaggedStreams::Release(Lag& lag, const std::vector<fusion::FusedPose>& poses, bool at_end) {
  bool patient = at_end;
  for (const fusion::FusedPose& pose : poses) {
    if (patient) WaitForRoom(*lag.channel->hub, &patient);
    if (lag.frames.empty()) return;
    const std::shared_ptr<const Frame> frame = std::move(lag.frames.front());
    lag.frames.pop_front();
    if (frame->step.frame.pose.t_ns != pose.t_ns) continue;  // cannot happen: the smoother keeps the order
    pipeline::StepResult step = frame->step;
    step.frame.pose = pose;
    if (worker_enu_)
      worker_enu_->ToGeodetic(pose.T_enu_body.translation(), step.frame.pose.lat_deg, step.frame.pose.lon_deg,
                              step.frame.pose.alt_m);
    auto msg = std::make_shared<PoseMessage>();
    output::FillPoseUpdate(step, frame->latency_ms, msg.get());
    const PoseMessage& causal = *frame->causal;
    msg->set_session_id(causal.session_id());
    msg->set_sequence(causal.sequence());
    msg->set_behind_real_time_s(causal.behind_real_time_s());
    msg->set_falling_behind(causal.falling_behind());
    msg->set_smoothed(true);
    msg->set_published_unix_ns(UnixNowNs());
    lag.channel->hub->Publish(std::move(msg));
  }
}

}  // namespace locaid::server
