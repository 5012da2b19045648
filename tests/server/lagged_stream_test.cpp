// Lagged (smoothed) pose streams, StreamPosesRequest.smoothing_lag_s: the
// real server on 127.0.0.1 with the production estimator (stereo VO + EKF,
// so there is a filter to smooth) on small synthetic drives, subscribed by
// gRPC clients and by the real `locaid` CLI.
#include "test_support.hpp"

#include "fusion/geodesy.hpp"

#include <cmath>
#include <limits>
#include <sstream>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kSecondNs = 1'000'000'000;

// A StreamPoses request of `lag_s` (set_lag_field false: the field unset).
v1::StreamPosesRequest Lagged(const std::string& id, double lag_s, bool from_start, bool set_lag_field = true) {
  v1::StreamPosesRequest req = PoseCollector::Request(id, from_start);
  if (set_lag_field) req.set_smoothing_lag_s(lag_s);
  return req;
}

// Reads a stream; after each pose, a GetStats of the session: its
// poses_published (causal poses, a count that only grows) is then at least
// what the session had published when it sent this pose, so a pose sent too
// early shows as a count below the causal pose it had to wait for (the
// session is paced: the count moves slower than a GetStats takes).
class StatsProbe {
 public:
  StatsProbe(int port, const std::string& id, double lag_s)
      : stub_(MakeStub(port)),
        collector_(MakeChannel(port), Lagged(id, lag_s, false), 120, [this, id](const v1::PoseUpdate&) {
          v1::SessionStats s;
          published_.push_back(FetchStats(stub_.get(), id, &s).ok() ? s.poses_published() : 0);
        }) {}
  PoseCollector& collector() { return collector_; }
  // Per pose of collector().poses(), after WaitDone.
  const std::vector<uint64_t>& published() const { return published_; }

 private:
  std::unique_ptr<v1::Localization::Stub> stub_;
  std::vector<uint64_t> published_;  // the reading thread's until the stream ends
  PoseCollector collector_;          // last: its thread starts once the rest is built
};

// The status of a StreamPoses call that is refused (ends before any pose).
grpc::Status RefusedStream(v1::Localization::Stub* stub, const std::string& id, double lag_s) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 10);
  v1::StreamPosesRequest req;
  req.set_session_id(id);
  req.set_smoothing_lag_s(lag_s);
  auto reader = stub->StreamPoses(&ctx, req);
  v1::PoseUpdate p;
  while (reader->Read(&p)) {
  }
  return reader->Finish();
}

double PositionVarianceSum(const v1::PoseUpdate& p) {
  return p.covariance_size() == 36 ? p.covariance(0) + p.covariance(7) + p.covariance(14) : 0;
}

class LaggedStreamTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<LocalizationServer>(LoopbackConfig(dir_ / "work"));  // the production estimator
    port_ = server_->port();
    stub_ = MakeStub(port_);
  }
  void TearDown() override { server_->Shutdown(); }

  // A synthetic drive of `frames` small frames (10 Hz), rendered by the
  // session first (it is STARTING meanwhile); rate 0: as fast as possible.
  std::string StartSynthetic(int frames, double rate) {
    v1::StartSessionRequest req;
    req.mutable_synthetic()->set_seed(7);
    req.mutable_synthetic()->set_frames(static_cast<uint32_t>(frames));
    req.mutable_synthetic()->set_options_yaml("width: 320\nheight: 96\n");
    req.set_playback_rate(rate);
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session session;
    const grpc::Status s = stub_->StartSession(&ctx, req, &session);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return session.id();
  }
  // Waits (bounded) until `n` subscribers (causal and lagged) are attached;
  // returns the frames processed by then.
  uint64_t WaitForSubscribers(const std::string& id, uint32_t n) {
    const v1::SessionStats s =
        WaitStats(stub_.get(), id, 10, [n](const v1::SessionStats& st) { return st.subscribers() >= n; });
    EXPECT_GE(s.subscribers(), n);
    return s.frames_processed();
  }
  void Stop(const std::string& id) {
    const CliResult r = RunCli(port_, {"session", "stop", id});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }

  const ScopedTempDir dir_{"lagged_stream"};
  std::unique_ptr<LocalizationServer> server_;
  int port_ = 0;
  std::unique_ptr<v1::Localization::Stub> stub_;
};

