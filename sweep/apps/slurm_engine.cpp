#include "sweep/apps/slurm_engine.hpp"

#include "sweep/apps/child_process.hpp"
#include "sweep/batching.hpp"
#include "sweep/result_store.hpp"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

// Single-quoted for bash.
std::string Quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string Trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s;
}

fs::path WriteScript(const Plan& plan, const std::string& self_exe, Stage stage) {
  const fs::path file = fs::path(plan.dir) / "slurm" / (std::string(ToString(stage)) + ".sbatch");
  std::ofstream out(file);
  out << "#!/bin/bash\n"
      << "# locaid-sweep: one " << ToString(stage) << " task of the sweep in " << plan.dir << " per array task;\n"
      << "# array task i runs entries [i*K, (i+1)*K) of arrays." << ToString(stage)
      << " of plan.json, K = runs_per_task." << ToString(stage) << " (" << plan.runs_per_task(stage) << ").\n"
      << "exec " << Quote(self_exe) << " task " << Quote(plan.dir) << " --stage " << ToString(stage) << "\n";
  if (!out.flush()) throw std::runtime_error(file.string() + ": cannot write");
  fs::permissions(file, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                  fs::perm_options::add);
  return file;
}

std::string Submit(const Plan& plan, const std::string& self_exe, Stage stage, size_t n, const SlurmOptions& o,
                   const std::string& after) {
  const fs::path logs = fs::path(plan.dir) / "slurm" / "logs";
  std::vector<std::string> argv = {"sbatch", "--parsable",
                                   "--array=0-" + std::to_string(n - 1) +
                                       (o.max_running > 0 ? "%" + std::to_string(o.max_running) : ""),
                                   "--job-name=locaid-sweep-" + std::string(ToString(stage)),
                                   "--chdir=" + plan.dir,
                                   "--output=" + (logs / "%A_%a.out").string(),
                                   "--error=" + (logs / "%A_%a.err").string()};
  if (!o.partition.empty()) argv.push_back("--partition=" + o.partition);
  if (!o.time.empty()) argv.push_back("--time=" + o.time);
  if (!o.mem.empty()) argv.push_back("--mem=" + o.mem);
  if (o.cpus_per_task > 0) argv.push_back("--cpus-per-task=" + std::to_string(o.cpus_per_task));
  if (!after.empty()) argv.push_back("--dependency=afterany:" + after);
  argv.insert(argv.end(), o.sbatch_args.begin(), o.sbatch_args.end());
  argv.push_back(WriteScript(plan, self_exe, stage).string());
  // posix_spawn needs a path: sbatch from PATH.
  std::string out, err;
  argv[0] = "/usr/bin/env";
  argv.insert(argv.begin() + 1, "sbatch");
  const ChildExit e = RunToEnd(argv, out, err);
  if (e.exit_code != 0) throw std::runtime_error("sbatch (" + Describe(e) + "): " + Trim(err));
  const std::string id = Trim(out.substr(0, out.find(';')));  // "123" or "123;cluster"
  if (id.empty() || id.find_first_not_of("0123456789") != std::string::npos)
    throw std::runtime_error("sbatch printed no job id: " + Trim(out) + " " + Trim(err));
  return id;
}

fs::path JobsFile(const std::string& dir) { return fs::path(dir) / "slurm" / "jobs.json"; }

// Job ids squeue lists among `ids`.
std::vector<std::string> Listed(const std::vector<std::string>& ids) {
  std::string list;
  for (const auto& id : ids)
    if (!id.empty()) list += (list.empty() ? "" : ",") + id;
  if (list.empty()) return {};
  std::string out, err;
  const ChildExit e = RunToEnd({"/usr/bin/env", "squeue", "-h", "-j", list, "-o", "%F"}, out, err);
  // Jobs that left the controller's memory are "Invalid job id": gone.
  if (e.exit_code != 0) {
    if (err.find("Invalid job id") != std::string::npos) return {};
    throw std::runtime_error("squeue (" + Describe(e) + "): " + Trim(err));
  }
  std::vector<std::string> listed;
  std::istringstream lines(out);
  for (std::string line; std::getline(lines, line);)
    if (!Trim(line).empty()) listed.push_back(Trim(line));
  return listed;
}

}  // namespace

std::vector<std::string> QueuedJobs(const std::string& dir) {
  std::ifstream in(JobsFile(dir));
  if (!in) return {};
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception&) {
    return {};
  }
  return Listed({j.value("vo", ""), j.value("filter", "")});
}

SlurmJobs SubmitSlurm(const Plan& plan, const std::string& self_exe, const SlurmOptions& options) {
  fs::create_directories(fs::path(plan.dir) / "slurm" / "logs");
  SlurmJobs jobs;
  if (!plan.vo_array.empty())
    jobs.vo = Submit(plan, self_exe, Stage::kVo, plan.array_tasks(Stage::kVo), options, "");
  try {
    if (!plan.filter_array.empty())
      jobs.filter = Submit(plan, self_exe, Stage::kFilter, plan.array_tasks(Stage::kFilter), options, jobs.vo);
  } catch (...) {
    // Keep the VO array known so a later run waits for it instead of racing it.
    WriteJsonAtomically(JobsFile(plan.dir), {{"vo", jobs.vo}, {"filter", ""}});
    throw;
  }
  WriteJsonAtomically(JobsFile(plan.dir), {{"vo", jobs.vo}, {"filter", jobs.filter}});
  return jobs;
}

std::optional<long> SlurmMaxArraySize() {
  try {
    std::string out, err;
    if (RunToEnd({"/usr/bin/env", "scontrol", "show", "config"}, out, err).exit_code != 0) return std::nullopt;
    return ParseMaxArraySize(out);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

void WaitForJobs(const SlurmJobs& jobs, double poll_s) {
  while (!Listed({jobs.vo, jobs.filter}).empty())
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
}

}  // namespace locaid::sweep
