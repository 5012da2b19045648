#include "server/session.hpp"

#include "output/pose_message.hpp"
#include "server/pair_helper.hpp"

#include <Eigen/Geometry>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <exception>
#include <optional>
#include <system_error>

namespace locaid::server {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

Session::Session(SessionOptions options, std::unique_ptr<pipeline::RunLoop> loop)
    : options_(std::move(options)),
      loop_(std::move(loop)),
      hub_(options_.history_size),
      lagged_(options_.id, options_.history_size),
      created_unix_ns_(UnixNowNs()),
      total_frames_(loop_->total_frames()),
      pacer_(options_.playback_rate),
      monitor_(options_.playback_rate, options_.behind_threshold_s),
      created_steady_(Clock::now()) {}

double Session::age_s() const { return std::chrono::duration<double>(Clock::now() - created_steady_).count(); }

Session::~Session() {
  Stop();
  Join();
}

void Session::Start() {
  state_ = loop_->ready() ? locaid::v1::SESSION_STATE_RUNNING : locaid::v1::SESSION_STATE_STARTING;
  // Subscriber wakes (which start gRPC writes) run on the hub's fan-out
  // thread, so 1000 subscribers do not slow the pipeline; joined in Join().
  hub_.StartFanoutThread();
  thread_ = std::thread([this] { Run(); });
}

void Session::Stop() {
  stop_ = true;
  for (auto from : {locaid::v1::SESSION_STATE_STARTING, locaid::v1::SESSION_STATE_RUNNING}) {
    if (state_.compare_exchange_strong(from, locaid::v1::SESSION_STATE_STOPPED)) break;
  }
  {
    std::lock_guard lock(wait_mu_);
  }
  wait_cv_.notify_all();
  loop_->Cancel();
}

void Session::Join() {
  std::lock_guard lock(join_mu_);
  if (joined_) return;
  if (thread_.joinable()) thread_.join();
  hub_.Close();
  hub_.StopFanoutThread();  // after a last wake round (streams see kEnd)
  lagged_.Close();          // after the smoothing thread's flush
  joined_ = true;
}

void Session::Post(Command command) {
  std::lock_guard lock(commands_mu_);
  commands_.push_back(std::move(command));
  loop_->Wake();
}

void Session::set_scenario_name(const std::string& name) {
  std::lock_guard lock(stats_mu_);
  options_.scenario = name;
}

void Session::RunCommands() {
  std::deque<Command> todo;
  {
    std::lock_guard lock(commands_mu_);
    todo.swap(commands_);
  }
  for (Command& c : todo) {
    try {
      c(*loop_);
    } catch (const std::exception& e) {
      std::lock_guard lock(stats_mu_);
      error_ = std::string("command failed: ") + e.what();
    }
  }
}

bool Session::Pace(int64_t t_ns, std::optional<Clock::time_point>* due) {
  *due = pacer_.Due(t_ns);
  if (*due) {
    monitor_.NoteWaiting(**due);
    std::unique_lock lock(wait_mu_);
    wait_cv_.wait_until(lock, **due, [this] { return stop_.load(); });
  }
  return !stop_;
}

void Session::NoteOrigin() {
  std::lock_guard lock(stats_mu_);
  if (!has_origin_) has_origin_ = loop_->origin(&origin_[0], &origin_[1], &origin_[2]);
}

void Session::Publish(const pipeline::StepResult& r, double latency_ms, std::optional<Clock::time_point> due) {
  auto msg = std::make_shared<PoseMessage>();
  output::FillPoseUpdate(r, latency_ms, msg.get());
  const double behind_s = monitor_.NotePose(r.t_ns, due, Clock::now());
  msg->set_behind_real_time_s(behind_s);
  msg->set_falling_behind(behind_s > monitor_.threshold_s());
  msg->set_session_id(options_.id);
  msg->set_sequence(sequence_++);
  counters_.Record(r, latency_ms);
  NoteOrigin();
  msg->set_published_unix_ns(UnixNowNs());
  const Hub::Item item = std::move(msg);
  hub_.Publish(item);
  lagged_.OnPose(r, latency_ms, item, options_.estimator.get());  // nothing without a lagged subscriber
}

bool Session::StepOnce() {
  RunCommands();
  lagged_.BeforeStep(options_.estimator.get());
  const auto t0 = Clock::now();
  pipeline::StepResult r = loop_->Step();
  const auto t1 = Clock::now();
  const double step_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  monitor_.NoteCpu(t1, helper_ ? helper_->cpu_seconds() : 0.0);
  auto starting = locaid::v1::SESSION_STATE_STARTING;
  if (loop_->ready()) state_.compare_exchange_strong(starting, locaid::v1::SESSION_STATE_RUNNING);
  switch (r.kind) {
    case pipeline::StepResult::Kind::kEnd: {
      auto running = locaid::v1::SESSION_STATE_RUNNING;  // a Stop() meanwhile made it STOPPED
      state_.compare_exchange_strong(running, locaid::v1::SESSION_STATE_FINISHED);
      return false;
    }
    case pipeline::StepResult::Kind::kIdle:
    case pipeline::StepResult::Kind::kFused:
      if (r.oxts_bad_lines > 0) counters_.Record(r, 0);
      return true;
    case pipeline::StepResult::Kind::kPose: {
      const double latency_ms = r.processing_ms >= 0 ? r.processing_ms : step_ms;
      std::optional<Clock::time_point> due;
      if (!Pace(r.t_ns, &due)) return false;
      Publish(r, latency_ms, due);
      return true;
    }
    default:  // skipped or corrupt input: counted
      counters_.Record(r, r.processing_ms >= 0 ? r.processing_ms : step_ms);
      return true;
  }
}

void Session::Run() {
  // Batch sessions yield to real-time ones (Linux: per-thread nice, +10 from
  // the nice the server was started with, at most 19; raising it needs no
  // privilege). A failure leaves the thread at the server's priority. The
  // decode helper is told the same nice (PairHelper sets its own thread's).
  int nice = 0;
  if (!realtime()) {
    errno = 0;
    const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
    if (errno == 0 && base < 19) {
      nice = std::min(19, base + kBatchNice);
      (void)setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice);
    }
  }
  // The left image of each frame decodes here, the right one on the helper.
  std::optional<PairHelper> helper;
  try {
    helper.emplace(nice);
    loop_->SetPairRunner(&*helper);
    helper_ = &*helper;
  } catch (const std::system_error&) {  // no thread to be had: this thread decodes both
  }
  try {
    while (!stop_ && StepOnce()) {
    }
  } catch (const std::exception& e) {
    // Stopping cancels input preparation (a render throws): that is a stop,
    // not a failure.
    for (auto from : {locaid::v1::SESSION_STATE_STARTING, locaid::v1::SESSION_STATE_RUNNING}) {
      if (stop_ || !state_.compare_exchange_strong(from, locaid::v1::SESSION_STATE_FAILED)) continue;
      std::lock_guard lock(stats_mu_);
      error_ = e.what();
      break;
    }
  }
  // The lagged streams' last lag seconds, smoothed, before their end (and
  // before the estimator the log is attached to goes).
  lagged_.Finish();
  try {
    loop_->SetPairRunner(nullptr);
    loop_->Release();
  } catch (const std::exception&) {  // freeing must not turn a finished session into a crash
  }
  helper_ = nullptr;
  helper.reset();
  monitor_.NoteEnded();
  ended_unix_ns_ = UnixNowNs();
  hub_.Close();
}

