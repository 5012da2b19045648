#include "sweep/apps/child_process.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

extern char** environ;

namespace locaid::sweep {

pid_t StartChild(const ChildSpec& spec) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, spec.stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, spec.stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  // The child starts with default signal handling whatever ours is.
  sigset_t all;
  sigfillset(&all);
  posix_spawnattr_setsigdefault(&attr, &all);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  short flags = POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK;
  if (spec.new_process_group) {
    flags |= POSIX_SPAWN_SETPGROUP;
    posix_spawnattr_setpgroup(&attr, 0);
  }
  posix_spawnattr_setflags(&attr, flags);
  std::vector<char*> argv;
  for (const auto& a : spec.argv) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, argv[0], &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) throw std::system_error(rc, std::generic_category(), "cannot start " + spec.argv[0]);
  return pid;
}

std::optional<ChildExit> ReapChild(pid_t pid, bool block) {
  int status = 0;
  rusage usage{};
  for (;;) {
    const pid_t r = ::wait4(pid, &status, block ? 0 : WNOHANG, &usage);
    if (r == 0) return std::nullopt;
    if (r < 0 && errno == EINTR) {
      if (block) continue;
      return std::nullopt;
    }
    if (r < 0) throw std::system_error(errno, std::generic_category(), "wait4");
    break;
  }
  ChildExit e;
  if (WIFEXITED(status)) e.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) e.signal = WTERMSIG(status);
  auto secs = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  e.cpu_s = secs(usage.ru_utime) + secs(usage.ru_stime);
  return e;
}

std::string Describe(const ChildExit& e) {
  if (e.signal != 0) {
    std::string s = "killed by signal " + std::to_string(e.signal) + " (" + ::strsignal(e.signal) + ")";
    if (e.signal == SIGKILL) s += ": out of memory, or killed";
    if (e.signal == SIGTERM) s += ": cancelled (scancel), over its time limit, or the node stopping";
    return s;
  }
  return "exit code " + std::to_string(e.exit_code);
}

ChildExit RunToEnd(const std::vector<std::string>& argv, std::string& out, std::string& err) {
  char out_name[] = "/tmp/locaid-sweep-out-XXXXXX";
  char err_name[] = "/tmp/locaid-sweep-err-XXXXXX";
  const int fo = ::mkstemp(out_name), fe = ::mkstemp(err_name);
  if (fo >= 0) ::close(fo);
  if (fe >= 0) ::close(fe);
  if (fo < 0 || fe < 0) throw std::system_error(errno, std::generic_category(), "mkstemp");
  ChildExit e;
  try {
    e = *ReapChild(StartChild({argv, out_name, err_name, false}), true);
  } catch (...) {
    ::unlink(out_name);
    ::unlink(err_name);
    throw;
  }
  auto slurp = [](const char* f) {
    std::ifstream in(f);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  out = slurp(out_name);
  err += slurp(err_name);
  ::unlink(out_name);
  ::unlink(err_name);
  return e;
}

std::vector<std::string> TailLines(const std::string& path, size_t n) {
  std::ifstream in(path, std::ios::binary);
  // Only the end of a long log matters.
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(std::max<std::streamoff>(0, size - 64 * 1024));
  std::stringstream s;
  s << in.rdbuf();
  std::deque<std::string> lines;
  std::string line;
  for (std::istringstream text(s.str()); std::getline(text, line);) {
    // "\rframe 50/80 ...\rframes 80 in 1 s": a progress line's last state.
    std::string last;
    std::string segment;
    for (std::istringstream parts(line); std::getline(parts, segment, '\r');) {
      while (!segment.empty() && segment.back() == ' ') segment.pop_back();
      if (!segment.empty()) last = segment;
    }
    line = last;
    if (line.empty()) continue;
    lines.push_back(line);
    if (lines.size() > n) lines.pop_front();
  }
  return {lines.begin(), lines.end()};
}

std::string SelfExe() { return std::filesystem::read_symlink("/proc/self/exe").string(); }

}  // namespace locaid::sweep
