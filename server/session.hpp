// One localization session: a pipeline::RunLoop (pipeline/frame_loop.hpp) run by one thread, started by
// Start() and joined once by Join() (the server's SessionReaper, or shutdown), publishing into a PoseHub.
// Stop() never blocks and may be called by any number of threads at once.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "server/lagged_streams.hpp"
#include "server/pose_hub.hpp"
#include "server/realtime_monitor.hpp"
#include "server/session_stats.hpp"
#include "pipeline/frame_loop.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace locaid::server {

class PairHelper;  // server/pair_helper.hpp

struct SessionOptions {
  std::string id;
  std::string source;        // "kitti:/path", "synthetic:seed=1", "live"
  std::string vo_method = "default";
  std::string scenario = "open-sky";
  double playback_rate = 0;  // 0 = as fast as possible, N = N x real time
  size_t history_size = 1000;
  bool live = false;                // pushed / gpsd input: real time by nature
  double behind_threshold_s = 0.1;  // lateness above which a paced session is falling behind
  // The estimator its frame loop was built with (lagged streams smooth its
  // filter); null: lagged streams pass the causal poses on after the lag.
  std::shared_ptr<EstimatorHandle> estimator;
};

// What overload does to a session (docs/api.md "Keeping real time"):
// real-time sessions (paced or live) run at normal priority and share the
// cores; batch sessions (unpaced recordings) run kBatchNice above the nice
// the server was started with (at most 19) and get what the real-time ones
// leave.
inline constexpr int kBatchNice = 10;

class Session {
 public:
  using Command = std::function<void(pipeline::RunLoop&)>;

  Session(SessionOptions options, std::unique_ptr<pipeline::RunLoop> loop);
  ~Session();  // Stop() + Join()
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  void Start();
  // Asks the thread to stop after the current frame and returns at once: a
  // RUNNING or STARTING session is STOPPED from now on. The hub is closed when
  // the thread ends (streams drain their queues and end with OK). Any thread,
  // any number of times.
  void Stop();
  // Waits for the thread to end, then joins it and the hub's fan-out threads.
  // Exactly one caller joins; concurrent callers wait for it; later calls
  // return at once. Never called on the session's own threads.
  void Join();
  // True for the first caller only: the session is handed to the reaper once.
  bool MarkRetired() { return !retired_.exchange(true); }

  // Runs `command` on the session thread before the next frame (so the
  // run loop is never touched by two threads).
  void Post(Command command);
  void set_scenario_name(const std::string& name);

  const std::string& id() const { return options_.id; }
  const SessionOptions& options() const { return options_; }
  // Paced or live (not a batch replay): what load-based admission counts.
  bool realtime() const { return options_.live || options_.playback_rate > 0; }
  // CPU cores its thread used over the last ~5 s, and its age (wall seconds).
  double cpu_cores() const { return monitor_.CpuCores(RealTimeMonitor::Clock::now()); }
  double age_s() const;
  Hub& hub() { return hub_; }
  // The lagged (smoothed) streams: StreamPosesRequest.smoothing_lag_s > 0.
  LaggedStreams& lagged() { return lagged_; }
  // Causal and lagged subscribers (what max_subscribers_per_session counts).
  size_t subscriber_count() const { return hub_.subscriber_count() + lagged_.subscriber_count(); }
  locaid::v1::Session ToProto() const;
  locaid::v1::SessionStats Stats() const;

  // What an operator scrapes (server/metrics.cpp): the newest pose's filter
  // figures and a histogram of the per-frame processing latency.
  using MetricsSnapshot = SessionMetricsSnapshot;
  static constexpr auto kLatencyBucketsS = SessionMetricsSnapshot::kLatencyBucketsS;
  MetricsSnapshot Metrics() const;
  locaid::v1::SessionState state() const { return state_.load(); }
  // Still preparing its input (rendering) on its thread, even if already
  // STOPPED: what max_concurrent_renders counts.
  bool preparing() const { return !loop_->ready() && ended_unix_ns_.load() == 0; }
  // Wall clock (ns) when the session's thread ended; 0 while it runs.
  int64_t ended_unix_ns() const { return ended_unix_ns_.load(); }

 private:
  void Run();
  void RunCommands();
  // One step of the run loop: false when the session is done.
  bool StepOnce();
  // Sleeps until the wall time at which sensor time t_ns is due (set in
  // *due; nullopt: not paced); false if stopped meanwhile.
  bool Pace(int64_t t_ns, std::optional<std::chrono::steady_clock::time_point>* due);
  void Publish(const pipeline::StepResult& r, double latency_ms,
               std::optional<std::chrono::steady_clock::time_point> due);
  void NoteOrigin();

  SessionOptions options_;
  std::unique_ptr<pipeline::RunLoop> loop_;
  Hub hub_;
  LaggedStreams lagged_;
  std::thread thread_;
  std::mutex join_mu_;  // one Join() at a time; joined_ after the first
  bool joined_ = false;
  std::atomic<bool> retired_{false};
  const int64_t created_unix_ns_;
  std::atomic<int64_t> ended_unix_ns_{0};  // when Run() returned; 0 while it runs
  const int64_t total_frames_;

  std::atomic<locaid::v1::SessionState> state_{locaid::v1::SESSION_STATE_STARTING};
  std::atomic<bool> stop_{false};
  std::mutex wait_mu_;
  std::condition_variable wait_cv_;

  std::mutex commands_mu_;
  std::deque<Command> commands_;

  SessionCounters counters_;
  Pacer pacer_;  // session thread only
  RealTimeMonitor monitor_;
  const PairHelper* helper_ = nullptr;  // session thread only: its decode helper while Run() runs
  const std::chrono::steady_clock::time_point created_steady_;
  uint64_t sequence_ = 0;

  // Guarded by stats_mu_.
  mutable std::mutex stats_mu_;
  bool has_origin_ = false;
  double origin_[3] = {0, 0, 0};
  std::string error_;
};


int64_t UnixNowNs();

}  // namespace locaid::server
