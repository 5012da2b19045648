// The tables' arithmetic: percentiles as numpy's default, NEES share,
// failures counted per group, a run without an outage has an empty
// end_error_pct, a smoothed sweep's columns next to the forward ones, every
// outage's figures, consistency and the gates.
#include "sweep/summary.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

using namespace locaid::sweep;

namespace {

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

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
    r.forward.end_error_pct = pct;
    r.forward.rmse_gps_m = 1;
    r.forward.nees_mean = nees;
    r.forward.nees_bound_99 = 4;
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
  EXPECT_DOUBLE_EQ(groups[0].forward.end_error_pct.median, 2.0);
  EXPECT_DOUBLE_EQ(groups[0].nees_over_bound_share, 0.5);
  EXPECT_EQ(groups[0].gps_resets, 2);
  EXPECT_EQ(groups[0].gps_rejected, 4);
  EXPECT_EQ(groups[1].forward.end_error_pct.n, 0u);  // no outage in that scenario
  EXPECT_EQ(groups[2].pending, 1u);

  locaid::test_support::ScopedTempDir dir("sweep_summary");
  WriteResultsCsv(rows, false, dir / "results.csv");
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
  EXPECT_EQ(header.find("_smoothed"), std::string::npos) << header;  // not a smoothed sweep
}

// A smoothed sweep: the smoothed errors go to their own columns and
// distributions, next to the forward ones; a run without them (failed,
// pending) leaves them empty. NaN (null in the JSON) is no value.
TEST(SweepSummary, SmoothedColumnsAndDistributionsNextToTheForwardOnes) {
  const nlohmann::json metrics = nlohmann::json::parse(R"({
    "rmse_gps_m": 1.5, "nees_mean": 2, "nees_bound_99": 4,
    "outages": [{"end_error_pct": 10, "end_error_m": 2, "max_error_m": 3, "rmse_m": 1.25}, {"end_error_pct": 99}],
    "smoothed": {"rmse_gps_m": 0.5, "nees_mean": 1, "nees_bound_99": 4,
                 "outages": [{"end_error_pct": 4, "end_error_m": 0.8, "max_error_m": 1, "rmse_m": null}]}})");
  ResultRow done;
  done.recording = "a";
  done.scenario = "tunnel";
  done.state = RunState::kDone;
  done.forward = ReadRunMetrics(metrics);
  done.smoothed = ReadRunMetrics(metrics["smoothed"]);
  EXPECT_EQ(done.forward.outage_rmse_m, 1.25);  // the first outage's
  EXPECT_EQ(done.forward.max_error_m, 3);
  EXPECT_EQ(done.smoothed->end_error_pct, 4);
  EXPECT_FALSE(done.smoothed->outage_rmse_m);
  ResultRow second = done;
  second.forward.end_error_pct = 20;
  second.smoothed->end_error_pct = 6;
  ResultRow failed = done;
  failed.state = RunState::kFailed;
  failed.forward = {};
  failed.smoothed.reset();
  const auto groups = Summarize({done, second, failed});
  ASSERT_EQ(groups.size(), 1u);
  EXPECT_DOUBLE_EQ(groups[0].forward.end_error_pct.median, 15);
  EXPECT_DOUBLE_EQ(groups[0].smoothed.end_error_pct.median, 5);
  EXPECT_DOUBLE_EQ(groups[0].smoothed.rmse_gps_m.max, 0.5);
  EXPECT_EQ(groups[0].smoothed.outage_rmse_m.n, 0u);

  locaid::test_support::ScopedTempDir dir("sweep_summary");
  WriteResultsCsv({done, failed}, true, dir / "results.csv");
  std::ifstream in(dir / "results.csv");
  std::string header, first, last;
  std::getline(in, header);
  std::getline(in, first);
  std::getline(in, last);
  EXPECT_EQ(header.rfind("recording,scenario,seed,imu,status,end_error_pct,rmse_gps_m,nees_mean,", 0), 0u) << header;
  const std::string added = ",run_id,error,max_error_m,outage_rmse_m,end_error_pct_smoothed,end_error_m_smoothed,"
                            "max_error_m_smoothed,outage_rmse_m_smoothed,rmse_gps_m_smoothed,max_vertical_error_m,"
                            "gps_rejected_vertical,end_error_pct_every_outage";
  EXPECT_TRUE(EndsWith(header, added)) << header;
  EXPECT_TRUE(EndsWith(first, ",3,1.25,4,0.8,1,,0.5,,0,")) << first;  // no figures read into this row
  EXPECT_TRUE(EndsWith(last, ",failed" + std::string(21, ','))) << last;  // 11 columns to error, 10 added: empty

  WriteSummaryCsv(groups, true, dir / "summary.csv");
  std::ifstream summary(dir / "summary.csv");
  std::getline(summary, header);
  EXPECT_NE(header.find(",max_error_m_median,max_error_m_p90,max_error_m_max,"), std::string::npos) << header;
  EXPECT_NE(header.find(",end_error_pct_smoothed_median,end_error_pct_smoothed_p90,"), std::string::npos) << header;
  WriteSummaryCsv(groups, false, dir / "summary.csv");
  std::ifstream plain(dir / "summary.csv");
  std::getline(plain, header);
  EXPECT_EQ(header.find("_smoothed"), std::string::npos) << header;
}

