#include "server/gpsd_feeder.hpp"

#include "sensors/gpsd_client.hpp"

#include <chrono>
#include <exception>
#include <memory>

namespace locaid::server {
namespace {

int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

GpsdFeeder::GpsdFeeder(GpsdEndpoint endpoint, pipeline::LiveFrameSource* sink)
    : endpoint_(std::move(endpoint)), sink_(sink), thread_([this] { Run(); }) {}

GpsdFeeder::~GpsdFeeder() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void GpsdFeeder::AddStats(pipeline::LiveInputStats& stats) const {
  std::lock_guard lock(mu_);
  stats.has_gpsd = true;
  stats.gpsd_connected = connected_;
  stats.gpsd_connects = connects_;
  stats.gpsd_losses = losses_;
  stats.gpsd_error = error_;
}

bool GpsdFeeder::SleepFor(double seconds) {
  std::unique_lock lock(mu_);
  return !cv_.wait_for(lock, std::chrono::duration<double>(seconds), [this] { return stop_; });
}

void GpsdFeeder::Run() {
  RestartBackoff backoff;
  int64_t last_t_ns = 0;
  for (;;) {
    {
      std::lock_guard lock(mu_);
      if (stop_) return;
    }
    std::unique_ptr<sensors::GpsdClient> client;
    try {
      client = std::make_unique<sensors::GpsdClient>(endpoint_.host, endpoint_.port);
    } catch (const std::exception& e) {
      {
        std::lock_guard lock(mu_);
        error_ = e.what();
      }
      if (!SleepFor(backoff.wait_s())) return;
      backoff.Failed();
      continue;
    }
    {
      std::lock_guard lock(mu_);
      connected_ = true;
      ++connects_;
    }
    bool delivered = false;  // a report came through: the connection was healthy
    try {
      // Short reads so that a stop is noticed within ~100 ms.
      for (;;) {
        {
          std::lock_guard lock(mu_);
          if (stop_) return;
        }
        for (const sensors::GpsdReport& report : client->Read(std::chrono::milliseconds(100))) {
          // gpsd may report an epoch more than once (one TPV per sentence
          // that completes it); the first report of an epoch is the fix.
          delivered = true;
          if (report.t_ns <= last_t_ns) continue;
          last_t_ns = report.t_ns;
          pipeline::LiveItem item;
          item.kind = pipeline::LiveItem::Kind::kGps;
          item.arrival_steady_ns = SteadyNowNs();
          if (auto fix = sensors::FixFromGpsd(report)) {
            item.t_ns = fix->t_ns;
            item.gps = *fix;
          } else {
            item.t_ns = report.t_ns;
            item.gps_no_fix = true;
          }
          sink_->PushAsyncFix(std::move(item));
        }
      }
    } catch (const std::exception& e) {
      std::lock_guard lock(mu_);
      connected_ = false;
      ++losses_;
      error_ = e.what();
    }
    client.reset();
    // Only a connection that delivered reports earns a fast retry; one that
    // failed before its first report (refused, garbage, closed at once) is a
    // failure like a refused connect, so the wait keeps doubling.
    if (delivered) backoff.Delivered();
    if (!SleepFor(backoff.wait_s())) return;
    if (!delivered) backoff.Failed();
  }
}

}  // namespace locaid::server