Session::MetricsSnapshot Session::Metrics() const {
  MetricsSnapshot m = counters_.Metrics();
  m.stats = Stats();
  m.state = state_.load();
  return m;
}

locaid::v1::SessionStats Session::Stats() const {
  locaid::v1::SessionStats s = counters_.Stats();
  monitor_.Fill(&s, Clock::now());
  const pipeline::LiveInputStats in = loop_->input_stats();
  s.set_imu_samples(in.imu_samples);
  s.set_speed_samples(in.speed_samples);
  s.set_gps_fixes_in(in.gps_fixes_in);
  s.set_gps_fixes_late(in.gps_fixes_late);
  s.set_gps_no_fix(in.gps_no_fix);
  s.set_sensor_items_rejected(in.sensor_rejected);
  if (!in.last_error.empty() && s.last_input_error().empty()) s.set_last_input_error(in.last_error);
  if (in.has_gpsd) {
    auto* g = s.mutable_gpsd();
    g->set_connected(in.gpsd_connected);
    g->set_connects(in.gpsd_connects);
    g->set_connection_losses(in.gpsd_losses);
    g->set_last_error(in.gpsd_error);
  }
  if (in.has_camera) {
    auto* c = s.mutable_camera();
    c->set_running(in.camera_running);
    c->set_pairs(in.camera_pairs);
    c->set_unpaired(in.camera_unpaired);
    c->set_dropped_late(in.camera_dropped_late);
    c->set_restarts(in.camera_restarts);
    c->set_last_error(in.camera_error);
  }
  if (in.fix_latency_max_ms > 0) {
    auto* g = s.mutable_gpsd();
    g->set_fix_latency_median_ms(in.fix_latency_median_ms);
    g->set_fix_latency_max_ms(in.fix_latency_max_ms);
  }
  HubStats h = hub_.stats();
  s.set_poses_published(h.published);  // the causal poses
  HubStats lagged = lagged_.stats();   // subscribers of lagged streams count too
  h.subscribers.insert(h.subscribers.end(), lagged.subscribers.begin(), lagged.subscribers.end());
  s.set_subscribers(static_cast<uint32_t>(h.subscribers.size()));
  s.set_dropped_total(h.dropped_total + lagged.dropped_total);
  for (const SubscriberInfo& i : h.subscribers) {
    auto* out = s.add_subscriber();
    out->set_id(i.id);
    out->set_peer(i.peer);
    out->set_delivered(i.delivered);
    out->set_dropped(i.dropped);
    out->set_queued(static_cast<uint32_t>(i.queued));
  }
  return s;
}

locaid::v1::Session Session::ToProto() const {
  locaid::v1::Session out;
  out.set_id(options_.id);
  out.set_state(state_.load());
  out.set_source(options_.source);
  out.set_vo_method(options_.vo_method);
  out.set_playback_rate(options_.playback_rate);
  out.set_total_frames(total_frames_);
  out.set_created_unix_ns(created_unix_ns_);
  out.set_ended_unix_ns(ended_unix_ns_.load());
  out.set_history_capacity(static_cast<uint32_t>(options_.history_size));
  {
    std::lock_guard lock(stats_mu_);
    out.set_scenario(options_.scenario);
    out.set_error(error_.empty() ? counters_.Stats().last_input_error() : error_);
    out.set_has_origin(has_origin_);
    out.set_origin_latitude_deg(origin_[0]);
    out.set_origin_longitude_deg(origin_[1]);
    out.set_origin_altitude_m(origin_[2]);
  }
  *out.mutable_stats() = Stats();
  return out;
}

}  // namespace locaid::server
