// The plan of a sweep: every run it consists of, written to DIR/plan.json so
// that any process on any node (a local worker, a Slurm array task, a
// Kubernetes Indexed Job pod) finds its run by index and runs exactly the
// argument list planned.
//
// Two stages: one VO run per recording (locaid-replay writes the recording's
// VO cache), then the filter runs (recording x scenario x seed x imu), which
// read that cache, except scenarios with camera faults, which run VO
// themselves. `arrays` lists, per stage, the tasks a `run` left to do;
// `runs_per_task` (K) cuts that list into consecutive batches: array task i
// (SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX) runs entries [i*K, (i+1)*K),
// so an array of ceil(N/K) tasks covers exactly those N runs. Each run of a
// batch is still its own locaid-replay child with its own result.
#pragma once

#include "sweep/manifest.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace locaid::sweep {

enum class Stage { kVo, kFilter };
const char* ToString(Stage stage);
Stage StageFromString(const std::string& s);  // throws std::invalid_argument

struct PlannedRecording {
  std::string path;
  std::string kind;  // "drive" or "bag"
  std::string bag_topics;
  std::string key;  // RecordingKey
};

struct VoTask {
  std::string id, key;
  size_t recording = 0;
  std::string cache;               // absolute path of the VO cache it writes
  std::vector<std::string> args;   // locaid-replay's arguments (without the program)
};

struct FilterTask {
  std::string id, key;
  size_t recording = 0;
  std::string scenario;  // its name
  int64_t seed = 0;
  bool imu = true;
  int vo_task = -1;  // the VO task whose cache it reads; -1: runs VO itself (camera faults)
  std::vector<std::string> args;
};

struct Plan {
  int version = 1;
  std::string dir;       // absolute DIR (the nodes must see it at this path)
  std::string manifest;  // the manifest's path
  std::string replay;    // absolute path of locaid-replay
  std::string replay_fingerprint;  // its size and mtime; part of every key
  std::string locaid_version;
  bool smooth = false;  // the manifest's smooth: every filter run has --smooth (absent in older plans: false)
  std::vector<PlannedRecording> recordings;
  std::vector<VoTask> vo;
  std::vector<FilterTask> filter;
  std::vector<size_t> vo_array, filter_array;  // array entry -> task index (the tasks left to do)
  size_t vo_runs_per_task = 1, filter_runs_per_task = 1;  // array entries per array task (K)

  const std::vector<size_t>& array(Stage s) const { return s == Stage::kVo ? vo_array : filter_array; }
  size_t runs_per_task(Stage s) const { return s == Stage::kVo ? vo_runs_per_task : filter_runs_per_task; }
  // ceil(array(s).size() / runs_per_task(s)): the size of the stage's job array.
  size_t array_tasks(Stage s) const;
  // The task indices (into vo / filter) that array task `i` runs, in order;
  // empty when i >= array_tasks(s).
  std::vector<size_t> batch(Stage s, size_t i) const;
  size_t runs() const { return vo.size() + filter.size(); }
};

// Every run of the manifest with its key and argument list. `dir`: the
// sweep's folder (absolute); `replay`: the locaid-replay binary.
Plan BuildPlan(const Manifest& manifest, const std::filesystem::path& dir, const std::filesystem::path& replay,
               const std::string& locaid_version);

nlohmann::json PlanToJson(const Plan& plan);
Plan PlanFromJson(const nlohmann::json& j);  // throws std::runtime_error naming the missing field

// DIR/plan.json, written atomically; read throws std::runtime_error.
void WritePlan(const Plan& plan);
Plan ReadPlan(const std::filesystem::path& dir);

}  // namespace locaid::sweep
