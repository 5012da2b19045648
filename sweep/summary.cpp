#include "sweep/summary.hpp"

#include "fusion/ekf_config.hpp"
#include "sweep/summary_text.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace fs = std::filesystem;

namespace locaid::sweep {

using namespace summary_text;

namespace {

std::optional<double> Number(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) return std::nullopt;
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}
std::optional<int64_t> Integer(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number_integer()) return std::nullopt;
  return j[key].get<int64_t>();
}

nlohmann::json ToJson(const Distribution& d) {
  if (d.n == 0) return nullptr;
  return {{"n", d.n}, {"median", d.median}, {"p90", d.p90}, {"max", d.max}};
}

// Every RunMetrics value of a group's done runs, per field.
struct MetricValues {
  std::vector<double> values[std::size(kMetricFields)];
  void Add(const RunMetrics& m) {
    for (size_t f = 0; f < std::size(kMetricFields); ++f)
      if (const auto& v = m.*kMetricFields[f].value) values[f].push_back(*v);
  }
  MetricDistributions Distributions() const {
    MetricDistributions d;
    for (size_t f = 0; f < std::size(kMetricFields); ++f) d.*kMetricFields[f].distribution = Distribute(values[f]);
    return d;
  }
};

// Every finite number of `key` in each object of the array `j[array]`.
std::vector<double> EachNumber(const nlohmann::json& j, const char* array, const char* key) {
  std::vector<double> out;
  if (!j.contains(array) || !j[array].is_array()) return out;
  for (const auto& o : j[array])
    if (const auto v = Number(o, key)) out.push_back(*v);
  return out;
}

std::map<std::string, int64_t> Counts(const nlohmann::json& j, const char* key) {
  std::map<std::string, int64_t> out;
  if (!j.contains(key) || !j[key].is_object()) return out;
  for (const auto& [name, n] : j[key].items())
    if (n.is_number_integer()) out[name] = n.get<int64_t>();
  return out;
}

void AddCounts(std::map<std::string, int64_t>& sum, const std::map<std::string, int64_t>& counts) {
  for (const auto& [name, n] : counts) sum[name] += n;
}

}  // namespace

std::vector<RunState> TaskStates(const Plan& plan, Stage stage) {
  std::vector<RunState> out;
  if (stage == Stage::kVo)
    for (const auto& t : plan.vo) out.push_back(ReadResult(plan.dir, t.id, t.key).state);
  else
    for (const auto& t : plan.filter) out.push_back(ReadResult(plan.dir, t.id, t.key).state);
  return out;
}

RunMetrics ReadRunMetrics(const nlohmann::json& m) {
  RunMetrics r;
  r.rmse_gps_m = Number(m, "rmse_gps_m");
  r.nees_mean = Number(m, "nees_mean");
  r.nees_bound_99 = Number(m, "nees_bound_99");
  if (m.contains("outages") && m["outages"].is_array() && !m["outages"].empty()) {
    const nlohmann::json& first = m["outages"][0];
    r.end_error_pct = Number(first, "end_error_pct");
    r.end_error_m = Number(first, "end_error_m");
    r.max_error_m = Number(first, "max_error_m");
    r.outage_rmse_m = Number(first, "rmse_m");
  }
  return r;
}

RunFigures ReadRunFigures(const nlohmann::json& m) {
  RunFigures f;
  f.end_error_pct = EachNumber(m, "outages", "end_error_pct");
  f.added_error_pct = EachNumber(m, "outages", "added_error_pct");
  f.reconverge_s = EachNumber(m, "outages", "reconverge_s");
  f.max_vertical_error_m = Number(m, "max_vertical_error_m");
  if (m.contains("vehicle") && Integer(m["vehicle"], "speed_used").value_or(0) > 0)
    f.speed_scale_error = Number(m["vehicle"], "speed_scale_error");
  f.modes = Counts(m, "modes");
  f.vo_health = Counts(m, "vo_health");
  f.gps_used = Integer(m, "gps_used").value_or(0);
  f.gps_rejected_vertical = Integer(m, "gps_rejected_vertical").value_or(0);
  f.vo_rejected_by_gate = Integer(m, "vo_rejected_by_gate").value_or(0);
  f.longest_rejection_run = std::max(Integer(m, "max_gps_rejection_run").value_or(0),
                                     Integer(m, "max_gps_rejection_run_vertical").value_or(0));
  return f;
}