TEST_F(LaggedStreamTest, LagZeroIsTheCausalStreamBitForBit) {
  const std::string id = StartSynthetic(30, 0);
  PoseCollector without(MakeChannel(port_), Lagged(id, 0, true, /*set_lag_field=*/false), 120);
  PoseCollector zero(MakeChannel(port_), Lagged(id, 0, true), 120);
  ASSERT_TRUE(without.WaitDone(120));
  ASSERT_TRUE(zero.WaitDone(120));
  EXPECT_TRUE(without.status().ok()) << without.status().error_message();
  EXPECT_TRUE(zero.status().ok()) << zero.status().error_message();
  const auto a = without.poses(), b = zero.poses();
  ASSERT_EQ(a.size(), 30u);
  ASSERT_EQ(b.size(), a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].SerializeAsString(), b[i].SerializeAsString()) << "pose " << i;
    EXPECT_FALSE(b[i].smoothed());
  }
}

TEST_F(LaggedStreamTest, AOneSecondLagGivesEveryPoseSmoothedOnceTheSessionIsOneSecondPastIt) {
  // 50 frames (5 s of sensor time) at 4 x real time: the lagged subscriber
  // is attached while the session renders its drive.
  const std::string id = StartSynthetic(50, 4);
  PoseCollector causal(MakeChannel(port_), id, /*from_start=*/true);
  StatsProbe probe(port_, id, 1.0);
  PoseCollector& lagged = probe.collector();
  const uint64_t frames_before = WaitForSubscribers(id, 2);
  ASSERT_TRUE(causal.WaitDone(120));
  ASSERT_TRUE(lagged.WaitDone(120)) << "the lagged stream ends after the session's last poses";
  EXPECT_TRUE(lagged.status().ok()) << lagged.status().error_message();
  const auto c = causal.poses(), l = lagged.poses();
  const auto& published = probe.published();
  ASSERT_EQ(c.size(), 50u);
  ASSERT_FALSE(l.empty());
  // Every causal pose from the lagged subscriber's first one, in order.
  const uint64_t first = l.front().sequence();
  if (frames_before == 0) {
    EXPECT_EQ(first, 0u) << "subscribed before the first pose";
  }
  ASSERT_EQ(l.size(), c.size() - first);
  size_t covariance_differs = 0, smoothable = 0;
  for (size_t i = 0; i < l.size(); ++i) {
    const v1::PoseUpdate& s = l[i];
    const v1::PoseUpdate& f = c[first + i];
    ASSERT_EQ(s.sequence(), f.sequence()) << i;
    EXPECT_EQ(s.t_ns(), f.t_ns()) << i;
    EXPECT_EQ(s.frame_index(), f.frame_index()) << i;
    EXPECT_TRUE(s.smoothed()) << i;
    EXPECT_FALSE(f.smoothed()) << i;
    ASSERT_EQ(s.covariance_size(), 36) << i;
    // Sent only once the causal pose 1 s later had been published (or, for
    // the last second, once the session had published its last pose).
    uint64_t needed = c.size();  // the whole session
    for (size_t j = first + i; j < c.size(); ++j) {
      if (c[j].t_ns() >= f.t_ns() + kSecondNs) {
        needed = j + 1;
        break;
      }
    }
    EXPECT_GE(published[i], needed) << "pose " << s.sequence() << " came before causal pose " << needed - 1;
    // Smoothing never loses information: the position variance of a
    // smoothed pose is at most the filter's.
    EXPECT_LE(PositionVarianceSum(s), PositionVarianceSum(f) * (1 + 1e-9) + 1e-12) << i;
    if (f.mode() == v1::MODE_LOST) continue;  // the filter had not started: nothing to smooth
    ++smoothable;
    bool differs = false;
    for (int k = 0; k < 36; ++k) differs = differs || s.covariance(k) != f.covariance(k);
    covariance_differs += differs ? 1 : 0;
  }
  ASSERT_GT(smoothable, 10u) << "the filter started too late in the drive";
  EXPECT_GE(covariance_differs, smoothable * 9 / 10) << "of " << smoothable;
  // Latitude, longitude and altitude are those of the smoothed position.
  const v1::Session session = GetSession(stub_.get(), id);
  ASSERT_TRUE(session.has_origin());
  fusion::EnuFrame enu;
  enu.SetOrigin(session.origin_latitude_deg(), session.origin_longitude_deg(), session.origin_altitude_m());
  for (const auto& p : l) {
    if (p.mode() == v1::MODE_LOST) continue;
    const Eigen::Vector3d geo = enu.ToEnu(p.latitude_deg(), p.longitude_deg(), p.altitude_m());
    const Eigen::Vector3d pos(p.position_enu_m().x(), p.position_enu_m().y(), p.position_enu_m().z());
    EXPECT_LT((geo - pos).norm(), 1e-6) << "pose " << p.sequence();
  }
}

