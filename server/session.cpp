#include "server/session.hpp"

#include "server/pose_message.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <exception>

namespace locaid::server {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

Session::Session(SessionOptions options, std::unique_ptr<pipeline::Pipeline> pipeline)
    : options_(std::move(options)),
      pipeline_(std::move(pipeline)),
      hub_(options_.history_size),
      created_unix_ns_(UnixNowNs()),
      total_frames_(pipeline_->total_frames()) {}

Session::~Session() {
  Stop();
  Join();
}

void Session::Start() {
  state_ = pipeline_->ready() ? locaid::v1::SESSION_STATE_RUNNING : locaid::v1::SESSION_STATE_STARTING;
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
  pipeline_->Cancel();
}

void Session::Join() {
  std::lock_guard lock(join_mu_);
  if (joined_) return;
  if (thread_.joinable()) thread_.join();
  hub_.Close();
  hub_.StopFanoutThread();  // after a last wake round (streams see kEnd)
  joined_ = true;
}

void Session::Post(Command command) {
  std::lock_guard lock(commands_mu_);
  commands_.push_back(std::move(command));
  pipeline_->Wake();
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
      c(*pipeline_);
    } catch (const std::exception& e) {
      std::lock_guard lock(stats_mu_);
      error_ = std::string("command failed: ") + e.what();
    }
  }
}

bool Session::Pace(int64_t t_ns) {
  if (options_.playback_rate <= 0) return !stop_;
  if (!paced_) {
    paced_ = true;
    pace_t0_ns_ = t_ns;
    pace_w0_ = Clock::now();
    return !stop_;
  }
  const double dt_s = static_cast<double>(t_ns - pace_t0_ns_) * 1e-9 / options_.playback_rate;
  const auto due = pace_w0_ + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(std::max(0.0, dt_s)));
  std::unique_lock lock(wait_mu_);
  wait_cv_.wait_until(lock, due, [this] { return stop_.load(); });
  return !stop_;
}

void Session::Record(const pipeline::StepResult& r, double latency_ms) {
  std::lock_guard lock(stats_mu_);
  if (r.kind != pipeline::StepResult::Kind::kIdle && r.kind != pipeline::StepResult::Kind::kEnd && r.kind != pipeline::StepResult::Kind::kFused) {
    stats_.set_frames_in(stats_.frames_in() + 1);
  }
  stats_.set_oxts_bad_lines(stats_.oxts_bad_lines() + static_cast<uint64_t>(std::max(0, r.oxts_bad_lines)));
  if (!r.error.empty()) stats_.set_last_input_error(r.error);
  if (r.kind == pipeline::StepResult::Kind::kSkipped) stats_.set_frames_skipped(stats_.frames_skipped() + 1);
  if (r.kind == pipeline::StepResult::Kind::kCorrupt) stats_.set_frames_corrupt(stats_.frames_corrupt() + 1);
  if (r.kind == pipeline::StepResult::Kind::kPose) {
    stats_.set_frames_processed(stats_.frames_processed() + 1);
    latency_sum_ms_ += latency_ms;
    stats_.set_latency_mean_ms(latency_sum_ms_ / static_cast<double>(stats_.frames_processed()));
    stats_.set_latency_max_ms(std::max(stats_.latency_max_ms(), latency_ms));
    const auto now = Clock::now();
    recent_.push_back(now);
    while (!recent_.empty() && now - recent_.front() > std::chrono::seconds(2)) recent_.pop_front();
    if (!has_origin_) {
      has_origin_ = pipeline_->origin(&origin_[0], &origin_[1], &origin_[2]);
    }
    const fusion::FusedPose& p = r.frame.pose;
    last_.has_pose = true;
    last_.mode = p.mode;
    last_.seconds_since_gps = p.seconds_since_gps;
    last_.last_gps_nis = p.last_gps_nis;
    last_.gps_gate = p.gps_gate;
    last_.position_sigma_h_m = std::sqrt(std::max(0.0, p.covariance(0, 0) + p.covariance(1, 1)));
    last_.vo_inliers = r.frame.vo.inliers;
    last_.gps_used = p.gps_used;
    last_.gps_rejected = p.gps_rejected;
    const double latency_s = latency_ms / 1000.0;
    for (size_t b = 0; b < kLatencyBucketsS.size(); ++b) last_.latency_le[b] += latency_s <= kLatencyBucketsS[b] ? 1 : 0;
    ++last_.latency_count;
    last_.latency_sum_s += latency_s;
  }
}

