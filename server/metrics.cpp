#include "server/metrics.hpp"

#include "fusion/types.hpp"

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>
#include <unistd.h>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;
using prometheus::ClientMetric;
using prometheus::MetricFamily;
using prometheus::MetricType;

class FunctionCollectable : public prometheus::Collectable {
 public:
  explicit FunctionCollectable(MetricsExporter::Collect collect) : collect_(std::move(collect)) {}
  std::vector<MetricFamily> Collect() const override { return collect_(); }

 private:
  MetricsExporter::Collect collect_;
};

// Families by name, in the order they are first used.
class Families {
 public:
  MetricFamily& Get(const std::string& name, const std::string& help, MetricType type) {
    auto it = index_.find(name);
    if (it != index_.end()) return families_[it->second];
    index_[name] = families_.size();
    families_.push_back({name, help, type, {}});
    return families_.back();
  }
  void Add(const std::string& name, const std::string& help, MetricType type, std::vector<ClientMetric::Label> labels,
           double value) {
    ClientMetric m;
    m.label = std::move(labels);
    if (type == MetricType::Counter) m.counter.value = value;
    else m.gauge.value = value;
    Get(name, help, type).metric.push_back(std::move(m));
  }
  std::vector<MetricFamily> Take() { return std::move(families_); }

 private:
  std::map<std::string, size_t> index_;
  std::vector<MetricFamily> families_;
};

const char* StateName(v1::SessionState s) {
  switch (s) {
    case v1::SESSION_STATE_STARTING: return "starting";
    case v1::SESSION_STATE_RUNNING: return "running";
    case v1::SESSION_STATE_FINISHED: return "finished";
    case v1::SESSION_STATE_STOPPED: return "stopped";
    case v1::SESSION_STATE_FAILED: return "failed";
    default: return "unspecified";
  }
}

const char* ModeName(fusion::Mode m) {
  switch (m) {
    case fusion::Mode::kGpsFused: return "gps_fused";
    case fusion::Mode::kGpsDegraded: return "gps_degraded";
    case fusion::Mode::kVoOnly: return "vo_only";
    case fusion::Mode::kLost: return "lost";
    case fusion::Mode::kDeadReckoning: return "dead_reckoning";
  }
  return "lost";
}

