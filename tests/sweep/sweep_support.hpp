// What the sweep tests share: running locaid-sweep and locaid-replay as a
// user does, rendering a small drive, writing manifests, reading results.
#pragma once

#include "pipeline/cli_support.hpp"
#include "sweep/result_store.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace locaid::sweep_test {

namespace fs = std::filesystem;
using locaid::test::CommandResult;
using locaid::test::RunCommand;

inline const std::string kBin = LOCAID_BIN_DIR;
inline const std::string kSweep = kBin + "/locaid-sweep";
inline const std::string kReplay = kBin + "/locaid-replay";
inline const fs::path kRealDrive =
    fs::path(LOCAID_SHARED_DATA) / "raw/2011_09_26/2011_09_26_drive_unknown_extract";

inline void WriteFile(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file) << text;
}

inline std::string ReadText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline nlohmann::json ReadJson(const fs::path& file) { return nlohmann::json::parse(ReadText(file)); }

inline std::string Quoted(const std::string& s) { return "'" + s + "'"; }

// locaid-synth into `out`; returns the drive folder (`out`/<date>_drive_<n>_sync).
inline fs::path RenderDrive(const fs::path& out, int seed, int frames = 80) {
  const auto r = RunCommand(kBin + "/locaid-synth --out " + out.string() + " --frames " + std::to_string(frames) +
                            " --width 640 --height 192 --seed " + std::to_string(seed) + " -q");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  for (const auto& e : fs::directory_iterator(out))
    if (e.is_directory() && e.path().filename().string().find("_drive_") != std::string::npos) return e.path();
  ADD_FAILURE() << "no drive folder in " << out;
  return {};
}

// An outage in the middle of any drive of a few seconds.
inline const char* kOutageScenario = R"(name: outage-mid
base: open-sky
outages: [{start_s: 3, duration_s: 2}]
)";

// The plan's runs, by stage.
inline nlohmann::json PlanJson(const fs::path& dir) { return ReadJson(dir / "plan.json"); }

// Every done filter result of DIR, by run id.
inline std::map<std::string, nlohmann::json> DoneResults(const fs::path& dir) {
  std::map<std::string, nlohmann::json> out;
  const nlohmann::json plan = PlanJson(dir);  // kept: a loop over a temporary's member would dangle
  for (const auto& t : plan["filter_tasks"]) {
    const fs::path f = dir / "runs" / (t["id"].get<std::string>() + ".json");
    if (fs::exists(f)) out[t["id"]] = ReadJson(f);
  }
  return out;
}

// locaid-replay run directly with a result's own argument list.
inline nlohmann::json DirectReplay(const nlohmann::json& result) {
  std::string cmd = kReplay;
  // Appended piece by piece: GCC 12's -Wrestrict misfires on "literal" + std::string&& (GCC PR 105651).
  for (const auto& a : result["args"]) {
    cmd += ' ';
    cmd += Quoted(a.get<std::string>());
  }
  std::string sub = "(";
  sub += cmd;
  sub += " 2>/dev/null)";
  const auto r = RunCommand(sub);
  EXPECT_EQ(r.exit_code, 0) << cmd;
  try {
    return nlohmann::json::parse(r.out);
  } catch (const std::exception& e) {
    ADD_FAILURE() << cmd << ": not JSON: " << r.out;
    return {};
  }
}

inline std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

}  // namespace locaid::sweep_test
