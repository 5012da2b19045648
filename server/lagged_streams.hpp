// A session's lagged pose streams (StreamPosesRequest.smoothing_lag_s > 0,
// docs/api.md "Lagged stream"): for each distinct lag a FixedLagSmoother
// (fusion/fixed_lag_smoother.hpp) and a PoseHub of its own, whose poses are
// the causal ones smoothed over the next lag seconds of sensor time.
//
// Threads:
//  - the StreamPoses handlers (any gRPC thread) Subscribe(); a new lag makes
//    a channel (hub + encodings) and marks the set changed;
//  - the session's stepping thread attaches an EpochLog to the session's
//    Localizer while at least one lag has a subscriber, and hands each
//    completed epoch and each published causal pose (with a copy of the open
//    epoch) to the smoothing thread: a copy and a queue push, nothing more,
//    so the causal stream does not wait for the backward passes;
//  - the smoothing thread (one per session, started with its first lagged
//    subscriber, at a batch session's nice, kBatchNice above
//    its starter's) runs the smoothers and publishes the released poses to the lags'
//    hubs, whose wakes run on one fan-out thread per lag.
// A lag whose last subscriber has left is dropped at the next pose; with no
// lag left the log is detached. At the session's end every smoother is
// flushed and its poses published before the lags' hubs close.
//
// Bounds: kMaxLagsPerSession distinct lags at a time (a further one is
// refused: RESOURCE_EXHAUSTED); if the smoothing thread falls more than
// kMaxSmoothingBacklogS of sensor time behind the filter (an overloaded
// machine), the poses it has not taken yet are dropped (a gap in the lagged
// streams' sequence), and smoothing starts over with a new log.
#pragma once

#include "fusion/epoch_log.hpp"
#include "fusion/fixed_lag_smoother.hpp"
#include "fusion/geodesy.hpp"
#include "locaid/v1/localization.pb.h"
#include "pipeline/frame_loop.hpp"
#include "pipeline/run_assembly.hpp"
#include "server/pose_hub.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace locaid::server {

using PoseMessage = locaid::v1::PoseUpdate;
using Hub = PoseHub<PoseMessage>;

class PoseEncodings;  // server/pose_encodings.hpp

inline constexpr double kMaxSmoothingLagS = 30;
inline constexpr size_t kMaxLagsPerSession = 4;
inline constexpr double kMaxSmoothingBacklogS = 10;
// At the session's end a lag releases up to its L seconds of poses at once;
// each then waits until every subscriber of the lag has room for it, so one
// that keeps reading loses none. After this long without any of them taking
// a pose, the rest go without waiting (a stalled client loses the oldest, as
// on any stream).
inline constexpr double kFlushPatienceS = 1;

// "" when `lag_s` is a valid StreamPosesRequest.smoothing_lag_s, else the
// message: "smoothing_lag_s must be in [0, 30] s (got 31)".
std::string CheckSmoothingLag(double lag_s);

// The estimator a session's frame loop was built with, recorded by the
// factory RecordEstimator wraps: written on the thread that builds the loop
// (the RPC's, before the session starts, or the session's own for a drive it
// renders first), read on the stepping thread only. `localizer` is null
// for estimators that are not a pipeline::Localizer (tests, benchmarks):
// their lagged streams give the causal poses, flagged smoothed, after the lag.
struct EstimatorHandle {
  pipeline::Estimator* estimator = nullptr;
  pipeline::Localizer* localizer = nullptr;
};
pipeline::EstimatorMaker RecordEstimator(pipeline::EstimatorMaker make, std::shared_ptr<EstimatorHandle> handle);

class LaggedStreams {
 public:
  // One lag's subscribers: its hub (history_size like the session's) and the
  // wire bytes of its poses.
  struct Channel {
    double lag_s = 0;
    std::shared_ptr<Hub> hub;
    std::shared_ptr<PoseEncodings> encodings;
    uint64_t id_base = 0;  // added to its subscribers' ids: unique within the session
  };
  struct Subscription {
    std::shared_ptr<Channel> channel;
    Hub::SubscriberPtr subscriber;
    std::string refused;  // not empty: nothing subscribed (RESOURCE_EXHAUSTED)
  };

  LaggedStreams(std::string session_id, size_t history_size);
  ~LaggedStreams();  // Close()
  LaggedStreams(const LaggedStreams&) = delete;
  LaggedStreams& operator=(const LaggedStreams&) = delete;

