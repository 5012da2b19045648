#include "sweep/manifest.hpp"

#include "sim/scenario.hpp"
#include "pipeline/scenario_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include <glob.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

constexpr int64_t kMaxSeeds = 1000000;  // a typo like to: 1e9 would plan a billion runs

// Reads one manifest; every error goes through Fail() with the node it is about.
class ManifestReader {
 public:
  explicit ManifestReader(const fs::path& file) : file_(file), dir_(file.parent_path()) {}

  [[noreturn]] void Fail(const YAML::Node& at, const std::string& key, const std::string& why) const {
    const YAML::Mark m = at.Mark();
    std::string where = file_.string();
    if (m.line >= 0) where += ":" + std::to_string(m.line + 1);
    throw ManifestError(where + ": " + key + ": " + why);
  }

  Manifest Read(const YAML::Node& root) {
    if (!root.IsMap()) Fail(root, "(top level)", "expected a map with recordings, scenarios, seeds");
    static const std::set<std::string> kKeys = {"recordings", "scenarios", "seeds", "imu", "replay_args",
                                                  "smooth"};
    for (const auto& kv : root) {
      const std::string key = kv.first.as<std::string>();
      if (!kKeys.count(key))
        Fail(kv.first, key, "unknown key (known: recordings, scenarios, seeds, imu, replay_args, smooth)");
    }
    for (const char* required : {"recordings", "scenarios", "seeds"})
      if (!root[required]) Fail(root, required, "missing (required)");
    Manifest m;
    m.file = file_;
    ReadRecordings(root["recordings"], m);
    ReadScenarios(root["scenarios"], m);
    ReadSeeds(root["seeds"], m);
    ReadImu(root["imu"], m);
    ReadReplayArgs(root["replay_args"], m);
    ReadSmooth(root["smooth"], m);
    return m;
  }

 private:
  fs::path Resolve(const std::string& p) const { return fs::path(p).is_absolute() ? fs::path(p) : dir_ / p; }

  std::string Scalar(const YAML::Node& n, const std::string& key) const {
    if (!n.IsScalar() || n.Scalar().empty()) Fail(n, key, "expected a non-empty string");
    return n.Scalar();
  }

  void ReadRecordings(const YAML::Node& list, Manifest& m) {
    if (!list.IsSequence() || list.size() == 0) Fail(list, "recordings", "expected a non-empty list of {path: ...}");
    std::set<fs::path> seen;
    for (size_t i = 0; i < list.size(); ++i) {
      const YAML::Node item = list[i];
      const std::string key = "recordings[" + std::to_string(i) + "]";
      if (!item.IsMap()) Fail(item, key, "expected a map with path (and bag_topics)");
      for (const auto& kv : item) {
        const std::string k = kv.first.as<std::string>();
        if (k != "path" && k != "bag_topics") Fail(kv.first, key + "." + k, "unknown key (known: path, bag_topics)");
      }
      if (!item["path"]) Fail(item, key + ".path", "missing (required)");
      const std::string pattern = Scalar(item["path"], key + ".path");
      fs::path topics;
      if (item["bag_topics"]) {
        topics = Resolve(Scalar(item["bag_topics"], key + ".bag_topics"));
        std::error_code ec;
        if (!fs::is_regular_file(topics, ec))
          Fail(item["bag_topics"], key + ".bag_topics", topics.string() + " is not a file");
        topics = fs::canonical(topics);
      }
      for (const fs::path& path : Expand(item["path"], key + ".path", Resolve(pattern).string())) {
        std::string why;
        const auto kind = ClassifyRecording(path, why);
        if (!kind) Fail(item["path"], key + ".path", path.string() + ": " + why);
        if (!topics.empty() && *kind != RecordingKind::kBag)
          Fail(item["bag_topics"], key + ".bag_topics", path.string() + " is a drive folder, not a bag");
        const fs::path canonical = fs::weakly_canonical(path);
        if (!seen.insert(canonical).second) continue;  // two globs may match the same recording
        m.recordings.push_back({canonical, *kind, topics});
      }
    }
  }

