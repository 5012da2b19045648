// A live session's GPS receiver read by the server itself: a gpsd daemon
// watched on one thread of its own (owned by the live source it feeds). Fixes go
// to the session's LiveFrameSource without blocking; a lost connection is
// counted and retried with backoff.
#pragma once

#include "pipeline/live_frame_source.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace locaid::server {

struct GpsdEndpoint {
  std::string host = "127.0.0.1";
  uint16_t port = 2947;
};

class GpsdReceiver final : public pipeline::InputFeeder {
 public:
  // Backoff between connection attempts: 0.5 s, doubling up to 5 s after
  // every failure (refused, or a connection that ended before its first
  // report, e.g. a gpsd sending garbage); back to 0.5 s only after a
  // connection that delivered reports.
  static constexpr double kFirstBackoffS = 0.5, kMaxBackoffS = 5.0;
  // `sink` must outlive the receiver.
  GpsdReceiver(GpsdEndpoint endpoint, pipeline::LiveFrameSource* sink);
  ~GpsdReceiver() override;  // stops and joins the thread
  GpsdReceiver(const GpsdReceiver&) = delete;
  GpsdReceiver& operator=(const GpsdReceiver&) = delete;

  // Connection figures, merged into the session's input stats. Any thread.
  void AddStats(pipeline::LiveInputStats& stats) const override;

 private:
  void Run();
  bool SleepFor(double seconds);  // false when stopping

  const GpsdEndpoint endpoint_;
  pipeline::LiveFrameSource* const sink_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  bool connected_ = false;
  uint64_t connects_ = 0, losses_ = 0;
  std::string error_;
  std::thread thread_;
};

}  // namespace locaid::server
