// The manifest: every mistake is an error naming the file, its line and the
// key, before anything runs; relative paths and globs resolve as documented.
// Recordings here are only layouts (a folder with image_00/, a .mcap file):
// the manifest tells kinds apart without reading them.
#include "error_of.hpp"
#include "sweep/manifest.hpp"
#include "sweep/plan.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using locaid::sweep::LoadManifest;
using locaid::sweep::Manifest;
using locaid::sweep::ManifestError;
using locaid::test_support::ErrorOf;
using locaid::test_support::ScopedTempDir;

namespace {

class ManifestTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dir_ / "drives/a_sync/image_00");
    fs::create_directories(dir_ / "drives/b_sync/image_00");
    fs::create_directories(dir_ / "bags");
    std::ofstream(dir_ / "bags/one.mcap") << "x";
    std::ofstream(dir_ / "bags/two.mcap") << "x";
    std::ofstream(dir_ / "topics.yaml") << "imu: /imu\n";
    std::ofstream(dir_ / "outage.yaml") << "name: outage-5s\nbase: open-sky\noutages: [{start_s: 5, duration_s: 5}]\n";
    fs::create_directories(dir_ / "empty_folder");
    std::ofstream(dir_ / "notes.txt") << "x";
  }
  fs::path Write(const std::string& text) {
    const fs::path f = dir_ / "sweep.yaml";
    std::ofstream(f) << text;
    return f;
  }
  // The error of a manifest, checked to name the file.
  std::string Error(const std::string& text) {
    const fs::path f = Write(text);
    const std::string e = ErrorOf<ManifestError>([&] { LoadManifest(f); });
    EXPECT_NE(e.find(fs::canonical(f).string() + ":"), std::string::npos) << e;
    return e;
  }
  ScopedTempDir dir_{"sweep_manifest"};
};

