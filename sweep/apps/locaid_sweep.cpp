// locaid-sweep: scenario sweeps of locaid-replay over many recordings, on
// this machine or as Slurm job arrays, resumable, with one results table.
// docs/sweeps.md.
//
//   locaid-sweep plan MANIFEST [--out DIR]           counts and estimated CPU time
//   locaid-sweep run MANIFEST --out DIR [--engine local|slurm|k8s] [--jobs N] [--runs-per-task K|auto] [--wait] ...
//   locaid-sweep status DIR                           exit 0 only when every run is done
//   locaid-sweep report DIR                           results.csv, summary.csv/.json, PNGs, report.md
//   locaid-sweep task DIR --stage vo|filter [--index N]   (hidden) one array task (a batch of runs) of the plan
//
// Threads: none. Processes: each run is a locaid-replay child (of a task
// process), so a run that crashes, is killed or runs out of memory is that
// run's failure and never the sweep's.
#include "sweep/apps/child_process.hpp"
#include "sweep/apps/estimate.hpp"
#include "sweep/apps/report_command.hpp"
#include "sweep/apps/run_command.hpp"
#include "sweep/apps/task_command.hpp"
#include "sweep/batching.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

using namespace locaid::sweep;

int main(int argc, char** argv) {
  CLI::App app{"locaid-sweep: scenario sweeps of locaid-replay over many recordings (docs/sweeps.md)"};
  app.require_subcommand(1);

  PlanCommandOptions plan_options;
  auto* plan_cmd = app.add_subcommand("plan", "count the runs and estimate their CPU time; runs nothing of the sweep");
  plan_cmd->add_option("manifest", plan_options.manifest, "sweep manifest (YAML)")->required();
  plan_cmd->add_option("--out", plan_options.out, "the sweep's folder: reuse the CPU times measured there");
  plan_cmd->add_flag("!--no-measure", plan_options.measure, "counts only, no measured run");
  plan_cmd->add_option("--jobs", plan_options.jobs, "for the wall time on this machine (default: its cores)");

  RunCommandOptions run;
  auto* run_cmd = app.add_subcommand("run", "run what is not done yet, then report");
  run_cmd->add_option("manifest", run.manifest, "sweep manifest (YAML)")->required();
  run_cmd->add_option("--out", run.out, "the sweep's folder (results, VO caches, plan, logs)")->required();
  run_cmd->add_option("--engine", run.engine,
                      "local (a process pool here), slurm (job arrays) or k8s (write the plan for Indexed Jobs)")
      ->check(CLI::IsMember({"local", "slurm", "k8s"}));
  run_cmd->add_option("--jobs", run.jobs, "local: runs at once (default: the number of cores)")
      ->check(CLI::PositiveNumber);
  run_cmd->add_option("--runs-per-task", run.runs_per_task,
                      "slurm, k8s: filter runs per array task, K or auto (default: at most 1000 tasks, and "
                      "about 30 s of estimated work per task); the local engine ignores it")
      ->check([](const std::string& v) {
        try {
          ParseRunsPerTask(v);
          return std::string();
        } catch (const std::exception& e) {
          return std::string(e.what());
        }
      });
  run_cmd->add_flag("--wait", run.slurm.wait, "slurm: wait until the jobs leave the queue, then report");
  run_cmd->add_option("--partition", run.slurm.partition, "slurm: sbatch --partition");
  run_cmd->add_option("--time", run.slurm.time, "slurm: sbatch --time, per task");
  run_cmd->add_option("--mem", run.slurm.mem, "slurm: sbatch --mem, per task");
  run_cmd->add_option("--cpus-per-task", run.slurm.cpus_per_task, "slurm: sbatch --cpus-per-task");
  run_cmd->add_option("--max-running", run.slurm.max_running, "slurm: at most K tasks of an array at once (%K)")
      ->check(CLI::PositiveNumber);
  run_cmd->add_option("--sbatch-arg", run.slurm.sbatch_args, "slurm: one more sbatch argument (repeatable)")
      ->allow_extra_args(false);
  run_cmd->add_option("--poll-s", run.slurm.poll_s, "slurm --wait: seconds between squeue calls")
      ->check(CLI::Range(0.1, 3600.0));

  std::string status_dir;
  auto* status_cmd = app.add_subcommand("status", "done / failed (with each error) / pending; exit 0 when all done");
  status_cmd->add_option("dir", status_dir, "the sweep's folder")->required();

  std::string report_dir;
  auto* report_cmd = app.add_subcommand("report", "write results.csv, summary.csv/.json, plots and report.md");
  report_cmd->add_option("dir", report_dir, "the sweep's folder")->required();

  std::string task_dir, task_stage;
  std::optional<size_t> task_index;
  auto* task_cmd = app.add_subcommand("task", "run one array task (a batch of runs) of the plan in DIR (what engines run)");
  task_cmd->group("");  // hidden: the engines' entry point, not a user's
  task_cmd->add_option("dir", task_dir, "the sweep's folder")->required();
  task_cmd->add_option("--stage", task_stage, "vo or filter")->required()->check(CLI::IsMember({"vo", "filter"}));
  task_cmd->add_option("--index", task_index, "array task index (default: SLURM_ARRAY_TASK_ID, else JOB_COMPLETION_INDEX)");

  CLI11_PARSE(app, argc, argv);
  try {
    if (*plan_cmd) return PrintPlan(plan_options);
    if (*run_cmd) return RunSweep(run);
    if (*task_cmd) return RunTask(task_dir, StageFromString(task_stage), task_index);
    const Plan plan = ReadPlan(std::filesystem::absolute(*status_cmd ? status_dir : report_dir));
    if (*status_cmd) return PrintStatus(plan);
    WriteReport(plan, SelfExe());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "locaid-sweep: " << e.what() << "\n";
    return 2;
  }
}