  // ---- Any thread.
  // Subscribes to lag `lag_s` (> 0, checked), making its channel if new.
  // After the session has ended: the lag's history (from_start) and the end.
  Subscription Subscribe(double lag_s, size_t queue_size, bool from_start, std::function<void()> wake,
                         std::string peer);
  size_t subscriber_count() const;
  // Every lag's subscribers (ids unique within the session, apart from the
  // causal hub's) and the poses dropped for them, also for those gone.
  HubStats stats() const;
  // Joins the smoothing thread (it ends after the flush Finish() asked for),
  // closes every hub and joins their fan-out threads. After the stepping
  // thread has ended; idempotent.
  void Close();

  // ---- The stepping thread.
  // Before each step: takes in new lags, attaches the log once the estimator
  // exists.
  void BeforeStep(const EstimatorHandle* estimator);
  // After the causal pose `causal` of `step` was published.
  void OnPose(const pipeline::StepResult& step, double latency_ms, const Hub::Item& causal,
              const EstimatorHandle* estimator);
  // The session has ended: flush every lag (its poses are published, then
  // its hub closes) and detach the log. Before the estimator is released.
  void Finish();

 private:
  // A causal pose and what its smoothed PoseUpdate is made from.
  struct Frame {
    pipeline::StepResult step;
    double latency_ms = 0;
    Hub::Item causal;
    std::shared_ptr<const fusion::EnuFrame> enu;  // null before the filter has an origin
  };
  // What the stepping thread hands the smoothing thread, in order.
  struct WorkItem {
    enum class Kind {
      kEpoch,      // a completed epoch (the log's sink)
      kPose,       // a causal pose, its epoch and the open epoch then
      kLags,       // the lags now (new ones start, missing ones are dropped)
      kStartOver,  // the same, every lag's smoother new (a new log)
      kFlush,      // the session's end: flush, publish, close the hubs
    } kind = Kind::kEpoch;
    fusion::Epoch epoch;  // kEpoch; kPose / kFlush: the open epoch (when has_open)
    bool has_open = false;
    std::shared_ptr<const Frame> frame;  // kPose
    int64_t frame_epoch = -1;            // kPose
    std::vector<std::shared_ptr<Channel>> lags;  // kLags, kStartOver, kFlush
    fusion::ErrorLayout layout;                  // kLags, kStartOver
  };
  // The smoothing thread's state of one lag: the frames waiting in the
  // smoother, oldest first (they come out in the same order).
  struct Lag {
    std::shared_ptr<Channel> channel;
    fusion::FixedLagSmoother smoother;
    std::deque<std::shared_ptr<const Frame>> frames;
  };

  // Stepping thread.
  void Sync(const EstimatorHandle* estimator);
  void DropIdleLags();
  void Detach();
  void StartOver();
  // Queues `item`; returns the sensor time between the oldest pose still
  // queued and the newest (the smoothing thread's backlog), s.
  double Push(WorkItem item);
  WorkItem LagsItem(WorkItem::Kind kind) const;

  // Smoothing thread.
  void Run();
  void Apply(WorkItem& item);
  // Publishes the smoothed PoseUpdates of `poses` to the lag's subscribers
  // (at_end: waiting for room, see kFlushPatienceS).
  void Release(Lag& lag, const std::vector<fusion::FusedPose>& poses, bool at_end = false);

  const std::string session_id_;
  const size_t history_size_;

  // Channels by lag: Subscribe (any thread) adds, the stepping thread drops.
  mutable std::mutex mu_;
  std::vector<std::shared_ptr<Channel>> channels_;
  uint64_t channels_made_ = 0;
  uint64_t dropped_departed_ = 0;  // by the subscribers of dropped channels
  bool finished_ = false;          // Finish() ran: new channels are born closed
  std::thread worker_;
  std::atomic<bool> changed_{false};

  // Stepping thread only.
  std::vector<std::shared_ptr<Channel>> active_;  // what the smoothing thread was last told
  std::unique_ptr<fusion::EpochLog> log_;
  pipeline::Localizer* attached_ = nullptr;  // the Localizer log_ is attached to
  uint64_t log_generation_ = 0;      // +1 per attached log
  uint64_t stepped_generation_ = 0;  // the log the last step ran with (0: none)
  fusion::ErrorLayout layout_;
  std::shared_ptr<const fusion::EnuFrame> enu_;  // a copy once the filter has an origin

  // The queue to the smoothing thread.
  std::mutex queue_mu_;
  std::condition_variable queue_cv_;
  std::deque<WorkItem> queue_;
  std::deque<int64_t> queued_pose_t_ns_;  // sensor times of the poses in queue_
  bool stop_ = false;

  // Smoothing thread only.
  std::vector<Lag> lags_;
  std::shared_ptr<const fusion::EnuFrame> worker_enu_;
};

}  // namespace locaid::server