// The figures of every outage, consistency and the gates from the runs'
// locaid-replay --json, summed and distributed per group.
TEST(SweepSummary, EveryOutageConsistencyAndTheGates) {
  const nlohmann::json a = nlohmann::json::parse(R"({
    "rmse_gps_m": 0.5, "nees_mean": 2, "nees_bound_99": 4, "max_vertical_error_m": 1.5,
    "gps_used": 990, "gps_rejected": 10, "gps_rejected_vertical": 3, "gps_resets": 1, "vo_rejected_by_gate": 4,
    "max_gps_rejection_run": 2, "max_gps_rejection_run_vertical": 3,
    "modes": {"GPS_FUSED": 80, "VO_ONLY": 20}, "vo_health": {"tracking": 100},
    "vehicle": {"speed_used": 50, "speed_scale_error": 0.004},
    "outages": [{"end_error_pct": 1, "added_error_pct": 0.5, "reconverge_s": 0.2},
                {"end_error_pct": 3, "added_error_pct": null, "reconverge_s": -1}]})");
  const nlohmann::json b = nlohmann::json::parse(R"({
    "rmse_gps_m": 0.7, "nees_mean": 6, "nees_bound_99": 4, "max_vertical_error_m": 2.5,
    "gps_used": 1995, "gps_rejected": 5, "gps_rejected_vertical": 1, "gps_resets": 0, "vo_rejected_by_gate": 2,
    "max_gps_rejection_run": 1, "max_gps_rejection_run_vertical": 1,
    "modes": {"GPS_FUSED": 90, "DEAD_RECKONING": 10}, "vo_health": {"tracking": 90, "dark": 10},
    "vehicle": {"speed_used": 0, "speed_scale_error": 0},
    "outages": [{"end_error_pct": 2, "added_error_pct": 1.5, "reconverge_s": 0.4}]})");
  auto done = [](const nlohmann::json& m, int64_t seed, double gate) {
    ResultRow r;
    r.recording = "a";
    r.scenario = "tunnel";
    r.seed = seed;
    r.state = RunState::kDone;
    r.forward = ReadRunMetrics(m);
    r.figures = ReadRunFigures(m);
    r.gps_rejected = m["gps_rejected"].get<int64_t>();
    r.gps_resets = m["gps_resets"].get<int64_t>();
    r.gps_gate_probability = gate;
    return r;
  };
  ResultRow failed = done(a, 3, 0.999);
  failed.state = RunState::kFailed;
  const auto groups = Summarize({done(a, 1, 0.999), done(b, 2, 0.99), failed});
  ASSERT_EQ(groups.size(), 1u);
  const GroupSummary& g = groups[0];
  EXPECT_EQ(g.forward.end_error_pct.n, 2u);  // the first outage's, as before
  EXPECT_EQ(g.end_error_pct_every.n, 3u);
  EXPECT_DOUBLE_EQ(g.end_error_pct_every.median, 2);
  EXPECT_DOUBLE_EQ(g.end_error_pct_every.max, 3);
  EXPECT_EQ(g.added_error_pct.n, 2u);  // null: not given
  EXPECT_DOUBLE_EQ(g.added_error_pct.max, 1.5);
  EXPECT_EQ(g.reconverge_s.n, 2u);
  EXPECT_DOUBLE_EQ(g.reconverge_s.max, 0.4);
  EXPECT_EQ(g.reconverge_never, 1u);
  EXPECT_EQ(g.nees_over_bound_seeds, std::vector<int64_t>{2});
  EXPECT_DOUBLE_EQ(g.nees_mean_over_bound.max, 1.5);
  EXPECT_DOUBLE_EQ(g.max_vertical_error_m.max, 2.5);
  EXPECT_EQ(g.speed_scale_error.n, 1u);  // only the run that fused speed readings
  EXPECT_DOUBLE_EQ(g.speed_scale_error.median, 0.004);
  EXPECT_EQ(g.modes.at("GPS_FUSED"), 170);
  EXPECT_EQ(g.modes.at("DEAD_RECKONING"), 10);
  EXPECT_EQ(g.vo_health.at("dark"), 10);
  EXPECT_EQ(g.gps_fixes, 3000);
  EXPECT_EQ(g.gps_rejected, 15);
  EXPECT_EQ(g.gps_rejected_vertical, 4);
  EXPECT_NEAR(g.gps_expected_false_alarms, 1000 * 0.001 + 2000 * 0.01, 1e-9);  // each run at its own gate
  EXPECT_EQ(g.gps_longest_rejection_run, 3);
  EXPECT_EQ(g.gps_resets, 1);
  EXPECT_DOUBLE_EQ(g.vo_rejected_per_run, 3);

  locaid::test_support::ScopedTempDir dir("sweep_summary");
  WriteSummaryJson(groups, false, dir / "summary.json");
  std::ifstream in(dir / "summary.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j[0]["end_error_pct_every"]["n"], 3);
  EXPECT_EQ(j[0]["reconverge_never"], 1);
  EXPECT_EQ(j[0]["nees_over_bound_seeds"], nlohmann::json::array({2}));
  EXPECT_EQ(j[0]["gps_longest_rejection_run"], 3);
  EXPECT_EQ(j[0]["modes"]["VO_ONLY"], 20);
}

// A run's GPS gate: EkfConfig's unless its --ekf sets it (by either name).
TEST(SweepSummary, GpsGateProbabilityFollowsTheRunsEkfSettings) {
  const double nominal = GpsGateProbability({"--drive", "d", "--json"});
  EXPECT_GT(nominal, 0.99);
  EXPECT_LT(nominal, 1.0);
  EXPECT_DOUBLE_EQ(GpsGateProbability({"--ekf", "gps.gate_probability=0.99", "--json"}), 0.99);
  EXPECT_DOUBLE_EQ(GpsGateProbability({"--ekf=gps.gate_probability=0.95"}), 0.95);
  EXPECT_DOUBLE_EQ(GpsGateProbability({"--ekf", "gps_gate_probability=0.9"}), 0.9);  // the flat name
  EXPECT_DOUBLE_EQ(GpsGateProbability({"--ekf", "vo.cov_scale=12"}), nominal);
}

}  // namespace
