// The tables' arithmetic: percentiles as numpy's default, NEES share,
// failures counted per group, a run without an outage has an empty
// end_error_pct.
#include "sweep/summary.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

using namespace locaid::sweep;

namespace {

TEST(SweepSummary, PercentilesInterpolateBetweenOrderStatistics) {
  const Distribution d = Distribute({4, 1, 3, 2, 5, 6, 7, 8, 9, 10});
  EXPECT_EQ(d.n, 10u);
  EXPECT_DOUBLE_EQ(d.median, 5.5);
  EXPECT_DOUBLE_EQ(d.p90, 9.1);  // numpy.percentile([1..10], 90)
  EXPECT_DOUBLE_EQ(d.max, 10);
  EXPECT_EQ(Distribute({}).n, 0u);
  EXPECT_DOUBLE_EQ(Distribute({3}).p90, 3);
}

TEST(SweepSummary, GroupsCountFailuresAndNeesOverItsBound) {
  auto row = [](std::string rec, bool imu, RunState s, std::optional<double> pct, double nees) {
    ResultRow r;
    r.recording = rec;
    r.scenario = "tunnel";
    r.imu = imu;
    r.state = s;
    r.end_error_pct = pct;
    r.rmse_gps_m = 1;
    r.nees_mean = nees;
    r.nees_bound_99 = 4;
    r.gps_resets = 1;
    r.gps_rejected = 2;
    return r;
  };
  const std::vector<ResultRow> rows = {row("a", true, RunState::kDone, 1.0, 3), row("a", true, RunState::kDone, 3.0, 5),
                                       row("a", true, RunState::kFailed, std::nullopt, 0),
                                       row("a", false, RunState::kDone, std::nullopt, 1),
                                       row("b", true, RunState::kPending, std::nullopt, 0)};
  const auto groups = Summarize(rows);
  ASSERT_EQ(groups.size(), 3u);
  EXPECT_EQ(groups[0].runs, 3u);
  EXPECT_EQ(groups[0].done, 2u);
  EXPECT_EQ(groups[0].failed, 1u);
  EXPECT_DOUBLE_EQ(groups[0].end_error_pct.median, 2.0);
  EXPECT_DOUBLE_EQ(groups[0].nees_over_bound_share, 0.5);
  EXPECT_EQ(groups[0].gps_resets, 2);
  EXPECT_EQ(groups[0].gps_rejected, 4);
  EXPECT_EQ(groups[1].end_error_pct.n, 0u);  // no outage in that scenario
  EXPECT_EQ(groups[2].pending, 1u);

  locaid::test_support::ScopedTempDir dir("sweep_summary");
  WriteResultsCsv(rows, dir / "results.csv");
  std::ifstream in(dir / "results.csv");
  std::string header, first, second, third, fourth;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("recording,scenario,seed,imu,status,end_error_pct,rmse_gps_m,nees_mean,", 0), 0u) << header;
  std::getline(in, first);
  std::getline(in, second);
  std::getline(in, third);
  std::getline(in, fourth);
  EXPECT_EQ(first.rfind("a,tunnel,0,on,done,1,1,3,", 0), 0u) << first;
  EXPECT_EQ(third.rfind("a,tunnel,0,on,failed,,", 0), 0u) << third;
  EXPECT_EQ(fourth.rfind("a,tunnel,0,off,done,,1,1,", 0), 0u) << fourth;  // no outage: empty
}

}  // namespace