double GpsGateProbability(const std::vector<std::string>& args) {
  fusion::EkfConfig config;
  for (size_t i = 0; i < args.size(); ++i) {
    std::string setting;
    if (args[i] == "--ekf" && i + 1 < args.size()) setting = args[++i];
    else if (args[i].rfind("--ekf=", 0) == 0) setting = args[i].substr(6);
    const size_t eq = setting.find('=');
    if (eq == std::string::npos) continue;
    double* field = fusion::FindEkfSetting(config, setting.substr(0, eq));
    if (field != &config.gps.gate_probability) continue;
    try {
      *field = std::stod(setting.substr(eq + 1));
    } catch (const std::exception&) {
      // locaid-replay refuses the run; no figure of it is summed
    }
  }
  return config.gps.gate_probability;
}

std::vector<ResultRow> CollectRows(const Plan& plan) {
  std::vector<ResultRow> rows;
  for (const auto& t : plan.filter) {
    ResultRow r;
    r.id = t.id;
    r.recording = plan.recordings[t.recording].path;
    r.scenario = t.scenario;
    r.seed = t.seed;
    r.imu = t.imu;
    r.gps_gate_probability = GpsGateProbability(t.args);
    const StoredResult stored = ReadResult(plan.dir, t.id, t.key);
    r.state = stored.state == RunState::kStale ? RunState::kPending : stored.state;
    r.cpu_s = Number(stored.json, "cpu_s");
    if (r.state == RunState::kFailed) r.error = stored.json.value("error", "");
    if (r.state == RunState::kDone && stored.json.contains("metrics")) {
      const nlohmann::json& m = stored.json["metrics"];
      r.forward = ReadRunMetrics(m);
      if (m.contains("smoothed") && m["smoothed"].is_object()) r.smoothed = ReadRunMetrics(m["smoothed"]);
      r.gps_rejected = Integer(m, "gps_rejected");
      r.gps_resets = Integer(m, "gps_resets");
      r.frames = Integer(m, "frames");
      r.figures = ReadRunFigures(m);
    }
    rows.push_back(r);
  }
  return rows;
}

Distribution Distribute(std::vector<double> v) {
  Distribution d;
  d.n = v.size();
  if (v.empty()) return d;
  std::sort(v.begin(), v.end());
  auto q = [&](double p) {
    const double k = (v.size() - 1) * p;
    const size_t lo = static_cast<size_t>(k), hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (v[hi] - v[lo]) * (k - lo);
  };
  d.median = q(0.5);
  d.p90 = q(0.9);
  d.max = v.back();
  return d;
}

namespace {

// What a group's figures gather from its done runs, before the distributions.
struct GroupValues {
  MetricValues forward, smoothed;
  size_t nees_n = 0, nees_over = 0;
  std::vector<double> end_every, added, reconverge, nees_ratio, vertical, speed_scale;
  int64_t vo_rejected = 0;

  void Add(const ResultRow& r, GroupSummary& s) {
    forward.Add(r.forward);
    if (r.smoothed) smoothed.Add(*r.smoothed);
    if (r.forward.nees_mean && r.forward.nees_bound_99) {
      ++nees_n;
      if (*r.forward.nees_mean > *r.forward.nees_bound_99) {
        ++nees_over;
        s.nees_over_bound_seeds.push_back(r.seed);
      }
      nees_ratio.push_back(*r.forward.nees_mean / *r.forward.nees_bound_99);
    }
    s.gps_resets += r.gps_resets.value_or(0);
    s.gps_rejected += r.gps_rejected.value_or(0);
    const RunFigures& f = r.figures;
    end_every.insert(end_every.end(), f.end_error_pct.begin(), f.end_error_pct.end());
    added.insert(added.end(), f.added_error_pct.begin(), f.added_error_pct.end());
    for (const double t : f.reconverge_s) {
      if (t >= 0) reconverge.push_back(t);
      else ++s.reconverge_never;
    }
    if (f.max_vertical_error_m) vertical.push_back(*f.max_vertical_error_m);
    if (f.speed_scale_error) speed_scale.push_back(*f.speed_scale_error);
    AddCounts(s.modes, f.modes);
    AddCounts(s.vo_health, f.vo_health);
    const int64_t fixes = f.gps_used + r.gps_rejected.value_or(0);
    s.gps_fixes += fixes;
    s.gps_expected_false_alarms += static_cast<double>(fixes) * (1 - r.gps_gate_probability);
    s.gps_rejected_vertical += f.gps_rejected_vertical;
    s.gps_longest_rejection_run = std::max(s.gps_longest_rejection_run, f.longest_rejection_run);
    vo_rejected += f.vo_rejected_by_gate;
  }