  // A path, or every match of a glob (sorted); a glob matching nothing is an error.
  std::vector<fs::path> Expand(const YAML::Node& at, const std::string& key, const std::string& pattern) const {
    if (pattern.find_first_of("*?[") == std::string::npos) return {pattern};
    glob_t g{};
    const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
    std::vector<fs::path> out;
    if (rc == 0)
      for (size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
    ::globfree(&g);
    if (out.empty()) Fail(at, key, "glob " + pattern + " matches nothing");
    std::sort(out.begin(), out.end());
    return out;
  }

  void ReadScenarios(const YAML::Node& list, Manifest& m) {
    if (!list.IsSequence() || list.size() == 0)
      Fail(list, "scenarios", "expected a non-empty list of built-in names or YAML files");
    const auto builtin = sim::BuiltinScenarioNames();
    std::string names;
    for (const auto& b : builtin) names += (names.empty() ? "" : ", ") + b;
    for (size_t i = 0; i < list.size(); ++i) {
      const std::string key = "scenarios[" + std::to_string(i) + "]";
      const std::string value = Scalar(list[i], key);
      ScenarioRef ref;
      const bool is_builtin = std::find(builtin.begin(), builtin.end(), value) != builtin.end();
      ref.builtin = is_builtin;
      ref.arg = value;
      if (!is_builtin) {
        std::error_code ec;
        const fs::path file = Resolve(value);
        if (!fs::is_regular_file(file, ec))
          Fail(list[i], key, "unknown scenario '" + value + "': not a built-in (" + names + ") nor a file");
        ref.arg = fs::canonical(file).string();
      }
      try {
        // The loader locaid-replay itself uses: what it refuses, the sweep refuses now.
        const sim::Scenario s = pipeline::LoadScenario(ref.arg);
        ref.name = s.name;
        ref.camera_faults = !s.camera_faults.empty();
      } catch (const std::exception& e) {
        Fail(list[i], key, e.what());
      }
      for (const auto& other : m.scenarios)
        if (other.name == ref.name) Fail(list[i], key, "scenario name '" + ref.name + "' is listed twice");
      m.scenarios.push_back(ref);
    }
  }

  int64_t Seed(const YAML::Node& n, const std::string& key) const {
    int64_t v = -1;
    if (!n.IsScalar() || !YAML::convert<int64_t>::decode(n, v)) Fail(n, key, "expected an integer");
    if (v < 0) Fail(n, key, "a seed is >= 0, got " + n.Scalar());
    return v;
  }

  void ReadSeeds(const YAML::Node& seeds, Manifest& m) {
    if (seeds.IsMap()) {
      for (const auto& kv : seeds) {
        const std::string k = kv.first.as<std::string>();
        if (k != "from" && k != "to") Fail(kv.first, "seeds." + k, "unknown key (known: from, to)");
      }
      if (!seeds["from"] || !seeds["to"]) Fail(seeds, "seeds", "expected {from: N, to: M}");
      const int64_t from = Seed(seeds["from"], "seeds.from"), to = Seed(seeds["to"], "seeds.to");
      if (to < from) Fail(seeds["to"], "seeds.to", "must be >= seeds.from (" + std::to_string(from) + ")");
      if (to - from + 1 > kMaxSeeds) Fail(seeds["to"], "seeds", "more than " + std::to_string(kMaxSeeds) + " seeds");
      for (int64_t s = from; s <= to; ++s) m.seeds.push_back(s);
    } else if (seeds.IsSequence() && seeds.size() > 0) {
      for (size_t i = 0; i < seeds.size(); ++i) {
        const std::string key = "seeds[" + std::to_string(i) + "]";
        const int64_t s = Seed(seeds[i], key);
        if (std::find(m.seeds.begin(), m.seeds.end(), s) != m.seeds.end())
          Fail(seeds[i], key, "seed " + std::to_string(s) + " is listed twice");
        m.seeds.push_back(s);
      }
    } else {
      Fail(seeds, "seeds", "expected {from: N, to: M} or a non-empty list of integers");
    }
  }

  void ReadImu(const YAML::Node& imu, Manifest& m) {
    if (!imu) {
      m.imu = {true};
      return;
    }
    if (!imu.IsSequence() || imu.size() == 0) Fail(imu, "imu", "expected a non-empty list of on / off");
    for (size_t i = 0; i < imu.size(); ++i) {
      const std::string key = "imu[" + std::to_string(i) + "]";
      bool on = false;
      // yaml-cpp reads on/off, true/false and yes/no as booleans.
      if (!imu[i].IsScalar() || !YAML::convert<bool>::decode(imu[i], on)) Fail(imu[i], key, "expected on or off");
      if (std::find(m.imu.begin(), m.imu.end(), on) != m.imu.end()) Fail(imu[i], key, "listed twice");
      m.imu.push_back(on);
    }
  }

  void ReadReplayArgs(const YAML::Node& args, Manifest& m) {
    if (!args) return;
    if (!args.IsSequence()) Fail(args, "replay_args", "expected a list of strings");
    for (size_t i = 0; i < args.size(); ++i) {
      const std::string key = "replay_args[" + std::to_string(i) + "]";
      const std::string a = Scalar(args[i], key);
      if (IsReservedReplayArg(a))
        Fail(args[i], key,
             a + " is set by the sweep for each run " +
                 (a.rfind("--smooth", 0) == 0 ? "(write smooth: true)" : "(or would make runs write one file)"));
      m.replay_args.push_back(a);
    }
  }

  void ReadSmooth(const YAML::Node& smooth, Manifest& m) {
    if (!smooth) return;
    // yaml-cpp also reads on/off and yes/no as booleans, as for imu.
    if (!smooth.IsScalar() || !YAML::convert<bool>::decode(smooth, m.smooth))
      Fail(smooth, "smooth", "expected true or false" + (smooth.IsScalar() ? ", got " + smooth.Scalar() : ""));
  }

  fs::path file_, dir_;
};

}  // namespace

bool IsReservedReplayArg(const std::string& arg) {
  const std::string name = arg.substr(0, arg.find('='));
  static const std::set<std::string> kReserved = {"--drive", "--bag",   "--bag-topics", "--scenario", "--seed",
                                                  "--no-imu", "--json", "--vo-cache",   "--inspect",  "--help",
                                                  "-h",       "--smooth"};
  return kReserved.count(name) > 0 || name.rfind("--out-", 0) == 0;
}

Manifest LoadManifest(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw ManifestError(file.string() + ": cannot read the manifest");
  std::stringstream text;
  text << in.rdbuf();
  const fs::path canonical = fs::canonical(file);
  YAML::Node root;
  try {
    root = YAML::Load(text.str());
  } catch (const YAML::Exception& e) {
    throw ManifestError(canonical.string() + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML: " + e.msg);
  }
  try {
    return ManifestReader(canonical).Read(root);
  } catch (const YAML::Exception& e) {  // a key that is not a scalar, and such
    throw ManifestError(canonical.string() + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
}

}  // namespace locaid::sweep
