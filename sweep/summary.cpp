#include "sweep/summary.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

std::optional<double> Number(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) return std::nullopt;
  return j[key].get<double>();
}
std::optional<int64_t> Integer(const nlohmann::json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number_integer()) return std::nullopt;
  return j[key].get<int64_t>();
}

// Shortest text that reads back as the same double ("" for none).
std::string Fmt(std::optional<double> v) {
  if (!v) return "";
  std::ostringstream s;
  s.precision(17);
  s << *v;
  double back = 0;
  for (int p = 6; p <= 17; ++p) {  // fewer digits where they round-trip
    std::ostringstream t;
    t.precision(p);
    t << *v;
    std::istringstream(t.str()) >> back;
    if (back == *v) return t.str();
  }
  return s.str();
}

std::string Csv(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (const char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return out + "\"";
}

std::ofstream Open(const fs::path& file) {
  std::ofstream out(file);
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
  return out;
}

nlohmann::json ToJson(const Distribution& d) {
  if (d.n == 0) return nullptr;
  return {{"n", d.n}, {"median", d.median}, {"p90", d.p90}, {"max", d.max}};
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

std::vector<ResultRow> CollectRows(const Plan& plan) {
  std::vector<ResultRow> rows;
  for (const auto& t : plan.filter) {
    ResultRow r;
    r.id = t.id;
    r.recording = plan.recordings[t.recording].path;
    r.scenario = t.scenario;
    r.seed = t.seed;
    r.imu = t.imu;
    const StoredResult stored = ReadResult(plan.dir, t.id, t.key);
    r.state = stored.state == RunState::kStale ? RunState::kPending : stored.state;
    r.cpu_s = Number(stored.json, "cpu_s");
    if (r.state == RunState::kFailed) r.error = stored.json.value("error", "");
    if (r.state == RunState::kDone && stored.json.contains("metrics")) {
      const nlohmann::json& m = stored.json["metrics"];
      r.rmse_gps_m = Number(m, "rmse_gps_m");
      r.nees_mean = Number(m, "nees_mean");
      r.nees_bound_99 = Number(m, "nees_bound_99");
      r.gps_rejected = Integer(m, "gps_rejected");
      r.gps_resets = Integer(m, "gps_resets");
      r.frames = Integer(m, "frames");
      if (m.contains("outages") && m["outages"].is_array() && !m["outages"].empty()) {
        r.end_error_pct = Number(m["outages"][0], "end_error_pct");
        r.end_error_m = Number(m["outages"][0], "end_error_m");
      }
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

std::vector<GroupSummary> Summarize(const std::vector<ResultRow>& rows) {
  // Groups in the order their first run appears (plan order: recording, scenario, imu).
  std::vector<GroupSummary> groups;
  std::map<std::tuple<std::string, std::string, bool>, size_t> index;
  std::vector<std::vector<double>> pct, m, rmse;
  std::vector<size_t> nees_over, nees_n;
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
      pct.emplace_back();
      m.emplace_back();
      rmse.emplace_back();
      nees_over.push_back(0);
      nees_n.push_back(0);
    }
    const size_t g = it->second;
    GroupSummary& s = groups[g];
    ++s.runs;
    if (r.state == RunState::kFailed) ++s.failed;
    if (r.state == RunState::kPending) ++s.pending;
    if (r.state != RunState::kDone) continue;
    ++s.done;
    if (r.end_error_pct) pct[g].push_back(*r.end_error_pct);
    if (r.end_error_m) m[g].push_back(*r.end_error_m);
    if (r.rmse_gps_m && std::isfinite(*r.rmse_gps_m)) rmse[g].push_back(*r.rmse_gps_m);
    if (r.nees_mean && r.nees_bound_99) {
      ++nees_n[g];
      if (*r.nees_mean > *r.nees_bound_99) ++nees_over[g];
    }
    s.gps_resets += r.gps_resets.value_or(0);
    s.gps_rejected += r.gps_rejected.value_or(0);
  }
  for (size_t g = 0; g < groups.size(); ++g) {
    groups[g].end_error_pct = Distribute(pct[g]);
    groups[g].end_error_m = Distribute(m[g]);
    groups[g].rmse_gps_m = Distribute(rmse[g]);
    groups[g].nees_over_bound_share = nees_n[g] ? static_cast<double>(nees_over[g]) / nees_n[g] : 0;
  }
  return groups;
}

void WriteResultsCsv(const std::vector<ResultRow>& rows, const fs::path& file) {
  auto out = Open(file);
  out << "recording,scenario,seed,imu,status,end_error_pct,rmse_gps_m,nees_mean,nees_bound_99,end_error_m,"
         "gps_rejected,gps_resets,frames,cpu_s,run_id,error\n";
  auto I = [](std::optional<int64_t> v) { return v ? std::to_string(*v) : std::string(); };
  for (const auto& r : rows)
    out << Csv(r.recording) << ',' << Csv(r.scenario) << ',' << r.seed << ',' << (r.imu ? "on" : "off") << ','
        << ToString(r.state) << ',' << Fmt(r.end_error_pct) << ',' << Fmt(r.rmse_gps_m) << ',' << Fmt(r.nees_mean)
        << ',' << Fmt(r.nees_bound_99) << ',' << Fmt(r.end_error_m) << ',' << I(r.gps_rejected) << ','
        << I(r.gps_resets) << ',' << I(r.frames) << ',' << Fmt(r.cpu_s) << ',' << r.id << ',' << Csv(r.error)
        << '\n';
}

void WriteSummaryCsv(const std::vector<GroupSummary>& groups, const fs::path& file) {
  auto out = Open(file);
  out << "recording,scenario,imu,runs,done,failed,pending,end_error_pct_median,end_error_pct_p90,"
         "end_error_pct_max,end_error_m_median,end_error_m_p90,end_error_m_max,rmse_gps_m_median,rmse_gps_m_p90,"
         "rmse_gps_m_max,nees_over_bound_share,gps_resets,gps_rejected\n";
  auto D = [](const Distribution& d) {
    if (d.n == 0) return std::string(",,");
    return Fmt(d.median) + "," + Fmt(d.p90) + "," + Fmt(d.max);
  };
  for (const auto& g : groups)
    out << Csv(g.recording) << ',' << Csv(g.scenario) << ',' << (g.imu ? "on" : "off") << ',' << g.runs << ','
        << g.done << ',' << g.failed << ',' << g.pending << ',' << D(g.end_error_pct) << ',' << D(g.end_error_m)
        << ',' << D(g.rmse_gps_m) << ',' << Fmt(g.nees_over_bound_share) << ',' << g.gps_resets << ','
        << g.gps_rejected << '\n';
}

void WriteSummaryJson(const std::vector<GroupSummary>& groups, const fs::path& file) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& g : groups)
    j.push_back({{"recording", g.recording},
                 {"scenario", g.scenario},
                 {"imu", g.imu},
                 {"runs", g.runs},
                 {"done", g.done},
                 {"failed", g.failed},
                 {"pending", g.pending},
                 {"end_error_pct", ToJson(g.end_error_pct)},
                 {"end_error_m", ToJson(g.end_error_m)},
                 {"rmse_gps_m", ToJson(g.rmse_gps_m)},
                 {"nees_over_bound_share", g.nees_over_bound_share},
                 {"gps_resets", g.gps_resets},
                 {"gps_rejected", g.gps_rejected}});
  WriteJsonAtomically(file, j);
}

void WriteReportMd(const Plan& plan, const std::vector<ResultRow>& rows, const std::vector<GroupSummary>& groups,
                   const std::vector<std::string>& plots, const std::string& plot_note, const fs::path& file) {
  size_t done = 0, failed = 0;
  for (const auto& r : rows) {
    done += r.state == RunState::kDone;
    failed += r.state == RunState::kFailed;
  }
  auto out = Open(file);
  out << "# Sweep report\n\n"
      << "Manifest `" << plan.manifest << "`, locaid " << plan.locaid_version << ": " << plan.recordings.size()
      << " recordings, " << rows.size() << " filter runs: " << done << " done, " << failed << " failed, "
      << rows.size() - done - failed << " pending.\n\n"
      << "- [results.csv](results.csv): one row per run (end_error_pct: the first outage's, % of the distance "
         "driven in it; empty without an outage)\n"
      << "- [summary.csv](summary.csv), [summary.json](summary.json): per recording x scenario x IMU\n\n";
  if (!plots.empty()) {
    out << "## End-of-outage error\n\n";
    for (const auto& p : plots) out << "![" << p << "](" << p << ")\n\n";
  } else {
    out << "No plots: " << plot_note << "\n\n";
  }
  out << "## Summary\n\n"
      << "| recording | scenario | IMU | done / runs | failed | end error % median / p90 / max | RMSE m median | "
         "NEES > 99 % bound |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& g : groups) {
    const auto& d = g.end_error_pct;
    out << "| " << fs::path(g.recording).filename().string() << " | " << g.scenario << " | "
        << (g.imu ? "on" : "off") << " | " << g.done << " / " << g.runs << " | " << g.failed << " | "
        << (d.n ? Fmt(std::round(d.median * 100) / 100) + " / " + Fmt(std::round(d.p90 * 100) / 100) + " / " +
                      Fmt(std::round(d.max * 100) / 100)
                : std::string("-"))
        << " | " << (g.rmse_gps_m.n ? Fmt(std::round(g.rmse_gps_m.median * 1000) / 1000) : std::string("-"))
        << " | " << Fmt(std::round(g.nees_over_bound_share * 1000) / 10) << " % |\n";
  }
  if (failed > 0) {
    out << "\n## Failed runs\n\n";
    for (const auto& r : rows)
      if (r.state == RunState::kFailed) out << "- `" << r.id << "`: " << r.error << "\n";
  }
}

}  // namespace locaid::sweep
