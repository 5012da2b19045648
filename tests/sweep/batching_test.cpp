// How many runs an array task carries (sweep/batching.hpp) and which runs
// array task i of a plan runs: the cap of min(1000, MaxArraySize - 1) tasks,
// about 30 s of estimated work per task, K = 1 for small sweeps without an
// estimate, and the plan's batches (consecutive entries of the stage's
// array) through plan.json.
#include "sweep/batching.hpp"
#include "sweep/plan.hpp"

#include <gtest/gtest.h>

using namespace locaid::sweep;

namespace {

TEST(SweepBatching, CapIsMaxArraySizeMinusOneAtMostAThousand) {
  EXPECT_EQ(ArrayTaskCap(std::nullopt), 1000u);  // Slurm's default MaxArraySize 1001
  EXPECT_EQ(ArrayTaskCap(1001), 1000u);
  EXPECT_EQ(ArrayTaskCap(101), 100u);
  EXPECT_EQ(ArrayTaskCap(100001), 1000u);
  EXPECT_EQ(ArrayTaskCap(1), 1u);
  EXPECT_EQ(ParseMaxArraySize("MailProg                = /bin/mail\nMaxArraySize            = 1001\n"
                              "MaxBatchRequeue         = 5\n"),
            1001);
  EXPECT_EQ(ParseMaxArraySize("MaxArraySizeX = 5\n"), std::nullopt);
}

TEST(SweepBatching, AutoKeepsTheArrayUnderTheCapAndGivesEachTaskThirtySeconds) {
  // No estimate: one run per task up to the cap, then as few per task as fit.
  Batching b = AutoBatching(40, std::nullopt, 1000);
  EXPECT_EQ(b.runs_per_task, 1u);
  EXPECT_EQ(b.tasks, 40u);
  b = AutoBatching(80000, std::nullopt, 1000);
  EXPECT_EQ(b.runs_per_task, 80u);
  EXPECT_EQ(b.tasks, 1000u);
  b = AutoBatching(1001, std::nullopt, 1000);
  EXPECT_EQ(b.runs_per_task, 2u);
  EXPECT_EQ(b.tasks, 501u);
  // 0.13 s per run: ceil(30 / 0.13) = 231 runs per task, never more than there are.
  b = AutoBatching(40, 0.13, 1000);
  EXPECT_EQ(b.runs_per_task, 40u);
  EXPECT_EQ(b.tasks, 1u);
  b = AutoBatching(80000, 0.13, 1000);
  EXPECT_EQ(b.runs_per_task, 231u);
  EXPECT_EQ(b.tasks, 347u);
  // Long runs: the cap decides.
  b = AutoBatching(80000, 3.9, 1000);
  EXPECT_EQ(b.runs_per_task, 80u);
  EXPECT_EQ(b.tasks, 1000u);
  b = AutoBatching(10, 60, 1000);
  EXPECT_EQ(b.runs_per_task, 1u);
  EXPECT_EQ(b.tasks, 10u);
  EXPECT_EQ(AutoBatching(0, 0.1, 1000).tasks, 0u);
}

TEST(SweepBatching, FixedAndParsed) {
  const Batching b = FixedBatching(8, 3);
  EXPECT_EQ(b.runs_per_task, 3u);
  EXPECT_EQ(b.tasks, 3u);
  EXPECT_EQ(ParseRunsPerTask("auto"), std::nullopt);
  EXPECT_EQ(ParseRunsPerTask("3"), 3u);
  for (const char* bad : {"0", "-2", "x", "3x", ""}) EXPECT_THROW(ParseRunsPerTask(bad), std::invalid_argument) << bad;
}

Plan SmallPlan() {
  Plan p;
  p.dir = "/s";
  p.manifest = "/s/sweep.yaml";
  p.replay = "/bin/locaid-replay";
  p.replay_fingerprint = "1:2";
  p.locaid_version = "0";
  p.recordings.push_back({"/d", "drive", "", "k"});
  p.vo.push_back({"vo.d", "kv", 0, "/s/vo/d.cache", {"--drive", "/d"}});
  for (int i = 0; i < 10; ++i) {
    std::string id = "f";  // not "f" + ...: GCC 12's -Wrestrict misfires on it (GCC PR 105651)
    id += std::to_string(i);
    p.filter.push_back({id, "k", 0, "open-sky", i, true, 0, {}});
  }
  p.filter_array = {1, 2, 3, 5, 6, 7, 9, 0};  // the pending runs, in any order
  p.vo_array = {0};
  return p;
}

TEST(SweepBatching, ArrayTaskIRunsConsecutiveEntriesOfTheStagesArray) {
  Plan p = SmallPlan();
  EXPECT_EQ(p.array_tasks(Stage::kFilter), 8u);  // one run per task unless told
  EXPECT_EQ(p.batch(Stage::kFilter, 3), std::vector<size_t>({5}));
  p.filter_runs_per_task = 3;
  EXPECT_EQ(p.array_tasks(Stage::kFilter), 3u);
  EXPECT_EQ(p.batch(Stage::kFilter, 0), std::vector<size_t>({1, 2, 3}));
  EXPECT_EQ(p.batch(Stage::kFilter, 1), std::vector<size_t>({5, 6, 7}));
  EXPECT_EQ(p.batch(Stage::kFilter, 2), std::vector<size_t>({9, 0}));
  EXPECT_TRUE(p.batch(Stage::kFilter, 3).empty());
  EXPECT_EQ(p.array_tasks(Stage::kVo), 1u);

  // Through plan.json; a plan written before batching has one run per task.
  const Plan back = PlanFromJson(PlanToJson(p));
  EXPECT_EQ(back.filter_runs_per_task, 3u);
  EXPECT_EQ(back.vo_runs_per_task, 1u);
  EXPECT_EQ(back.batch(Stage::kFilter, 2), std::vector<size_t>({9, 0}));
  auto old = PlanToJson(p);
  old.erase("runs_per_task");
  EXPECT_EQ(PlanFromJson(old).filter_runs_per_task, 1u);
  auto zero = PlanToJson(p);
  zero["runs_per_task"]["filter"] = 0;
  EXPECT_THROW(PlanFromJson(zero), std::runtime_error);
}

}  // namespace