TEST_F(LaggedStreamTest, ALagOutsideZeroToThirtySecondsIsRefusedWithTheRange) {
  // A live session waiting for frames: it runs until stopped.
  std::string id;
  {
    v1::StartSessionRequest req;
    *req.mutable_live() = SmallCamera();
    grpc::ClientContext ctx;
    SetDeadline(&ctx);
    v1::Session session;
    ASSERT_TRUE(stub_->StartSession(&ctx, req, &session).ok());
    id = session.id();
  }
  const struct {
    double lag;
    const char* got;
  } cases[] = {{31, "(got 31)"}, {-1, "(got -1)"}, {std::numeric_limits<double>::quiet_NaN(), "(got nan)"}};
  for (const auto& c : cases) {
    const grpc::Status s = RefusedStream(stub_.get(), id, c.lag);
    EXPECT_EQ(s.error_code(), grpc::INVALID_ARGUMENT) << c.got;
    EXPECT_NE(s.error_message().find(std::string("smoothing_lag_s must be in [0, 30] s ") + c.got),
              std::string::npos)
        << s.error_message();
  }
  // The bound on distinct lags: four at a time, a fifth is refused, a lag
  // already smoothed is shared.
  std::vector<std::unique_ptr<PoseCollector>> four;
  for (double lag : {0.5, 1.0, 2.0, 30.0})
    four.push_back(std::make_unique<PoseCollector>(MakeChannel(port_), Lagged(id, lag, false), 120));
  WaitForSubscribers(id, 4);
  const grpc::Status fifth = RefusedStream(stub_.get(), id, 3.0);
  EXPECT_EQ(fifth.error_code(), grpc::RESOURCE_EXHAUSTED);
  EXPECT_NE(fifth.error_message().find("4 distinct lags (0.5 s, 1 s, 2 s, 30 s)"), std::string::npos)
      << fifth.error_message();
  PoseCollector shared(MakeChannel(port_), Lagged(id, 2.0, false), 120);
  WaitForSubscribers(id, 5);
  Stop(id);
  for (auto& c : four) ASSERT_TRUE(c->WaitDone(60));
  ASSERT_TRUE(shared.WaitDone(60));
  EXPECT_TRUE(shared.status().ok()) << shared.status().error_message();
}