void Session::Run() {
  try {
    while (!stop_) {
      RunCommands();
      const auto t0 = Clock::now();
      pipeline::StepResult r = pipeline_->Step();
      const auto t1 = Clock::now();
      auto starting = locaid::v1::SESSION_STATE_STARTING;
      if (pipeline_->ready()) state_.compare_exchange_strong(starting, locaid::v1::SESSION_STATE_RUNNING);
      if (r.kind == pipeline::StepResult::Kind::kEnd) {
        auto running = locaid::v1::SESSION_STATE_RUNNING;  // a Stop() meanwhile made it STOPPED
        state_.compare_exchange_strong(running, locaid::v1::SESSION_STATE_FINISHED);
        break;
      }
      if (r.kind == pipeline::StepResult::Kind::kIdle || r.kind == pipeline::StepResult::Kind::kFused) {
        if (r.oxts_bad_lines > 0) Record(r, 0);
        continue;
      }
      double latency_ms = r.processing_ms >= 0
                              ? r.processing_ms
                              : std::chrono::duration<double, std::milli>(t1 - t0).count();
      if (r.kind != pipeline::StepResult::Kind::kPose) {
        Record(r, latency_ms);
        continue;
      }
      if (!Pace(r.t_ns)) break;
      auto msg = std::make_shared<PoseMessage>();
      FillPoseUpdate(r, latency_ms, msg.get());
      msg->set_session_id(options_.id);
      msg->set_sequence(sequence_++);
      Record(r, latency_ms);
      msg->set_published_unix_ns(UnixNowNs());
      hub_.Publish(std::move(msg));
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
  try {
    pipeline_->Release();
  } catch (const std::exception&) {  // freeing must not turn a finished session into a crash
  }
  ended_unix_ns_ = UnixNowNs();
  hub_.Close();
}

Session::MetricsSnapshot Session::Metrics() const {
  MetricsSnapshot m;
  {
    std::lock_guard lock(stats_mu_);
    m = last_;
  }
  m.stats = Stats();
  m.state = state_.load();
  return m;
}

locaid::v1::SessionStats Session::Stats() const {
  locaid::v1::SessionStats s;
  {
    std::lock_guard lock(stats_mu_);
    s = stats_;
    const auto now = Clock::now();
    size_t n = 0;
    for (const auto& t : recent_) n += (now - t <= std::chrono::seconds(2)) ? 1 : 0;
    if (n >= 2) {
      const double span_s = std::chrono::duration<double>(recent_.back() - recent_[recent_.size() - n]).count();
      s.set_fps(span_s > 0 ? static_cast<double>(n - 1) / span_s : 0.0);
    }
  }
  const pipeline::LiveInputStats in = pipeline_->input_stats();
  s.set_imu_samples(in.imu_samples);
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
  if (in.fix_latency_max_ms > 0) {
    auto* g = s.mutable_gpsd();
    g->set_fix_latency_median_ms(in.fix_latency_median_ms);
    g->set_fix_latency_max_ms(in.fix_latency_max_ms);
  }
  const HubStats h = hub_.stats();
  s.set_poses_published(h.published);
  s.set_subscribers(static_cast<uint32_t>(h.subscribers.size()));
  s.set_dropped_total(h.dropped_total);
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
    out.set_error(error_.empty() ? stats_.last_input_error() : error_);
    out.set_has_origin(has_origin_);
    out.set_origin_latitude_deg(origin_[0]);
    out.set_origin_longitude_deg(origin_[1]);
    out.set_origin_altitude_m(origin_[2]);
  }
  *out.mutable_stats() = Stats();
  return out;
}

}  // namespace locaid::server