  void Finish(GroupSummary& s) const {
    s.forward = forward.Distributions();
    s.smoothed = smoothed.Distributions();
    s.nees_over_bound_share = nees_n ? static_cast<double>(nees_over) / nees_n : 0;
    s.end_error_pct_every = Distribute(end_every);
    s.added_error_pct = Distribute(added);
    s.reconverge_s = Distribute(reconverge);
    s.nees_mean_over_bound = Distribute(nees_ratio);
    s.max_vertical_error_m = Distribute(vertical);
    s.speed_scale_error = Distribute(speed_scale);
    s.vo_rejected_per_run = s.done ? static_cast<double>(vo_rejected) / s.done : 0;
  }
};

}  // namespace

std::vector<GroupSummary> Summarize(const std::vector<ResultRow>& rows) {
  // Groups in the order their first run appears (plan order: recording, scenario, imu).
  std::vector<GroupSummary> groups;
  std::map<std::tuple<std::string, std::string, bool>, size_t> index;
  std::vector<GroupValues> values;
  for (const auto& r : rows) {
    const auto k = std::make_tuple(r.recording, r.scenario, r.imu);
    auto it = index.find(k);
    if (it == index.end()) {
      it = index.emplace(k, groups.size()).first;
      GroupSummary fresh;
      fresh.recording = r.recording;
      fresh.scenario = r.scenario;
      fresh.imu = r.imu;
      groups.push_back(fresh);
      values.emplace_back();
    }
    const size_t g = it->second;
    GroupSummary& s = groups[g];
    ++s.runs;
    if (r.state == RunState::kFailed) ++s.failed;
    if (r.state == RunState::kPending) ++s.pending;
    if (r.state != RunState::kDone) continue;
    ++s.done;
    values[g].Add(r, s);
  }
  for (size_t g = 0; g < groups.size(); ++g) values[g].Finish(groups[g]);
  return groups;
}

void WriteResultsCsv(const std::vector<ResultRow>& rows, bool smoothed, const fs::path& file) {
  auto out = Open(file);
  // Columns added later come last, so the first ones keep their positions.
  out << "recording,scenario,seed,imu,status,end_error_pct,rmse_gps_m,nees_mean,nees_bound_99,end_error_m,"
         "gps_rejected,gps_resets,frames,cpu_s,run_id,error";
  for (const auto& f : kForwardAdded) out << ',' << f.name;
  if (smoothed)
    for (const auto& f : kMetricFields) out << ',' << f.name << "_smoothed";
  out << ",max_vertical_error_m,gps_rejected_vertical,end_error_pct_every_outage\n";
  auto I = [](std::optional<int64_t> v) { return v ? std::to_string(*v) : std::string(); };
  for (const auto& r : rows) {
    const RunMetrics& m = r.forward;
    out << Csv(r.recording) << ',' << Csv(r.scenario) << ',' << r.seed << ',' << (r.imu ? "on" : "off") << ','
        << ToString(r.state) << ',' << Fmt(m.end_error_pct) << ',' << Fmt(m.rmse_gps_m) << ',' << Fmt(m.nees_mean)
        << ',' << Fmt(m.nees_bound_99) << ',' << Fmt(m.end_error_m) << ',' << I(r.gps_rejected) << ','
        << I(r.gps_resets) << ',' << I(r.frames) << ',' << Fmt(r.cpu_s) << ',' << r.id << ',' << Csv(r.error);
    for (const auto& f : kForwardAdded) out << ',' << Fmt(m.*f.value);
    if (smoothed)
      for (const auto& f : kMetricFields) out << ',' << (r.smoothed ? Fmt((*r.smoothed).*f.value) : std::string());
    // A done run's figures beyond the first outage (every outage's end error, space-separated).
    const bool done = r.state == RunState::kDone;
    std::string every;
    for (const double v : r.figures.end_error_pct) {
      if (!every.empty()) every += ' ';
      every += Fmt(v);
    }
    out << ',' << Fmt(r.figures.max_vertical_error_m) << ','
        << (done ? std::to_string(r.figures.gps_rejected_vertical) : std::string()) << ',' << every << '\n';
  }
}

