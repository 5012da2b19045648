// The results of a sweep's runs in DIR/runs/: <id>.json for a run that
// finished (locaid-replay's --json output under "metrics"), <id>.failed.json
// for one that did not (exit status or signal, the last lines of its error
// output). Each carries the key of the inputs it was computed from; a file
// with another key is stale, i.e. pending. Files are written to a temporary
// name and renamed, so a reader never sees half a result, and a file that
// does not parse is pending, never a result.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace locaid::sweep {

enum class RunState { kPending, kStale, kDone, kFailed };
const char* ToString(RunState s);

struct StoredResult {
  RunState state = RunState::kPending;
  nlohmann::json json;  // the file's content (done or failed)
};

std::filesystem::path DoneFile(const std::filesystem::path& dir, const std::string& id);
std::filesystem::path FailedFile(const std::filesystem::path& dir, const std::string& id);

// kDone / kFailed only when the file's "key" is `key`; kStale when a result
// of other inputs is there.
StoredResult ReadResult(const std::filesystem::path& dir, const std::string& id, const std::string& key);

// PATH.tmp.<pid>, flushed, renamed to PATH. Throws std::runtime_error.
void WriteJsonAtomically(const std::filesystem::path& path, const nlohmann::json& j);

// Writes the result (its "status" says done or failed) and removes the
// other kind of file of the same run, so one run has one result.
void StoreResult(const std::filesystem::path& dir, const std::string& id, const nlohmann::json& result);

// locaid-replay --json minus what measures the machine, not the run
// (frames_per_s, vo_ms_mean, --smooth's smoothing.backward_pass_s): equal
// for the same inputs, bit for bit.
nlohmann::json DeterministicMetrics(nlohmann::json replay_json);

}  // namespace locaid::sweep
