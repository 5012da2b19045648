// Running the project's programs from a test, as a user runs them.
#pragma once

#include <array>
#include <cstdio>
#include <string>
#include <sys/wait.h>

namespace locaid::test {

struct CommandResult {
  int exit_code = -1;
  std::string out;  // stdout + stderr
};

// Runs a shell command line; its stderr is captured with its stdout.
inline CommandResult RunCommand(const std::string& cmd) {
  CommandResult r;
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The text of a scalar field of a JSON object printed one field per line
// ("key": value), or "" when absent.
inline std::string JsonField(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) return {};
  const auto start = at + key.size() + 3;
  return json.substr(start, json.find_first_of(",\n}", start) - start);
}

}  // namespace locaid::test
