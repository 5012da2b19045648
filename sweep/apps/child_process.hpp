// Child processes of locaid-sweep: a locaid-replay run, a task worker, sbatch.
// Started with posix_spawn, output to files, reaped with its CPU time.
#pragma once

#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

namespace locaid::sweep {

struct ChildSpec {
  std::vector<std::string> argv;  // argv[0] is the program's path
  std::string stdout_path = "/dev/null", stderr_path = "/dev/null";
  // Its own process group, so a terminal's Ctrl-C reaches only us and we
  // decide what the child gets (kill(-pid, ...) reaches its children too).
  bool new_process_group = false;
};

// Throws std::system_error when the program cannot be started.
pid_t StartChild(const ChildSpec& spec);

struct ChildExit {
  int exit_code = -1;  // -1 when killed by a signal
  int signal = 0;
  double cpu_s = 0;  // user + system of the child and what it waited for
};
// block = false: nullopt while it runs (or a signal came). block = true:
// waits, also through signals.
std::optional<ChildExit> ReapChild(pid_t pid, bool block);

// "exit code 3", "killed by signal 9 (Killed)".
std::string Describe(const ChildExit& e);

// Runs a program to its end; its stdout is returned, stderr appended to `err`.
// Returns the exit; throws std::system_error when it cannot be started.
ChildExit RunToEnd(const std::vector<std::string>& argv, std::string& out, std::string& err);

// The last `n` non-empty lines of a file (a progress line written with '\r'
// counts as its last state only).
std::vector<std::string> TailLines(const std::string& path, size_t n);

// This program's own path (/proc/self/exe).
std::string SelfExe();

}  // namespace locaid::sweep
