#include "sweep/apps/task_command.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/recording.hpp"
#include "sweep/result_store.hpp"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <iostream>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

volatile sig_atomic_t g_child = 0;
volatile sig_atomic_t g_signal = 0;

void Forward(int sig) {
  g_signal = sig;
  if (g_child > 0) ::kill(g_child, sig);
}

std::optional<size_t> IndexFromEnvironment() {
  for (const char* name : {"SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"}) {
    const char* v = std::getenv(name);
    if (v == nullptr || *v == '\0') continue;
    char* end = nullptr;
    const unsigned long long n = std::strtoull(v, &end, 10);
    if (*end == '\0') return static_cast<size_t>(n);
  }
  return std::nullopt;
}

std::string HostName() {
  char host[256] = {};
  ::gethostname(host, sizeof host - 1);
  return host;
}

// What every result of a task says about its run.
nlohmann::json Header(const Plan& plan, Stage stage, size_t task) {
  nlohmann::json j;
  if (stage == Stage::kVo) {
    const VoTask& t = plan.vo[task];
    j = {{"id", t.id}, {"key", t.key}, {"stage", "vo"}, {"recording", plan.recordings[t.recording].path},
         {"args", t.args}};
  } else {
    const FilterTask& t = plan.filter[task];
    j = {{"id", t.id},       {"key", t.key},   {"stage", "filter"}, {"recording", plan.recordings[t.recording].path},
         {"scenario", t.scenario}, {"seed", t.seed}, {"imu", t.imu}, {"args", t.args}};
  }
  j["replay"] = plan.replay;
  j["host"] = HostName();
  const char* job = std::getenv("SLURM_ARRAY_JOB_ID");
  const char* array_task = std::getenv("SLURM_ARRAY_TASK_ID");
  if (job != nullptr && array_task != nullptr) j["slurm_job"] = std::string(job) + "_" + array_task;
  return j;
}

int Fail(const fs::path& dir, nlohmann::json result, const std::string& error) {
  result["status"] = "failed";
  result["error"] = error;
  StoreResult(dir, result["id"], result);
  std::cerr << "locaid-sweep task " << result["id"].get<std::string>() << ": failed: " << error << "\n";
  return 1;
}

// One run of the plan: its checks, its locaid-replay child, its stored
// result. Returns 0 done, 1 failed (stored), 130 interrupted (nothing stored).
int RunOne(const Plan& plan, const fs::path& dir, Stage stage, size_t task) {
  nlohmann::json result = Header(plan, stage, task);
  const std::vector<std::string>& args = stage == Stage::kVo ? plan.vo[task].args : plan.filter[task].args;

  if (FileFingerprint(plan.replay) != plan.replay_fingerprint)
    return Fail(dir, result, plan.replay + " is not the locaid-replay the sweep was planned with (rebuilt or "
                                           "missing on this node); run `locaid-sweep run` again to re-plan");
  if (stage == Stage::kVo) {
    std::error_code ec;
    fs::remove(plan.vo[task].cache, ec);  // else locaid-replay would read it instead of writing it
    fs::create_directories(fs::path(plan.vo[task].cache).parent_path(), ec);
  } else if (const int vo = plan.filter[task].vo_task; vo >= 0) {
    // A filter run needs its recording's VO: say which VO run failed instead of
    // letting locaid-replay find no cache.
    const VoTask& v = plan.vo[static_cast<size_t>(vo)];
    const StoredResult vo_result = ReadResult(dir, v.id, v.key);
    if (vo_result.state == RunState::kFailed)
      return Fail(dir, result, "VO run " + v.id + " of this recording failed: " + vo_result.json.value("error", ""));
    if (vo_result.state != RunState::kDone || !fs::exists(v.cache))
      return Fail(dir, result, "VO run " + v.id + " of this recording has no result (the VO stage did not finish)");
  }

  const fs::path tmp = dir / "tmp";
  fs::create_directories(tmp);
  const std::string base = (tmp / (result["id"].get<std::string>() + "." + std::to_string(::getpid()))).string();
  ChildSpec spec{{plan.replay}, base + ".out", base + ".err", false};
  spec.argv.insert(spec.argv.end(), args.begin(), args.end());

  const auto t0 = std::chrono::steady_clock::now();
  ChildExit exit;
  try {
    g_child = StartChild(spec);
    if (g_signal != 0) ::kill(g_child, g_signal);  // came before the pid was known
    exit = *ReapChild(g_child, true);
    g_child = 0;
  } catch (const std::exception& e) {
    g_child = 0;
    return Fail(dir, result, e.what());
  }
  result["wall_s"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result["cpu_s"] = exit.cpu_s;
  const std::string out = ReadFileText(spec.stdout_path);
  const std::vector<std::string> tail = TailLines(spec.stderr_path, 20);
  std::error_code ec;
  fs::remove(spec.stdout_path, ec);
  fs::remove(spec.stderr_path, ec);
  if (g_signal == SIGINT) {
    std::cerr << "locaid-sweep task " << result["id"].get<std::string>() << ": interrupted, nothing stored\n";
    return 130;
  }

  result["exit_code"] = exit.exit_code >= 0 ? nlohmann::json(exit.exit_code) : nlohmann::json(nullptr);
  result["signal"] = exit.signal != 0 ? nlohmann::json(exit.signal) : nlohmann::json(nullptr);
  result["stderr_tail"] = tail;
  if (exit.exit_code != 0 || exit.signal != 0) {
    // locaid-replay's own message ("locaid-replay: FILE: why") says most.
    std::string why = Describe(exit);
    for (auto it = tail.rbegin(); it != tail.rend(); ++it)
      if (it->rfind("locaid-replay", 0) == 0) {
        why = *it + " (" + why + ")";
        break;
      }
    return Fail(dir, result, why);
  }
  try {
    result["metrics"] = nlohmann::json::parse(out);
  } catch (const nlohmann::json::exception&) {
    return Fail(dir, result, "locaid-replay exited 0 but printed no JSON");
  }
  if (stage == Stage::kVo && !fs::exists(plan.vo[task].cache))
    return Fail(dir, result, "locaid-replay exited 0 but wrote no VO cache " + plan.vo[task].cache);
  result["status"] = "done";
  StoreResult(dir, result["id"], result);
  std::cerr << "locaid-sweep task " << result["id"].get<std::string>() << ": done in " << exit.cpu_s
            << " s CPU\n";
  return 0;
}

}  // namespace

