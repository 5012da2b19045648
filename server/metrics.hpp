// Operator metrics: Prometheus text exposition on --metrics-listen
// (prometheus-cpp's pull exposer, off by default). Values are read from the
// sessions when scraped; nothing is counted twice on the pose path.
#pragma once

#include "server/session.hpp"

#include <prometheus/collectable.h>
#include <prometheus/exposer.h>
#include <prometheus/metric_family.h>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace locaid::server {

// Server-wide figures beside the sessions'.
struct ServerFigures {
  size_t render_queue = 0;            // sessions preparing their input (SessionRegistry::Preparing)
  size_t max_concurrent_renders = 0;
  uint64_t rendered_drive_bytes = 0;  // under SyntheticRoot(work_dir)
  uint64_t resident_memory_bytes = 0; // of this process
  double realtime_cpu_cores = 0;      // sum of the real-time sessions' cpu_cores
  double max_cpu_cores = 0;           // the config's (0: off)
};

using SessionMetrics = std::pair<std::string, Session::MetricsSnapshot>;  // (id, snapshot)

// The metric families, names and help texts listed in docs/api.md ("Metrics").
std::vector<prometheus::MetricFamily> BuildMetricFamilies(const std::vector<SessionMetrics>& sessions,
                                                         const ServerFigures& server);

// Bytes of the regular files under `dir` (0 when absent); resident set size
// of this process from /proc/self/statm (0 when unavailable).
uint64_t DirectoryBytes(const std::string& dir);
uint64_t ResidentMemoryBytes();

// Serves GET /metrics on `listen` (host:port; port 0 picks one) with what
// `collect` returns at each scrape. The exposer's threads (2) are started here
// and stopped by the destructor. Throws std::runtime_error when it cannot bind.
class MetricsExporter {
 public:
  using Collect = std::function<std::vector<prometheus::MetricFamily>()>;
  MetricsExporter(const std::string& listen, Collect collect);
  ~MetricsExporter();
  int port() const { return port_; }

 private:
  std::shared_ptr<prometheus::Collectable> collectable_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  int port_ = 0;
};

}  // namespace locaid::server
