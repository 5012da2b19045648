#include "sweep/apps/estimate.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/apps/run_command.hpp"
#include "sweep/batching.hpp"
#include "sweep/result_store.hpp"
#include "sweep/summary.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

struct Costs {
  double vo_cpu_s = 0, filter_cpu_s = 0;  // a filter run from the cache
  std::string how;
};

double CpuOf(const fs::path& dir, const std::string& id, const std::string& key) {
  const StoredResult r = ReadResult(dir, id, key);
  return r.state == RunState::kDone ? r.json.value("cpu_s", -1.0) : -1.0;
}

// Medians of the done runs in the plan's DIR; nullopt without both kinds.
std::optional<Costs> FromDir(const Plan& plan) {
  std::vector<double> vo, filter;
  for (const auto& t : plan.vo)
    if (const double c = CpuOf(plan.dir, t.id, t.key); c >= 0) vo.push_back(c);
  for (const auto& t : plan.filter)
    if (const double c = CpuOf(plan.dir, t.id, t.key); c >= 0 && t.vo_task >= 0) filter.push_back(c);
  if (vo.empty() || filter.empty()) return std::nullopt;
  return Costs{Distribute(vo).median, Distribute(filter).median,
               "the median CPU time of the " + std::to_string(vo.size()) + " VO runs and " +
                   std::to_string(filter.size()) + " filter runs already done in " + plan.dir};
}

// One VO run and one filter run (reading its cache) of the first recording,
// in a temporary folder, through `locaid-sweep task` as the engines run them.
Costs Measure(const Plan& full, const std::string& self) {
  const char* env = std::getenv("TMPDIR");
  std::string pattern = std::string(env && *env ? env : "/tmp") + "/locaid-sweep-plan-XXXXXX";
  if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp " + pattern);
  const fs::path tmp = pattern;
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{tmp};

  // The first run reading the first VO cache; without VO runs (every
  // scenario has camera faults) the first run, which does VO itself.
  size_t pick = 0;
  for (size_t i = 0; i < full.filter.size(); ++i)
    if (!full.vo.empty() && full.filter[i].vo_task == 0) {
      pick = i;
      break;
    }
  // The same tasks, pointed at the temporary folder.
  Plan p = full;
  auto retarget = [&](std::vector<std::string>& args) {
    for (auto& a : args)
      if (a.rfind(full.dir, 0) == 0) a = tmp.string() + a.substr(full.dir.size());
  };
  p.dir = tmp.string();
  p.vo.clear();
  p.vo_array.clear();
  if (!full.vo.empty()) {
    p.vo = {full.vo[0]};
    p.vo[0].cache = tmp.string() + full.vo[0].cache.substr(full.dir.size());
    retarget(p.vo[0].args);
    p.vo_array = {0};
  }
  p.filter = {full.filter[pick]};
  p.filter[0].vo_task = p.vo.empty() ? -1 : 0;
  retarget(p.filter[0].args);
  p.filter_array = {0};
  WritePlan(p);
  std::cerr << "locaid-sweep: measuring " << (p.vo.empty() ? "" : "one VO run and ") << "one filter run of "
            << full.recordings[p.filter[0].recording].path << " ...\n";
  for (const char* stage : {"vo", "filter"}) {
    if (p.vo.empty() && std::string(stage) == "vo") continue;
    std::string out, err;
    const ChildExit e = RunToEnd({self, "task", tmp.string(), "--stage", stage, "--index", "0"}, out, err);
    if (e.exit_code != 0) throw std::runtime_error(std::string("the measured ") + stage + " run failed: " + err);
  }
  Costs c;
  c.filter_cpu_s = CpuOf(tmp, p.filter[0].id, p.filter[0].key);
  c.vo_cpu_s = p.vo.empty() ? c.filter_cpu_s : CpuOf(tmp, p.vo[0].id, p.vo[0].key);
  std::ostringstream s;
  s.precision(3);
  if (!p.vo.empty()) s << "one VO run (" << c.vo_cpu_s << " s CPU) and ";
  s << "one filter run" << (p.vo.empty() ? " (with VO)" : " from its cache") << " (" << c.filter_cpu_s
    << " s CPU) of " << full.recordings[p.filter[0].recording].path
    << ", measured now; every recording is assumed to cost as much as this one (the cost grows with its frames)";
  c.how = s.str();
  return c;
}

fs::path CostsFile(const std::string& dir) { return fs::path(dir) / "costs.json"; }

std::optional<double> Median(std::vector<double> v) {
  if (v.empty()) return std::nullopt;
  return Distribute(std::move(v)).median;
}

std::string Hours(double s) {
  char buf[64];
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%.1f h", s / 3600);
  else if (s >= 60) std::snprintf(buf, sizeof buf, "%.1f min", s / 60);
  else std::snprintf(buf, sizeof buf, "%.1f s", s);
  return buf;
}

}  // namespace