TEST_F(LaggedStreamTest, StopSessionDeliversThePosesStillWaitingForTheirLagSmoothedThenEndsOk) {
  // Real time, a 1 s lag: stopped after 25 poses, about 10 still wait.
  const std::string id = StartSynthetic(60, 1);
  PoseCollector causal(MakeChannel(port_), id, /*from_start=*/true);
  PoseCollector lagged(MakeChannel(port_), Lagged(id, 1.0, false), 120);
  WaitForSubscribers(id, 2);
  ASSERT_TRUE(causal.WaitPoses(25, 60));
  ASSERT_TRUE(lagged.WaitPoses(1, 60));
  Stop(id);
  ASSERT_TRUE(causal.WaitDone(60));
  ASSERT_TRUE(lagged.WaitDone(60));
  EXPECT_TRUE(lagged.status().ok()) << lagged.status().error_message();
  const auto c = causal.poses(), l = lagged.poses();
  ASSERT_LT(c.size(), 60u) << "stopped before the end";
  ASSERT_FALSE(l.empty());
  const uint64_t first = l.front().sequence();
  ASSERT_EQ(l.size(), c.size() - first) << "every causal pose from the first lagged one, none lost";
  for (size_t i = 0; i < l.size(); ++i) {
    EXPECT_EQ(l[i].sequence(), c[first + i].sequence()) << i;
    EXPECT_EQ(l[i].t_ns(), c[first + i].t_ns()) << i;
    EXPECT_TRUE(l[i].smoothed()) << i;
  }
  // At least the last second was still waiting at the stop.
  size_t last_second = 0;
  for (const auto& p : l) last_second += p.t_ns() > c.back().t_ns() - kSecondNs ? 1 : 0;
  EXPECT_GE(last_second, 5u);
}

TEST_F(LaggedStreamTest, ALagLongerThanTheSessionGivesEveryPoseAtItsEndAlsoBeyondTheQueue) {
  // 40 poses, all still waiting for a 30 s lag when the drive ends: released
  // at once into a queue of 8, which a subscriber that reads drains in time.
  const std::string id = StartSynthetic(40, 0);
  v1::StreamPosesRequest req = Lagged(id, 30, false);
  req.set_queue_size(8);
  PoseCollector lagged(MakeChannel(port_), req, 120);
  PoseCollector causal(MakeChannel(port_), id, /*from_start=*/true);
  ASSERT_TRUE(causal.WaitDone(120));
  ASSERT_TRUE(lagged.WaitDone(120));
  EXPECT_TRUE(lagged.status().ok()) << lagged.status().error_message();
  const auto c = causal.poses(), l = lagged.poses();
  ASSERT_EQ(c.size(), 40u);
  ASSERT_FALSE(l.empty());
  const uint64_t first = l.front().sequence();
  ASSERT_EQ(l.size(), c.size() - first);
  for (size_t i = 0; i < l.size(); ++i) {
    EXPECT_EQ(l[i].sequence(), c[first + i].sequence()) << i;
    EXPECT_TRUE(l[i].smoothed()) << i;
    EXPECT_EQ(l[i].dropped_for_subscriber(), 0u) << i;
  }
}

TEST_F(LaggedStreamTest, TheCliSubscribesWithALagAndWritesASmoothedColumn) {
  const std::string id = StartSynthetic(40, 2);
  const fs::path csv = dir_ / "lagged.csv";
  const CliResult r = RunCli(port_, {"subscribe", id, "--lag", "1", "--format", "csv", "--out", csv.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<std::string> smoothed = CsvColumn(Slurp(csv), "smoothed");
  for (size_t i = 0; i < smoothed.size(); ++i) EXPECT_EQ(smoothed[i], "1") << "pose " << i;
  EXPECT_FALSE(smoothed.empty()) << "a smoothed column with poses";
  const CliResult bad = RunCli(port_, {"subscribe", id, "--lag", "31"});
  EXPECT_EQ(bad.exit_code, 2) << "a usage error: " << bad.err;
  fs::remove(csv);
}

}  // namespace
}  // namespace locaid::server::testing