void AddSession(Families& f, const std::string& id, const Session::MetricsSnapshot& m) {
  const std::vector<ClientMetric::Label> sid = {{"session", id}};
  const auto& st = m.stats;
  const char* frames = "Frames of the session's input by what became of them";
  for (const auto& [kind, value] : {std::pair<const char*, uint64_t>{"in", st.frames_in()},
                                    {"processed", st.frames_processed()},
                                    {"skipped", st.frames_skipped()},
                                    {"corrupt", st.frames_corrupt()}}) {
    f.Add("locaid_session_frames_total", frames, MetricType::Counter, {{"session", id}, {"kind", kind}},
          static_cast<double>(value));
  }
  f.Add("locaid_session_poses_published_total", "Poses handed to the session's subscribers", MetricType::Counter,
        sid, static_cast<double>(st.poses_published()));
  f.Add("locaid_session_poses_dropped_total", "Poses dropped for subscribers that did not keep up",
        MetricType::Counter, sid, static_cast<double>(st.dropped_total()));
  f.Add("locaid_session_subscribers", "Open pose streams", MetricType::Gauge, sid, st.subscribers());
  f.Add("locaid_session_frames_per_second", "Processing rate over the last ~2 s", MetricType::Gauge, sid, st.fps());
  f.Add("locaid_session_behind_real_time_seconds",
        "Paced sessions: how late the newest pose was, or how overdue the next one is (0: on time)", MetricType::Gauge,
        sid, st.behind_real_time_s());
  f.Add("locaid_session_falling_behind", "1 while a paced session is more than behind_threshold_s late",
        MetricType::Gauge, sid, st.falling_behind() ? 1 : 0);
  f.Add("locaid_session_realtime_factor", "Sensor seconds processed per wall second over the last ~2 s",
        MetricType::Gauge, sid, st.realtime_factor());
  f.Add("locaid_session_cpu_cores", "CPU time of the session's threads (pipeline, decode helper) per wall second over the last ~5 s",
        MetricType::Gauge, sid, st.cpu_cores());
  ClientMetric hist;
  hist.label = sid;
  hist.histogram.sample_count = m.latency_count;
  hist.histogram.sample_sum = m.latency_sum_s;
  for (size_t b = 0; b < Session::kLatencyBucketsS.size(); ++b)
    hist.histogram.bucket.push_back({m.latency_le[b], Session::kLatencyBucketsS[b]});
  hist.histogram.bucket.push_back({m.latency_count, std::numeric_limits<double>::infinity()});
  f.Get("locaid_session_processing_latency_seconds", "Wall time from reading a frame to publishing its pose",
        MetricType::Histogram)
      .metric.push_back(std::move(hist));
  if (!m.has_pose) return;
  for (fusion::Mode mode : {fusion::Mode::kGpsFused, fusion::Mode::kGpsDegraded, fusion::Mode::kVoOnly,
                            fusion::Mode::kDeadReckoning, fusion::Mode::kLost}) {
    f.Add("locaid_session_mode", "1 for the mode of the newest pose, 0 for the others", MetricType::Gauge,
          {{"session", id}, {"mode", ModeName(mode)}}, mode == m.mode ? 1.0 : 0.0);
  }
  // +Inf before the first accepted fix: reported as -1 (no GPS yet).
  f.Add("locaid_session_seconds_since_gps", "Sensor seconds since the last accepted GPS fix (-1: none yet)",
        MetricType::Gauge, sid, std::isfinite(m.seconds_since_gps) ? m.seconds_since_gps : -1.0);
  f.Add("locaid_session_gps_fixes_total", "GPS fixes the filter used or whose horizontal part the gate rejected",
        MetricType::Counter, {{"session", id}, {"result", "used"}}, m.gps_used);
  f.Add("locaid_session_gps_fixes_total", "GPS fixes the filter used or whose horizontal part the gate rejected",
        MetricType::Counter, {{"session", id}, {"result", "rejected"}}, m.gps_rejected);
  f.Add("locaid_session_gps_nis", "Normalised innovation squared of the newest fix (horizontal, 2 dof)",
        MetricType::Gauge, sid, m.last_gps_nis);
  f.Add("locaid_session_gps_gate", "The gate the NIS is held against (chi-square, 2 dof)", MetricType::Gauge, sid,
        m.gps_gate);
  f.Add("locaid_session_vo_inliers", "VO inlier tracks of the newest frame", MetricType::Gauge, sid, m.vo_inliers);
  for (vo::Health h : {vo::Health::kTracking, vo::Health::kDark, vo::Health::kFrozen, vo::Health::kLost,
                       vo::Health::kNoImages}) {
    f.Add("locaid_session_vo_health", "1 for what the cameras gave VO on the newest frame, 0 for the others",
          MetricType::Gauge, {{"session", id}, {"health", vo::ToString(h)}}, h == m.vo_health ? 1.0 : 0.0);
  }
  f.Add("locaid_session_speed_readings_used_total", "Vehicle speed readings the filter fused", MetricType::Counter,
        sid, m.speed_used);
  f.Add("locaid_session_speed_scale_error", "Estimated speed sensor scale error (reads (1 + e) x true speed)",
        MetricType::Gauge, sid, m.speed_scale_error);
  static constexpr std::array<const char*, 6> kVoAxes = {"tx", "ty", "tz", "rx", "ry", "rz"};
  for (int i = 0; i < m.noise.vo_scale_size() && i < 6; ++i) {
    f.Add("locaid_session_vo_noise_scale", "Learned VO noise: variance multiple of the model per body axis",
          MetricType::Gauge, {{"session", id}, {"axis", kVoAxes[static_cast<size_t>(i)]}}, m.noise.vo_scale(i));
  }
  f.Add("locaid_session_gps_noise_scale", "Learned GPS noise: variance multiple of the fixes' stated covariance",
        MetricType::Gauge, {{"session", id}, {"component", "horizontal"}}, m.noise.gps_horizontal_scale());
  f.Add("locaid_session_gps_noise_scale", "Learned GPS noise: variance multiple of the fixes' stated covariance",
        MetricType::Gauge, {{"session", id}, {"component", "vertical"}}, m.noise.gps_vertical_scale());
  f.Add("locaid_session_position_sigma_meters", "Horizontal position 1-sigma radius, sqrt(var_e + var_n)",
        MetricType::Gauge, sid, m.position_sigma_h_m);
}

}  // namespace

