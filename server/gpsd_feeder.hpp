// A live session's GPS receiver read by the server itself: a gpsd daemon
// watched on one thread of its own (owned by the live source it feeds, as
// the CameraFeeder is). Fixes go to the session's LiveFrameSource without
// blocking; a lost connection is counted and retried with RestartBackoff.
#pragma once

#include "pipeline/live_frame_source.hpp"
#include "server/restart_backoff.hpp"

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

class GpsdFeeder final : public pipeline::InputFeeder {
 public:
  // Between connection attempts a RestartBackoff: a failure is a refused
  // connection or one that ended before its first report (e.g. a gpsd
  // sending garbage); only a connection that delivered reports brings the
  // wait back to its first.
  // `sink` must outlive the feeder.
  GpsdFeeder(GpsdEndpoint endpoint, pipeline::LiveFrameSource* sink);
  ~GpsdFeeder() override;  // stops and joins the thread
  GpsdFeeder(const GpsdFeeder&) = delete;
  GpsdFeeder& operator=(const GpsdFeeder&) = delete;

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
