#include "sweep/result_store.hpp"

#include <unistd.h>

#include <fstream>
#include <stdexcept>
#include <system_error>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

std::optional<nlohmann::json> ParseFile(const fs::path& file) {
  std::ifstream in(file);
  if (!in) return std::nullopt;
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;  // not written by us through a rename: never a result
  }
}

}  // namespace

const char* ToString(RunState s) {
  switch (s) {
    case RunState::kDone: return "done";
    case RunState::kFailed: return "failed";
    case RunState::kStale: return "stale";
    case RunState::kPending: break;
  }
  return "pending";
}

fs::path DoneFile(const fs::path& dir, const std::string& id) { return dir / "runs" / (id + ".json"); }
fs::path FailedFile(const fs::path& dir, const std::string& id) { return dir / "runs" / (id + ".failed.json"); }

StoredResult ReadResult(const fs::path& dir, const std::string& id, const std::string& key) {
  StoredResult r;
  for (const auto& [file, state] : {std::pair{DoneFile(dir, id), RunState::kDone},
                                    std::pair{FailedFile(dir, id), RunState::kFailed}}) {
    auto j = ParseFile(file);
    if (!j || !j->is_object()) continue;
    if (j->value("key", "") != key) {
      r.state = RunState::kStale;
      continue;
    }
    return {state, std::move(*j)};
  }
  return r;
}

void WriteJsonAtomically(const fs::path& path, const nlohmann::json& j) {
  fs::create_directories(path.parent_path());
  const fs::path tmp = path.string() + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << j.dump(2) << '\n';
    if (!out.flush()) throw std::runtime_error(tmp.string() + ": write failed");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": cannot rename the result into place");
  }
}

void StoreResult(const fs::path& dir, const std::string& id, const nlohmann::json& result) {
  const bool done = result.value("status", "") == "done";
  WriteJsonAtomically(done ? DoneFile(dir, id) : FailedFile(dir, id), result);
  std::error_code ec;
  fs::remove(done ? FailedFile(dir, id) : DoneFile(dir, id), ec);
}

nlohmann::json DeterministicMetrics(nlohmann::json replay_json) {
  replay_json.erase("frames_per_s");
  replay_json.erase("vo_ms_mean");
  if (auto s = replay_json.find("smoothing"); s != replay_json.end() && s->is_object()) s->erase("backward_pass_s");
  return replay_json;
}

}  // namespace locaid::sweep