void WriteSummaryCsv(const std::vector<GroupSummary>& groups, bool smoothed, const fs::path& file) {
  auto out = Open(file);
  out << "recording,scenario,imu,runs,done,failed,pending,end_error_pct_median,end_error_pct_p90,"
         "end_error_pct_max,end_error_m_median,end_error_m_p90,end_error_m_max,rmse_gps_m_median,rmse_gps_m_p90,"
         "rmse_gps_m_max,nees_over_bound_share,gps_resets,gps_rejected";
  for (const auto& f : kForwardAdded) out << ',' << TripleHeader(f.name);
  if (smoothed)
    for (const auto& f : kMetricFields) out << ',' << TripleHeader(std::string(f.name) + "_smoothed");
  out << ',' << TripleHeader("end_error_pct_every") << ',' << TripleHeader("added_error_pct") << ','
      << TripleHeader("reconverge_s") << ",reconverge_never,nees_over_bound_runs," << TripleHeader("nees_mean_over_bound")
      << ',' << TripleHeader("max_vertical_error_m") << ',' << TripleHeader("speed_scale_error")
      << ",gps_fixes,gps_rejected_vertical,gps_expected_false_alarms,gps_longest_rejection_run,vo_rejected_per_run\n";
  for (const auto& g : groups) {
    const MetricDistributions& d = g.forward;
    out << Csv(g.recording) << ',' << Csv(g.scenario) << ',' << (g.imu ? "on" : "off") << ',' << g.runs << ','
        << g.done << ',' << g.failed << ',' << g.pending << ',' << CsvTriple(d.end_error_pct) << ','
        << CsvTriple(d.end_error_m) << ',' << CsvTriple(d.rmse_gps_m) << ',' << Fmt(g.nees_over_bound_share) << ','
        << g.gps_resets << ',' << g.gps_rejected;
    for (const auto& f : kForwardAdded) out << ',' << CsvTriple(d.*f.distribution);
    if (smoothed)
      for (const auto& f : kMetricFields) out << ',' << CsvTriple(g.smoothed.*f.distribution);
    out << ',' << CsvTriple(g.end_error_pct_every) << ',' << CsvTriple(g.added_error_pct) << ','
        << CsvTriple(g.reconverge_s) << ',' << g.reconverge_never << ',' << g.nees_over_bound_seeds.size() << ','
        << CsvTriple(g.nees_mean_over_bound) << ',' << CsvTriple(g.max_vertical_error_m) << ','
        << CsvTriple(g.speed_scale_error) << ',' << g.gps_fixes << ',' << g.gps_rejected_vertical << ','
        << Fmt(g.gps_expected_false_alarms) << ',' << g.gps_longest_rejection_run << ',' << Fmt(g.vo_rejected_per_run)
        << '\n';
  }
}

void WriteSummaryJson(const std::vector<GroupSummary>& groups, bool smoothed, const fs::path& file) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& g : groups) {
    nlohmann::json o = {{"recording", g.recording},
                        {"scenario", g.scenario},
                        {"imu", g.imu},
                        {"runs", g.runs},
                        {"done", g.done},
                        {"failed", g.failed},
                        {"pending", g.pending},
                        {"nees_over_bound_share", g.nees_over_bound_share},
                        {"gps_resets", g.gps_resets},
                        {"gps_rejected", g.gps_rejected}};
    for (const auto& f : kMetricFields) o[f.name] = ToJson(g.forward.*f.distribution);
    o["end_error_pct_every"] = ToJson(g.end_error_pct_every);
    o["added_error_pct"] = ToJson(g.added_error_pct);
    o["reconverge_s"] = ToJson(g.reconverge_s);
    o["reconverge_never"] = g.reconverge_never;
    o["nees_mean_over_bound"] = ToJson(g.nees_mean_over_bound);
    o["nees_over_bound_seeds"] = g.nees_over_bound_seeds;
    o["max_vertical_error_m"] = ToJson(g.max_vertical_error_m);
    o["speed_scale_error"] = ToJson(g.speed_scale_error);
    o["modes"] = g.modes;
    o["vo_health"] = g.vo_health;
    o["gps_fixes"] = g.gps_fixes;
    o["gps_rejected_vertical"] = g.gps_rejected_vertical;
    o["gps_expected_false_alarms"] = g.gps_expected_false_alarms;
    o["gps_longest_rejection_run"] = g.gps_longest_rejection_run;
    o["vo_rejected_per_run"] = g.vo_rejected_per_run;
    if (smoothed) {
      o["smoothed"] = nlohmann::json::object();
      for (const auto& f : kMetricFields) o["smoothed"][f.name] = ToJson(g.smoothed.*f.distribution);
    }
    j.push_back(o);
  }
  WriteJsonAtomically(file, j);
}

}  // namespace locaid::sweep
