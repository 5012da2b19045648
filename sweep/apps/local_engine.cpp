#include "sweep/apps/local_engine.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/result_store.hpp"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <thread>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

volatile sig_atomic_t g_stop = 0;
void OnStop(int) { g_stop = 1; }

using Clock = std::chrono::steady_clock;

struct Running {
  Stage stage;
  size_t index;  // array index
  Clock::time_point start;
  std::string log;
};

std::string Duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

}  // namespace

bool LocalStopRequested() { return g_stop != 0; }

LocalOutcome RunLocal(const Plan& plan, const std::string& self_exe, int jobs) {
  g_stop = 0;
  struct sigaction sa {}, old_int {}, old_term {};
  sa.sa_handler = OnStop;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, &old_int);
  ::sigaction(SIGTERM, &sa, &old_term);

  // The VO tasks of this run; a filter task waits for its VO task if that is one of them.
  std::map<size_t, size_t> vo_array_of_task;
  for (size_t i = 0; i < plan.vo_array.size(); ++i) vo_array_of_task[plan.vo_array[i]] = i;
  std::set<size_t> vo_ended;  // array indices
  size_t next_vo = 0;
  std::vector<size_t> waiting_filter;  // array indices not started yet
  for (size_t i = 0; i < plan.filter_array.size(); ++i) waiting_filter.push_back(i);

  const size_t total = plan.vo_array.size() + plan.filter_array.size();
  LocalOutcome out;
  std::map<pid_t, Running> running;
  double wall_sum[2] = {0, 0};
  size_t wall_n[2] = {0, 0};
  const bool tty = ::isatty(2) != 0;
  auto last_line = Clock::now();
  fs::create_directories(fs::path(plan.dir) / "logs");

  auto ready = [&](size_t filter_index) {
    const int vo = plan.filter[plan.filter_array[filter_index]].vo_task;
    if (vo < 0) return true;
    const auto it = vo_array_of_task.find(static_cast<size_t>(vo));
    return it == vo_array_of_task.end() || vo_ended.count(it->second) > 0;
  };
  auto start = [&](Stage stage, size_t index) {
    const auto& tasks_id = stage == Stage::kVo ? plan.vo[plan.vo_array[index]].id
                                               : plan.filter[plan.filter_array[index]].id;
    const std::string log = (fs::path(plan.dir) / "logs" / (tasks_id + ".log")).string();
    const pid_t pid = StartChild({{self_exe, "task", plan.dir, "--stage", ToString(stage), "--index",
                                   std::to_string(index)},
                                  "/dev/null", log, true});
    running[pid] = {stage, index, Clock::now(), log};
  };
  auto eta = [&]() {
    const size_t vo_left = plan.vo_array.size() - next_vo + 0;
    double s = 0;
    for (int k = 0; k < 2; ++k)
      if (wall_n[k] == 0 && (k == 0 ? vo_left : waiting_filter.size()) > 0) return std::nan("");
    if (wall_n[0]) s += vo_left * wall_sum[0] / wall_n[0];
    if (wall_n[1]) s += waiting_filter.size() * wall_sum[1] / wall_n[1];
    if (wall_n[1]) s += running.size() * 0.5 * wall_sum[1] / wall_n[1];  // about half of each is left
    return s / jobs;
  };
  auto progress = [&](bool final_line) {
    const size_t finished = out.done + out.failed;
    const std::string line = "locaid-sweep: " + std::to_string(finished) + "/" + std::to_string(total) +
                             " runs (" + std::to_string(out.done) + " done, " + std::to_string(out.failed) +
                             " failed), " + std::to_string(running.size()) + " running, ETA " +
                             (final_line ? std::string("0:00") : Duration(eta()));
    if (tty) {
      std::cerr << "\r" << line << "   " << (final_line ? "\n" : "") << std::flush;
    } else if (final_line || Clock::now() - last_line > std::chrono::seconds(15)) {
      std::cerr << line << "\n";
      last_line = Clock::now();
    }
  };

  for (;;) {
    // Start what may start: VO first (filter runs wait on it), then filter runs.
    while (!g_stop && static_cast<int>(running.size()) < jobs) {
      if (next_vo < plan.vo_array.size()) {
        start(Stage::kVo, next_vo++);
        continue;
      }
      auto it = waiting_filter.begin();
      while (it != waiting_filter.end() && !ready(*it)) ++it;
      if (it == waiting_filter.end()) break;
      start(Stage::kFilter, *it);
      waiting_filter.erase(it);
    }
    if (running.empty()) break;
    if (g_stop) {
      for (const auto& [pid, r] : running) ::kill(-pid, SIGINT);  // the task and its locaid-replay
    }
    bool reaped = false;
    for (auto it = running.begin(); it != running.end();) {
      const auto exit = ReapChild(it->first, g_stop != 0);
      if (!exit) {
        ++it;
        continue;
      }
      reaped = true;
      const Running& r = it->second;
      const int k = r.stage == Stage::kVo ? 0 : 1;
      if (r.stage == Stage::kVo) vo_ended.insert(r.index);
      if (exit->exit_code == 0) {
        ++out.done;
      } else if (exit->exit_code == 130 || (g_stop && exit->signal != 0)) {
        ++out.left;  // interrupted: stays pending
      } else {
        ++out.failed;
        if (exit->exit_code != 1)  // 1: the task stored the failure itself
          std::cerr << "\nlocaid-sweep: task process " << Describe(*exit) << "; see " << r.log << "\n";
      }
      if (exit->exit_code == 0 || exit->exit_code == 1) {
        wall_sum[k] += std::chrono::duration<double>(Clock::now() - r.start).count();
        ++wall_n[k];
      }
      std::error_code ec;
      if (exit->exit_code == 0 && fs::file_size(r.log, ec) == 0) fs::remove(r.log, ec);
      it = running.erase(it);
    }
    progress(false);
    // A short nap: a run of a short drive takes a fraction of a second, and a
    // longer poll interval would add to each of them.
    if (!reaped) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  out.left += plan.vo_array.size() - next_vo + waiting_filter.size();
  out.interrupted = g_stop != 0;
  progress(true);
  ::sigaction(SIGINT, &old_int, nullptr);
  ::sigaction(SIGTERM, &old_term, nullptr);
  return out;
}

}  // namespace locaid::sweep
