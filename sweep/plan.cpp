#include "sweep/plan.hpp"

#include "sweep/key_hash.hpp"
#include "sweep/recording.hpp"
#include "sweep/result_store.hpp"

#include <algorithm>
#include <fstream>
#include <stdexcept>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

// A file name part: [A-Za-z0-9._-], others become '_', at most 40 characters.
std::string Slug(const std::string& s) {
  std::string out;
  for (const char c : s.substr(0, 40)) {
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ||
                       c == '_' || c == '.';
    out += plain ? c : '_';
  }
  return out;
}

// What a run reads of its recording: --drive / --bag (and --bag-topics).
std::vector<std::string> SourceArgs(const PlannedRecording& r) {
  std::vector<std::string> a = {r.kind == "bag" ? "--bag" : "--drive", r.path};
  if (!r.bag_topics.empty()) a.insert(a.end(), {"--bag-topics", r.bag_topics});
  return a;
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += x + '\x1f';
  return s;
}

// A scenario's content for the key: its name, or its YAML file's bytes (a
// scenario file is small, unlike a recording).
std::string ScenarioContent(const ScenarioRef& s) {
  return s.builtin ? "builtin:" + s.arg : "file:" + ReadFileText(s.arg);
}

std::string FileContent(const std::string& path) { return path.empty() ? "" : ReadFileText(path); }

}  // namespace

const char* ToString(Stage stage) { return stage == Stage::kVo ? "vo" : "filter"; }

Stage StageFromString(const std::string& s) {
  if (s == "vo") return Stage::kVo;
  if (s == "filter") return Stage::kFilter;
  throw std::invalid_argument("stage must be vo or filter, got '" + s + "'");
}

size_t Plan::array_tasks(Stage s) const {
  const size_t k = std::max<size_t>(runs_per_task(s), 1);
  return (array(s).size() + k - 1) / k;
}

std::vector<size_t> Plan::batch(Stage s, size_t i) const {
  const size_t k = std::max<size_t>(runs_per_task(s), 1);
  const auto& a = array(s);
  if (i >= array_tasks(s)) return {};
  const size_t begin = i * k, end = std::min(a.size(), begin + k);
  return {a.begin() + static_cast<std::ptrdiff_t>(begin), a.begin() + static_cast<std::ptrdiff_t>(end)};
}

Plan BuildPlan(const Manifest& manifest, const fs::path& dir, const fs::path& replay,
               const std::string& locaid_version) {
  Plan plan;
  plan.dir = fs::absolute(dir).lexically_normal().string();
  plan.manifest = manifest.file.string();
  plan.replay = fs::absolute(replay).lexically_normal().string();
  plan.replay_fingerprint = FileFingerprint(replay);
  if (plan.replay_fingerprint.empty()) throw std::runtime_error(replay.string() + ": no such program");
  plan.locaid_version = locaid_version;
  plan.smooth = manifest.smooth;
  const std::string program = "locaid " + locaid_version + " replay " + plan.replay_fingerprint;

  for (size_t ri = 0; ri < manifest.recordings.size(); ++ri) {
    const Recording& rec = manifest.recordings[ri];
    PlannedRecording pr{rec.path.string(), rec.kind == RecordingKind::kBag ? "bag" : "drive",
                        rec.bag_topics.string(), RecordingKey(rec.path)};
    plan.recordings.push_back(pr);
    const std::string rec_slug = Slug(rec.path.stem().string()) + "-" + HashHex(pr.path).substr(0, 8);

    // The VO run: any scenario works (the cache holds VO only); --scenario
    // is given so a bag is scanned as the filter runs scan it.
    VoTask vo;
    vo.id = "vo." + rec_slug;
    vo.recording = ri;
    vo.cache = (fs::path(plan.dir) / "vo" / (rec_slug + ".cache")).string();
    vo.args = SourceArgs(pr);
    vo.args.insert(vo.args.end(), {"--scenario", "open-sky", "--seed", "1", "--json", "--vo-cache", vo.cache});
    vo.args.insert(vo.args.end(), manifest.replay_args.begin(), manifest.replay_args.end());
    vo.key = KeyHasher()
                 .Add("recording", pr.key)
                 .Add("bag_topics", FileContent(pr.bag_topics))
                 .Add("args", Join(vo.args))
                 .Add("program", program)
                 .Hex();
    // Only when a scenario reads the cache (camera faults change what VO sees).
    int vo_index = -1;
    for (const ScenarioRef& sc : manifest.scenarios)
      if (!sc.camera_faults && vo_index < 0) {
        plan.vo.push_back(vo);
        vo_index = static_cast<int>(plan.vo.size()) - 1;
      }

    for (const ScenarioRef& sc : manifest.scenarios)
      for (const int64_t seed : manifest.seeds)
        for (const bool imu : manifest.imu) {
          FilterTask t;
          t.recording = ri;
          t.scenario = sc.name;
          t.seed = seed;
          t.imu = imu;
          t.vo_task = sc.camera_faults ? -1 : vo_index;
          t.id = rec_slug + "." + Slug(sc.name) + ".s" + std::to_string(seed) + (imu ? "" : ".noimu");
          t.args = SourceArgs(pr);
          t.args.insert(t.args.end(), {"--scenario", sc.arg, "--seed", std::to_string(seed)});
          if (!imu) t.args.push_back("--no-imu");
          t.args.push_back("--json");
          if (t.vo_task >= 0) t.args.insert(t.args.end(), {"--vo-cache", vo.cache});
          if (manifest.smooth) t.args.push_back("--smooth");  // in the args, hence in the key
          t.args.insert(t.args.end(), manifest.replay_args.begin(), manifest.replay_args.end());
          t.key = KeyHasher()
                      .Add("recording", pr.key)
                      .Add("bag_topics", FileContent(pr.bag_topics))
                      .Add("scenario", ScenarioContent(sc))
                      .Add("vo", t.vo_task >= 0 ? vo.key : "")  // a new cache is a new input
                      .Add("args", Join(t.args))
                      .Add("program", program)
                      .Hex();
          plan.filter.push_back(t);
        }
  }
  return plan;
}

