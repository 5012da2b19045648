// What a lagged (smoothed) subscriber costs the causal stream of its session:
// a server in this process (127.0.0.1) with the production estimator (VO +
// EKF) plays the same synthetic drive in paced sessions, alternately without
// and with one subscriber of smoothing_lag_s (default 2 s) beside the causal
// one. Per causal pose, the latency is the server's processing_latency_ms
// (frame read to pose handed to subscribers) plus the delay from
// published_unix_ns to receipt here; printed as p50 / p99 / max per run,
// with the poses the lagged subscriber got.
//
//   build/bin/locaid-bench-lagged [--frames 300] [--rate 1] [--lag 2] [--runs 3] [--width W --height H]
#include "server/server.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace v1 = locaid::v1;
using namespace locaid::server;

namespace {

int64_t NowUnixNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// Reads one stream to its end on its own thread.
struct Reader {
  Reader(v1::Localization::Stub* stub, const std::string& id, double lag_s) {
    req.set_session_id(id);
    req.set_from_start(lag_s == 0);
    req.set_smoothing_lag_s(lag_s);
    thread = std::thread([this, stub] {
      auto reader = stub->StreamPoses(&ctx, req);
      v1::PoseUpdate p;
      while (reader->Read(&p)) {
        const double delay_ms = static_cast<double>(NowUnixNs() - p.published_unix_ns()) * 1e-6;
        latency_ms.push_back(p.processing_latency_ms() + delay_ms);
        delivery_ms.push_back(delay_ms);
        max_behind_s = std::max(max_behind_s, p.behind_real_time_s());
        smoothed += p.smoothed() ? 1 : 0;
        if (latency_ms.size() == 1) first_sequence = p.sequence();
        gaps += latency_ms.size() > 1 && p.sequence() != last_sequence + 1 ? 1 : 0;
        last_sequence = p.sequence();
      }
      status = reader->Finish();
    });
  }
  void Join() { thread.join(); }

  grpc::ClientContext ctx;
  v1::StreamPosesRequest req;
  std::thread thread;
  std::vector<double> latency_ms, delivery_ms;
  double max_behind_s = 0;
  size_t smoothed = 0, gaps = 0;
  uint64_t first_sequence = 0, last_sequence = 0;
  grpc::Status status;
};

}  // namespace

int main(int argc, char** argv) {
  int frames = 300, runs = 3, width = 0, height = 0;
  double rate = 1, lag_s = 2;
  CLI::App app{"locaid lagged-stream benchmark: the causal stream's latency with and without a lagged subscriber"};
  app.add_option("--frames", frames, "frames of the synthetic drive (10 Hz)")->capture_default_str();
  app.add_option("--rate", rate, "playback rate (1 = real time)")->capture_default_str();
  app.add_option("--lag", lag_s, "the lagged subscriber's smoothing_lag_s")->capture_default_str();
  app.add_option("--runs", runs, "pairs of sessions (without, with), alternating")->capture_default_str();
  app.add_option("--width", width, "image width (0: the synthetic default)");
  app.add_option("--height", height, "image height (0: the synthetic default)");
  CLI11_PARSE(app, argc, argv);

  const std::filesystem::path work =
      std::filesystem::temp_directory_path() / ("locaid-bench-lagged-" + std::to_string(getpid()));
  struct RemoveAtExit {
    std::filesystem::path dir;
    ~RemoveAtExit() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } remove_work{work};
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.work_dir = work.string();
  LocalizationServer server(config);  // the production estimator
  auto stub = v1::Localization::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(server.port()), grpc::InsecureChannelCredentials()));
  std::string yaml;
  if (width > 0) yaml += "width: " + std::to_string(width) + "\n";
  if (height > 0) yaml += "height: " + std::to_string(height) + "\n";

  std::printf("frames=%d rate=%g lag_s=%g runs=%d\n", frames, rate, lag_s, runs);
  std::vector<double> all[2];
  for (int run = 0; run < 2 * runs; ++run) {
    const bool with_lag = run % 2 == 1;
    v1::StartSessionRequest start;
    start.mutable_synthetic()->set_seed(11);
    start.mutable_synthetic()->set_frames(static_cast<uint32_t>(frames));
    start.mutable_synthetic()->set_options_yaml(yaml);
    start.set_playback_rate(rate);
    v1::Session session;
    {
      grpc::ClientContext ctx;
      const grpc::Status s = stub->StartSession(&ctx, start, &session);
      if (!s.ok()) {
        std::cerr << "StartSession: " << s.error_message() << "\n";
        return 1;
      }
    }
    Reader causal(stub.get(), session.id(), 0);
    std::unique_ptr<Reader> lagged;
    if (with_lag) lagged = std::make_unique<Reader>(stub.get(), session.id(), lag_s);
    causal.Join();
    if (lagged) lagged->Join();
    if (!causal.status.ok() || (lagged && !lagged->status.ok())) {
      std::cerr << "stream failed: " << causal.status.error_message()
                << (lagged ? " / " + lagged->status.error_message() : "") << "\n";
      return 1;
    }
    all[with_lag ? 1 : 0].insert(all[with_lag ? 1 : 0].end(), causal.latency_ms.begin(), causal.latency_ms.end());
    std::printf("%-12s causal latency_ms p50=%.2f p99=%.2f max=%.2f (delivery p50=%.3f p99=%.3f) poses=%zu "
                "behind_max_s=%.3f",
                with_lag ? "with-lag" : "without", Percentile(causal.latency_ms, 0.5),
                Percentile(causal.latency_ms, 0.99), Percentile(causal.latency_ms, 1.0),
                Percentile(causal.delivery_ms, 0.5), Percentile(causal.delivery_ms, 0.99), causal.latency_ms.size(),
                causal.max_behind_s);
    if (lagged)
      std::printf("  lagged poses=%zu (sequence %llu-%llu, %zu gaps) smoothed=%zu", lagged->latency_ms.size(),
                  static_cast<unsigned long long>(lagged->first_sequence),
                  static_cast<unsigned long long>(lagged->last_sequence), lagged->gaps, lagged->smoothed);
    std::printf("\n");
    std::fflush(stdout);
    grpc::ClientContext ctx;
    v1::StopSessionRequest stop;
    stop.set_session_id(session.id());
    stop.set_remove(true);
    v1::Session out;
    (void)stub->StopSession(&ctx, stop, &out);
  }
  for (int k = 0; k < 2; ++k) {
    std::printf("all runs %-8s causal latency_ms p50=%.2f p99=%.2f (%zu poses)\n", k ? "with-lag" : "without",
                Percentile(all[k], 0.5), Percentile(all[k], 0.99), all[k].size());
  }
  server.Shutdown();
  return 0;
}