std::vector<MetricFamily> BuildMetricFamilies(const std::vector<SessionMetrics>& sessions,
                                              const ServerFigures& server) {
  Families f;
  std::map<std::string, int> by_state = {{"starting", 0}, {"running", 0}, {"finished", 0}, {"stopped", 0},
                                         {"failed", 0}};
  for (const auto& [id, m] : sessions) ++by_state[StateName(m.state)];
  for (const auto& [state, n] : by_state)
    f.Add("locaid_sessions", "Sessions in the registry by state", MetricType::Gauge, {{"state", state}}, n);
  f.Add("locaid_render_queue",
        "Sessions rendering their synthetic drive, stopped ones until the render ends (what max_concurrent_renders "
        "bounds)",
        MetricType::Gauge, {}, static_cast<double>(server.render_queue));
  f.Add("locaid_render_queue_limit", "max_concurrent_renders", MetricType::Gauge, {},
        static_cast<double>(server.max_concurrent_renders));
  f.Add("locaid_rendered_drives_bytes", "Disk used by rendered synthetic drives", MetricType::Gauge, {},
        static_cast<double>(server.rendered_drive_bytes));
  f.Add("locaid_realtime_cpu_cores", "CPU the real-time sessions' threads used over the last ~5 s, cores",
        MetricType::Gauge, {}, server.realtime_cpu_cores);
  f.Add("locaid_realtime_cpu_cores_limit", "max_cpu_cores (0: admission by max_sessions only)", MetricType::Gauge, {},
        server.max_cpu_cores);
  f.Add("locaid_resident_memory_bytes", "Resident set size of the server process", MetricType::Gauge, {},
        static_cast<double>(server.resident_memory_bytes));
  for (const auto& [id, m] : sessions) AddSession(f, id, m);
  return f.Take();
}

uint64_t DirectoryBytes(const std::string& dir) {
  std::error_code ec;
  uint64_t bytes = 0;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
       !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    std::error_code size_ec;
    if (it->is_regular_file(size_ec)) {
      const auto n = it->file_size(size_ec);
      if (!size_ec) bytes += n;
    }
  }
  return bytes;
}

uint64_t ResidentMemoryBytes() {
  std::ifstream statm("/proc/self/statm");
  uint64_t size_pages = 0, resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return 0;
  return resident_pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
}

MetricsExporter::MetricsExporter(const std::string& listen, Collect collect)
    : collectable_(std::make_shared<FunctionCollectable>(std::move(collect))) {
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(listen, 2);
  } catch (const std::exception& e) {
    throw std::runtime_error("metrics_listen '" + listen + "': cannot serve: " + e.what());
  }
  exposer_->RegisterCollectable(collectable_);
  const auto ports = exposer_->GetListeningPorts();
  if (ports.empty()) throw std::runtime_error("metrics_listen '" + listen + "': not listening");
  port_ = ports.front();
}

MetricsExporter::~MetricsExporter() = default;

}  // namespace locaid::server