nlohmann::json PlanToJson(const Plan& plan) {
  nlohmann::json j;
  j["version"] = plan.version;
  j["dir"] = plan.dir;
  j["manifest"] = plan.manifest;
  j["replay"] = plan.replay;
  j["replay_fingerprint"] = plan.replay_fingerprint;
  j["locaid_version"] = plan.locaid_version;
  j["smooth"] = plan.smooth;
  j["recordings"] = nlohmann::json::array();
  for (const auto& r : plan.recordings)
    j["recordings"].push_back({{"path", r.path}, {"kind", r.kind}, {"bag_topics", r.bag_topics}, {"key", r.key}});
  j["vo_tasks"] = nlohmann::json::array();
  for (const auto& t : plan.vo)
    j["vo_tasks"].push_back(
        {{"id", t.id}, {"key", t.key}, {"recording", t.recording}, {"cache", t.cache}, {"args", t.args}});
  j["filter_tasks"] = nlohmann::json::array();
  for (const auto& t : plan.filter)
    j["filter_tasks"].push_back({{"id", t.id},
                                 {"key", t.key},
                                 {"recording", t.recording},
                                 {"scenario", t.scenario},
                                 {"seed", t.seed},
                                 {"imu", t.imu},
                                 {"vo_task", t.vo_task},
                                 {"args", t.args}});
  j["arrays"] = {{"vo", plan.vo_array}, {"filter", plan.filter_array}};
  j["runs_per_task"] = {{"vo", plan.vo_runs_per_task}, {"filter", plan.filter_runs_per_task}};
  return j;
}

Plan PlanFromJson(const nlohmann::json& j) {
  try {
    Plan p;
    p.version = j.at("version").get<int>();
    if (p.version != 1) throw std::runtime_error("plan version " + std::to_string(p.version) + " (this reads 1)");
    p.dir = j.at("dir").get<std::string>();
    p.manifest = j.at("manifest").get<std::string>();
    p.replay = j.at("replay").get<std::string>();
    p.replay_fingerprint = j.at("replay_fingerprint").get<std::string>();
    p.locaid_version = j.at("locaid_version").get<std::string>();
    p.smooth = j.value("smooth", false);
    for (const auto& r : j.at("recordings"))
      p.recordings.push_back({r.at("path"), r.at("kind"), r.at("bag_topics"), r.at("key")});
    for (const auto& t : j.at("vo_tasks"))
      p.vo.push_back({t.at("id"), t.at("key"), t.at("recording"), t.at("cache"), t.at("args")});
    for (const auto& t : j.at("filter_tasks"))
      p.filter.push_back({t.at("id"), t.at("key"), t.at("recording"), t.at("scenario"), t.at("seed"), t.at("imu"),
                          t.at("vo_task"), t.at("args")});
    p.vo_array = j.at("arrays").at("vo").get<std::vector<size_t>>();
    p.filter_array = j.at("arrays").at("filter").get<std::vector<size_t>>();
    // Plans written before batching have one run per array task.
    if (const auto k = j.find("runs_per_task"); k != j.end()) {
      p.vo_runs_per_task = k->at("vo").get<size_t>();
      p.filter_runs_per_task = k->at("filter").get<size_t>();
      if (p.vo_runs_per_task == 0 || p.filter_runs_per_task == 0)
        throw std::runtime_error("runs_per_task must be at least 1");
    }
    for (size_t i : p.vo_array)
      if (i >= p.vo.size()) throw std::runtime_error("arrays.vo names task " + std::to_string(i));
    for (size_t i : p.filter_array)
      if (i >= p.filter.size()) throw std::runtime_error("arrays.filter names task " + std::to_string(i));
    return p;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(std::string("malformed plan: ") + e.what());
  }
}

void WritePlan(const Plan& plan) {
  WriteJsonAtomically(fs::path(plan.dir) / "plan.json", PlanToJson(plan));
}

Plan ReadPlan(const fs::path& dir) {
  const fs::path file = dir / "plan.json";
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": no plan (is " + dir.string() + " a sweep folder?)");
  try {
    Plan plan = PlanFromJson(nlohmann::json::parse(in));
    // Results are found where the plan is (a folder mounted elsewhere on
    // another machine); the VO caches stay at their planned paths.
    plan.dir = fs::absolute(dir).lexically_normal().string();
    return plan;
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
}

}  // namespace locaid::sweep