std::optional<RunCostEstimate> EstimatePendingFilterRun(const Plan& plan) {
  if (plan.filter_array.empty()) return std::nullopt;
  // A sample of the done runs is enough for a median (a sweep of 80,000 runs
  // need not parse every result once more).
  constexpr size_t kSample = 500;
  std::vector<double> vo, cached, uncached;
  for (const auto& t : plan.vo)
    if (vo.size() < kSample)
      if (const double c = CpuOf(plan.dir, t.id, t.key); c >= 0) vo.push_back(c);
  for (const auto& t : plan.filter) {
    auto& into = t.vo_task >= 0 ? cached : uncached;
    if (into.size() < kSample)
      if (const double c = CpuOf(plan.dir, t.id, t.key); c >= 0) into.push_back(c);
  }
  std::optional<double> c_vo = Median(vo), c_cached = Median(cached), c_uncached = Median(uncached);
  std::string source = "the median CPU time of the runs done in " + plan.dir;
  const bool from_dir = c_cached || c_uncached;
  // What the done runs do not tell, `plan --out DIR`'s measurement may.
  if (std::ifstream in(CostsFile(plan.dir)); in) {
    try {
      const auto j = nlohmann::json::parse(in);
      bool used = false;
      if (!c_cached && j.contains("filter_cpu_s")) c_cached = j["filter_cpu_s"].get<double>(), used = true;
      if (!c_vo && j.contains("vo_cpu_s")) c_vo = j["vo_cpu_s"].get<double>(), used = true;
      if (used)
        source = from_dir ? source + " and `locaid-sweep plan`'s measurement (costs.json)"
                          : "`locaid-sweep plan`'s measurement in " + CostsFile(plan.dir).string();
    } catch (const nlohmann::json::exception&) {
    }
  }
  if (!c_uncached) c_uncached = c_vo;  // a run with camera faults does VO itself
  double sum = 0;
  for (const size_t i : plan.filter_array) {
    const auto& c = plan.filter[i].vo_task >= 0 ? c_cached : c_uncached;
    if (!c) return std::nullopt;
    sum += *c;
  }
  return RunCostEstimate{sum / static_cast<double>(plan.filter_array.size()), source};
}

int PrintPlan(const PlanCommandOptions& o) {
  Plan plan;
  try {
    // Without --out, the plan's paths point at a folder that is never made.
    plan = PlanFor(o.manifest, o.out.empty() ? (fs::temp_directory_path() / "locaid-sweep-unplaced").string()
                                             : o.out);
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep: " << e.what() << "\n";
    return 2;
  }
  size_t drives = 0, cached = 0;
  for (const auto& r : plan.recordings) drives += r.kind == "drive";
  for (const auto& t : plan.filter) cached += t.vo_task >= 0;
  const size_t uncached = plan.filter.size() - cached;
  std::cout << "recordings: " << plan.recordings.size() << " (" << drives << " drive folders, "
            << plan.recordings.size() - drives << " ROS 2 bags)\n"
            << "runs: " << plan.filter.size() << " filter runs (" << cached << " from a VO cache, " << uncached
            << " with camera faults running VO themselves) + " << plan.vo.size() << " VO runs\n";
  if (!o.out.empty() && fs::exists(fs::path(plan.dir) / "runs")) {
    size_t done = 0;
    for (const auto s : TaskStates(plan, Stage::kVo)) done += s == RunState::kDone;
    for (const auto s : TaskStates(plan, Stage::kFilter)) done += s == RunState::kDone;
    std::cout << "already done in " << plan.dir << ": " << done << " of " << plan.runs() << "\n";
  }
  if (!o.measure) return 0;
  Costs c;
  bool kept = false;  // measured now and kept in DIR/costs.json
  try {
    const auto from_dir = o.out.empty() ? std::nullopt : FromDir(plan);
    c = from_dir ? *from_dir : Measure(plan, SelfExe());
    if (!from_dir && !o.out.empty()) {
      // Kept for `run --runs-per-task auto` (how many runs one array task carries).
      fs::create_directories(plan.dir);
      WriteJsonAtomically(CostsFile(plan.dir), {{"vo_cpu_s", c.vo_cpu_s},
                                                {"filter_cpu_s", c.filter_cpu_s},
                                                {"how", c.how},
                                                {"replay_fingerprint", plan.replay_fingerprint}});
      kept = true;
    }
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep: no estimate: " << e.what() << "\n";
    return 1;
  }
  // A run with camera faults does VO and the filter in one.
  const double cpu_s = plan.vo.size() * c.vo_cpu_s + cached * c.filter_cpu_s + uncached * c.vo_cpu_s;
  const int jobs = o.jobs > 0 ? o.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::cout.precision(3);
  std::cout << "estimated CPU time: " << Hours(cpu_s) << " (" << cpu_s / 3600 << " CPU hours); on this machine with "
            << jobs << " jobs about " << Hours(cpu_s / jobs) << " wall\n"
            << "estimated from " << c.how << "\n";
  // What `run --engine slurm|k8s` would submit (auto batching; a Slurm
  // cluster's MaxArraySize is read by `run`, Slurm's default assumed here).
  const double per_run = cached + uncached > 0 ? (cached * c.filter_cpu_s + uncached * c.vo_cpu_s) /
                                                     static_cast<double>(cached + uncached)
                                               : 0;
  const size_t cap = ArrayTaskCap(std::nullopt);
  const Batching b = AutoBatching(plan.filter.size(), per_run, cap);
  const size_t vo_k = std::max<size_t>(1, (plan.vo.size() + cap - 1) / cap);
  std::cout << "on Slurm or Kubernetes (--runs-per-task auto): " << (plan.vo.size() + vo_k - 1) / vo_k
            << " VO array tasks, then " << b.tasks << " filter array tasks of up to " << b.runs_per_task
            << " runs (" << b.why << "; MaxArraySize 1001 assumed)\n";
  if (kept)
    std::cout << "measurement kept in " << CostsFile(plan.dir).string() << " for `locaid-sweep run`\n";
  return 0;
}

}  // namespace locaid::sweep