int RunTask(const fs::path& dir_arg, Stage stage, std::optional<size_t> index) {
  const fs::path dir = fs::absolute(dir_arg);
  Plan plan;
  try {
    plan = ReadPlan(dir);
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep task: " << e.what() << "\n";
    return 2;
  }
  if (!index) index = IndexFromEnvironment();
  const size_t tasks = plan.array_tasks(stage);
  if (!index || *index >= tasks) {
    std::cerr << "locaid-sweep task: " << (index ? "index " + std::to_string(*index) + " is not" : "no index given,")
              << " in the plan's " << ToString(stage) << " array of " << tasks
              << " tasks (--index N, SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX)\n";
    return 2;
  }
  const std::vector<size_t> batch = plan.batch(stage, *index);
  auto id_of = [&](size_t task) -> const std::string& {
    return stage == Stage::kVo ? plan.vo[task].id : plan.filter[task].id;
  };
  auto key_of = [&](size_t task) -> const std::string& {
    return stage == Stage::kVo ? plan.vo[task].key : plan.filter[task].key;
  };

  struct sigaction sa {};
  sa.sa_handler = Forward;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGTERM, &sa, nullptr);
  ::sigaction(SIGINT, &sa, nullptr);

  size_t failed = 0, ran = 0;
  for (const size_t task : batch) {
    if (g_signal != 0) break;
    // Done by an earlier attempt of this array task (a requeue, a retried pod);
    // a VO run also needs its cache still there (`run` replans one whose cache is gone).
    if (ReadResult(dir, id_of(task), key_of(task)).state == RunState::kDone &&
        (stage != Stage::kVo || fs::exists(plan.vo[task].cache))) {
      ++ran;
      continue;
    }
    const int rc = RunOne(plan, dir, stage, task);
    if (rc == 130) return 130;
    failed += rc != 0;
    ++ran;
  }
  if (g_signal != 0) {
    // SIGTERM: the run it reached is recorded as failed; the ones after it never started.
    if (ran < batch.size()) {
      std::cerr << "locaid-sweep task: stopped by signal " << g_signal << " after " << ran << " of " << batch.size()
                << " runs; left pending:";
      for (size_t i = ran; i < batch.size(); ++i) std::cerr << " " << id_of(batch[i]);
      std::cerr << "\n";
    }
    return 128 + g_signal;
  }
  return failed == 0 ? 0 : 1;
}

}  // namespace locaid::sweep