const char* kGood = R"(recordings:
  - path: drives/*_sync
  - path: bags/one.mcap
    bag_topics: topics.yaml
scenarios: [open-sky, outage.yaml]
seeds: {from: 1, to: 3}
imu: [on, off]
replay_args: ["--vehicle-constraints", "auto"]
)";

TEST_F(ManifestTest, ReadsEveryKeyWithPathsRelativeToTheManifest) {
  const Manifest m = LoadManifest(Write(kGood));
  ASSERT_EQ(m.recordings.size(), 3u);
  EXPECT_EQ(m.recordings[0].path, fs::canonical(dir_ / "drives/a_sync"));  // glob matches, sorted
  EXPECT_EQ(m.recordings[1].path, fs::canonical(dir_ / "drives/b_sync"));
  EXPECT_EQ(m.recordings[0].kind, locaid::sweep::RecordingKind::kDrive);
  EXPECT_EQ(m.recordings[2].kind, locaid::sweep::RecordingKind::kBag);
  EXPECT_EQ(m.recordings[2].bag_topics, fs::canonical(dir_ / "topics.yaml"));
  ASSERT_EQ(m.scenarios.size(), 2u);
  EXPECT_TRUE(m.scenarios[0].builtin);
  EXPECT_EQ(m.scenarios[1].name, "outage-5s");
  EXPECT_EQ(m.scenarios[1].arg, fs::canonical(dir_ / "outage.yaml").string());
  EXPECT_EQ(m.seeds, (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(m.imu, (std::vector<bool>{true, false}));
  EXPECT_EQ(m.replay_args, (std::vector<std::string>{"--vehicle-constraints", "auto"}));
}

TEST_F(ManifestTest, DefaultsAndSeedLists) {
  const Manifest m = LoadManifest(Write("recordings: [{path: bags/two.mcap}]\nscenarios: [urban-canyon]\n"
                                        "seeds: [7, 3]\n"));
  EXPECT_EQ(m.imu, std::vector<bool>{true});
  EXPECT_EQ(m.seeds, (std::vector<int64_t>{7, 3}));
  EXPECT_TRUE(m.replay_args.empty());
}

TEST_F(ManifestTest, UnknownKeyNamesItsLine) {
  const std::string e = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1]\nimus: [on]\n");
  EXPECT_NE(e.find(":4: imus: unknown key"), std::string::npos) << e;
  const std::string nested = Error("recordings:\n  - path: bags/one.mcap\n    topics: x.yaml\nscenarios: [open-sky]\n"
                                   "seeds: [1]\n");
  EXPECT_NE(nested.find(":3: recordings[0].topics: unknown key"), std::string::npos) << nested;
}

TEST_F(ManifestTest, MissingRecordingNamesThePath) {
  const std::string e = Error("recordings:\n  - path: drives/a_sync\n  - path: drives/gone_sync\n"
                              "scenarios: [open-sky]\nseeds: [1]\n");
  EXPECT_NE(e.find(":3: recordings[1].path: "), std::string::npos) << e;
  EXPECT_NE(e.find("gone_sync: does not exist"), std::string::npos) << e;
}

TEST_F(ManifestTest, GlobMatchingNothing) {
  const std::string e = Error("recordings:\n  - path: bags/*.bag\nscenarios: [open-sky]\nseeds: [1]\n");
  EXPECT_NE(e.find(":2: recordings[0].path: glob "), std::string::npos) << e;
  EXPECT_NE(e.find("bags/*.bag matches nothing"), std::string::npos) << e;
}

TEST_F(ManifestTest, NotADriveNorABag) {
  const std::string folder = Error("recordings:\n  - path: empty_folder\nscenarios: [open-sky]\nseeds: [1]\n");
  EXPECT_NE(folder.find(":2: recordings[0].path: "), std::string::npos) << folder;
  EXPECT_NE(folder.find("not a KITTI drive"), std::string::npos) << folder;
  const std::string file = Error("recordings:\n  - path: notes.txt\nscenarios: [open-sky]\nseeds: [1]\n");
  EXPECT_NE(file.find("notes.txt: a file that is not a ROS 2 bag"), std::string::npos) << file;
  const std::string topics = Error("recordings:\n  - path: drives/a_sync\n    bag_topics: topics.yaml\n"
                                   "scenarios: [open-sky]\nseeds: [1]\n");
  EXPECT_NE(topics.find(":3: recordings[0].bag_topics: "), std::string::npos) << topics;
}

TEST_F(ManifestTest, UnknownScenario) {
  const std::string e = Error("recordings: [{path: bags/one.mcap}]\nscenarios:\n  - open-sky\n  - open-skies\n"
                              "seeds: [1]\n");
  EXPECT_NE(e.find(":4: scenarios[1]: unknown scenario 'open-skies'"), std::string::npos) << e;
  EXPECT_NE(e.find("urban-canyon"), std::string::npos) << e;  // the built-ins are listed
  // A scenario file locaid-replay would refuse: its own error, with its own line.
  std::ofstream(dir_ / "bad.yaml") << "name: bad\ngps: {sigma_h_m: -1}\n";
  const std::string bad = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [bad.yaml]\nseeds: [1]\n");
  EXPECT_NE(bad.find(":2: scenarios[0]: "), std::string::npos) << bad;
  EXPECT_NE(bad.find("bad.yaml:2"), std::string::npos) << bad;
  EXPECT_NE(bad.find("sigma_h_m"), std::string::npos) << bad;
}

TEST_F(ManifestTest, BadSeeds) {
  const std::string range = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\n"
                                  "seeds: {from: 5,\n        to: 2}\n");
  EXPECT_NE(range.find(":4: seeds.to: must be >= seeds.from (5)"), std::string::npos) << range;
  const std::string negative = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\n"
                                     "seeds: {from: -1, to: 2}\n");
  EXPECT_NE(negative.find(":3: seeds.from: a seed is >= 0"), std::string::npos) << negative;
  const std::string word = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1, two]\n");
  EXPECT_NE(word.find(":3: seeds[1]: expected an integer"), std::string::npos) << word;
  const std::string twice = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1, 1]\n");
  EXPECT_NE(twice.find("seeds[1]: seed 1 is listed twice"), std::string::npos) << twice;
  const std::string missing = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\n");
  EXPECT_NE(missing.find(":1: seeds: missing"), std::string::npos) << missing;
}

TEST_F(ManifestTest, ReplayArgsTheSweepSetsAreRefused) {
  const std::string e = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1]\n"
                              "replay_args: [--ekf, vo_cov_scale=2,\n              --seed]\n");
  EXPECT_NE(e.find(":5: replay_args[2]: --seed is set by the sweep"), std::string::npos) << e;
  const std::string out = Error("recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1]\n"
                                "replay_args: [--out-csv=x.csv]\n");
  EXPECT_NE(out.find("replay_args[0]: --out-csv=x.csv"), std::string::npos) << out;
}

TEST_F(ManifestTest, SmoothIsABoolean) {
  const std::string base = "recordings: [{path: bags/one.mcap}]\nscenarios: [open-sky]\nseeds: [1]\n";
  EXPECT_FALSE(LoadManifest(Write(base)).smooth);  // default
  EXPECT_TRUE(LoadManifest(Write(base + "smooth: true\n")).smooth);
  EXPECT_FALSE(LoadManifest(Write(base + "smooth: false\n")).smooth);
  const std::string maybe = Error(base + "smooth: maybe\n");
  EXPECT_NE(maybe.find(":4: smooth: expected true or false, got maybe"), std::string::npos) << maybe;
  const std::string list = Error(base + "smooth: [true]\n");
  EXPECT_NE(list.find(":4: smooth: expected true or false"), std::string::npos) << list;
  // One way to smooth: the key, not --smooth among replay_args.
  const std::string arg = Error(base + "replay_args: [--smooth]\n");
  EXPECT_NE(arg.find(":4: replay_args[0]: --smooth is set by the sweep for each run (write smooth: true)"),
            std::string::npos)
      << arg;
  EXPECT_EQ(LoadManifest(Write(base + "smooth: true\nreplay_args: [--smooth-memory-mb, '64']\n")).replay_args.size(),
            2u);
}

TEST_F(ManifestTest, NotYaml) {
  const std::string e = Error("recordings: [{path: bags/one.mcap}\nscenarios: [open-sky]\n");
  EXPECT_NE(e.find("not valid YAML"), std::string::npos) << e;
}

// The plan: one VO run per recording, the filter runs read its cache; a
// scenario with camera faults runs VO itself; keys change with the inputs.
TEST_F(ManifestTest, PlanKeysFollowTheInputs) {
  std::ofstream(dir_ / "dark.yaml") << "name: dark\nbase: open-sky\ncamera: [{start_s: 1, duration_s: 1, fault: dark}]\n";
  const fs::path f = Write("recordings: [{path: drives/a_sync}]\nscenarios: [open-sky, dark.yaml]\nseeds: [1, 2]\n");
  fs::path replay = dir_ / "locaid-replay";
  std::ofstream(replay) << "binary";
  const auto plan = locaid::sweep::BuildPlan(LoadManifest(f), dir_ / "out", replay, "0.1.0");
  ASSERT_EQ(plan.vo.size(), 1u);
  ASSERT_EQ(plan.filter.size(), 4u);
  EXPECT_EQ(plan.filter[0].vo_task, 0);
  EXPECT_EQ(plan.filter[2].vo_task, -1);  // dark: camera faults
  const auto& args = plan.filter[2].args;
  EXPECT_EQ(std::find(args.begin(), args.end(), "--vo-cache"), args.end());
  std::set<std::string> keys;
  for (const auto& t : plan.filter) keys.insert(t.key);
  EXPECT_EQ(keys.size(), 4u);
  // Same inputs, same keys; a touched recording file: new keys everywhere.
  const auto again = locaid::sweep::BuildPlan(LoadManifest(f), dir_ / "out", replay, "0.1.0");
  EXPECT_EQ(again.filter[1].key, plan.filter[1].key);
  std::ofstream(dir_ / "drives/a_sync/image_00/0.png") << "new";
  const auto changed = locaid::sweep::BuildPlan(LoadManifest(f), dir_ / "out", replay, "0.1.0");
  EXPECT_NE(changed.vo[0].key, plan.vo[0].key);
  EXPECT_NE(changed.filter[1].key, plan.filter[1].key);
  EXPECT_EQ(changed.filter[1].id, plan.filter[1].id);  // the same run, with new inputs
  // Another locaid version: new keys.
  EXPECT_NE(locaid::sweep::BuildPlan(LoadManifest(f), dir_ / "out", replay, "0.2.0").filter[1].key,
            changed.filter[1].key);
  // smooth: true: --smooth in every filter run's arguments (so new keys), not in
  // the VO run's (the cache is the same); the plan says so and reads back.
  std::ofstream(f, std::ios::app) << "smooth: true\n";
  const auto smoothed = locaid::sweep::BuildPlan(LoadManifest(f), dir_ / "out", replay, "0.1.0");
  EXPECT_TRUE(smoothed.smooth);
  EXPECT_FALSE(changed.smooth);
  for (const auto& t : smoothed.filter)
    EXPECT_NE(std::find(t.args.begin(), t.args.end(), "--smooth"), t.args.end()) << t.id;
  const auto& vo_args = smoothed.vo[0].args;
  EXPECT_EQ(std::find(vo_args.begin(), vo_args.end(), "--smooth"), vo_args.end());
  EXPECT_EQ(smoothed.vo[0].key, changed.vo[0].key);
  EXPECT_NE(smoothed.filter[1].key, changed.filter[1].key);
  EXPECT_EQ(smoothed.filter[1].id, changed.filter[1].id);
  EXPECT_TRUE(locaid::sweep::PlanFromJson(locaid::sweep::PlanToJson(smoothed)).smooth);
  auto old_plan = locaid::sweep::PlanToJson(changed);
  old_plan.erase("smooth");  // a plan written before the key: not smoothed
  EXPECT_FALSE(locaid::sweep::PlanFromJson(old_plan).smooth);
}

}  // namespace
