#include "sweep/batching.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace locaid::sweep {
namespace {

size_t CeilDiv(size_t a, size_t b) { return b == 0 ? 0 : (a + b - 1) / b; }

std::string Seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, s < 10 ? "%.2f s" : "%.0f s", s);
  return buf;
}

}  // namespace

size_t ArrayTaskCap(std::optional<long> max_array_size) {
  const long m = max_array_size.value_or(kDefaultMaxArraySize);
  return std::clamp<size_t>(m > 1 ? static_cast<size_t>(m - 1) : 1, 1, kMaxArrayTasks);
}

std::optional<long> ParseMaxArraySize(const std::string& text) {
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string name, eq;
    long value = 0;
    if (words >> name >> eq >> value && name == "MaxArraySize" && eq == "=") return value;
  }
  return std::nullopt;
}

Batching AutoBatching(size_t runs, std::optional<double> cpu_s_per_run, size_t cap) {
  cap = std::max<size_t>(cap, 1);
  Batching b;
  const size_t for_cap = std::max<size_t>(1, CeilDiv(runs, cap));
  b.runs_per_task = for_cap;
  std::string why = "at most " + std::to_string(cap) + " array tasks";
  if (cpu_s_per_run && *cpu_s_per_run > 0 && std::isfinite(*cpu_s_per_run)) {
    const auto for_work = static_cast<size_t>(std::ceil(kMinTaskWorkS / *cpu_s_per_run));
    const size_t k = std::min(std::max<size_t>(for_work, 1), std::max<size_t>(runs, 1));
    if (k > b.runs_per_task) {
      b.runs_per_task = k;
      why = for_work >= runs ? "one task: less than " + Seconds(kMinTaskWorkS) + " of work in all"
                             : "at least " + Seconds(kMinTaskWorkS) + " of work per task";
    }
    why += ", at an estimated " + Seconds(*cpu_s_per_run) + " CPU per run: about " +
           Seconds(static_cast<double>(b.runs_per_task) * *cpu_s_per_run) + " per task";
  } else {
    why += ", no cost estimate yet";
  }
  b.tasks = CeilDiv(runs, b.runs_per_task);
  b.why = "auto: " + why;
  return b;
}

Batching FixedBatching(size_t runs, size_t runs_per_task) {
  Batching b;
  b.runs_per_task = std::max<size_t>(runs_per_task, 1);
  b.tasks = CeilDiv(runs, b.runs_per_task);
  b.why = "--runs-per-task " + std::to_string(b.runs_per_task);
  return b;
}

std::optional<size_t> ParseRunsPerTask(const std::string& text) {
  if (text == "auto") return std::nullopt;
  size_t used = 0;
  long long k = 0;
  try {
    k = std::stoll(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || k < 1) throw std::invalid_argument("must be auto or a positive integer, got '" + text + "'");
  return static_cast<size_t>(k);
}

}  // namespace locaid::sweep
