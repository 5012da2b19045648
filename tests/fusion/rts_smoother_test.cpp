// The smoother (fusion/epoch_log.hpp, rts_smoother.hpp): on linear-Gaussian
// models it equals the batch least-squares solution; its store spills to
// disk without changing a bit; on simulated drives it is never worse than
// the filter on average and its NEES stays in bounds.
#include "fusion/ekf.hpp"
#include "fusion/epoch_log.hpp"
#include "fusion/fixed_lag_smoother.hpp"
#include "fusion/offline_smoother.hpp"
#include "fusion/process_model.hpp"
#include "fusion/rts_smoother.hpp"
#include "sim.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <random>

namespace locaid::fusion {
namespace {

constexpr double kLinearTol = 1e-9;

// ---------------------------------------------------------------- linear model
// State [p (3), v (3)] held in NominalState's p and v; constant velocity.
struct LinearStep {
  enum Kind { kPropagate, kMeasurePosition, kMeasureVelocity, kMark, kBreak } kind;
  Eigen::VectorXd z;  // measurement (3)
};

struct LinearCase {
  std::string name;
  double dt = 0.1, q_acc = 0.3, r_pos = 0.5, r_vel = 0.2;
  std::vector<LinearStep> steps;
};

Eigen::MatrixXd Phi(double dt) {
  Eigen::MatrixXd F = Eigen::MatrixXd::Identity(6, 6);
  F.topRightCorner(3, 3) = dt * Eigen::Matrix3d::Identity();
  return F;
}
Eigen::MatrixXd Q(const LinearCase& c) {  // white acceleration, plus a little on p (full rank)
  Eigen::MatrixXd q = Eigen::MatrixXd::Zero(6, 6);
  const double a = c.q_acc * c.q_acc, dt = c.dt;
  q.topLeftCorner(3, 3).diagonal().setConstant(a * dt * dt * dt / 3 + 1e-4);
  q.topRightCorner(3, 3).diagonal().setConstant(a * dt * dt / 2);
  q.bottomLeftCorner(3, 3).diagonal().setConstant(a * dt * dt / 2);
  q.bottomRightCorner(3, 3).diagonal().setConstant(a * dt);
  return q;
}
Eigen::MatrixXd H(LinearStep::Kind kind) {
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(3, 6);
  h.middleCols(kind == LinearStep::kMeasurePosition ? 0 : 3, 3).setIdentity();
  return h;
}
Eigen::VectorXd StateOf(const NominalState& x) {
  Eigen::VectorXd v(6);
  v << x.p_enu_m, x.v_enu_mps;
  return v;
}

Eigen::MatrixXd P0() { return Eigen::VectorXd::LinSpaced(6, 4.0, 0.5).asDiagonal(); }

// The Kalman filter with the log's hooks, as the EKF's models call them.
// Returns, per Mark, the epoch seq and the state index it stands for.
struct LinearRun {
  std::vector<Epoch> epochs;
  std::map<int64_t, int> state_of_epoch;  // epoch seq -> index of the state (0 = the start)
};
LinearRun RunLinearFilter(const LinearCase& c) {
  LinearRun run;
  EpochLog log([&](Epoch&& e) { run.epochs.push_back(std::move(e)); });
  FilterState s;
  s.initialized = true;
  s.P = P0();
  s.log = &log;
  log.Start(s);
  int state = 0;
  for (const LinearStep& st : c.steps) {
    switch (st.kind) {
      case LinearStep::kPropagate: {
        const Eigen::VectorXd x = Phi(c.dt) * StateOf(s.x);
        s.x.p_enu_m = x.head<3>();
        s.x.v_enu_mps = x.tail<3>();
        s.P = Phi(c.dt) * s.P * Phi(c.dt).transpose() + Q(c);
        s.t_ns += static_cast<int64_t>(c.dt * 1e9);
        ++state;
        log.Transition(s, Phi(c.dt));
        break;
      }
      case LinearStep::kMeasurePosition:
      case LinearStep::kMeasureVelocity: {
        const Eigen::MatrixXd h = H(st.kind);
        const double r = st.kind == LinearStep::kMeasurePosition ? c.r_pos : c.r_vel;
        const Eigen::MatrixXd R = Eigen::MatrixXd::Identity(3, 3) * r * r;
        const Eigen::MatrixXd K = s.P * h.transpose() * (h * s.P * h.transpose() + R).inverse();
        const Eigen::VectorXd dx = K * (st.z - h * StateOf(s.x));
        const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(6, 6) - K * h;
        s.P = IKH * s.P * IKH.transpose() + K * R * K.transpose();
        s.x.p_enu_m += dx.head<3>();
        s.x.v_enu_mps += dx.tail<3>();
        log.Corrected(s, dx);
        break;
      }
      case LinearStep::kMark:
        run.state_of_epoch[log.Mark(s)] = state;
        break;
      case LinearStep::kBreak:
        log.Start(s);
        run.state_of_epoch[log.Mark(s)] = state;
        break;
    }
  }
  run.state_of_epoch[log.Mark(s)] = state;
  log.Finish();
  return run;
}

// Batch MAP over the states 0..N of one chain (prior on state 0 at the
// state and covariance the chain starts from): the normal equations.
struct Batch {
  Eigen::VectorXd mean;  // 6 (N + 1)
  Eigen::MatrixXd cov;
};
Batch SolveBatch(const LinearCase& c, const std::vector<LinearStep>& steps, const Eigen::VectorXd& x0,
                 const Eigen::MatrixXd& P0) {
  int n_states = 1;
  for (const auto& st : steps) n_states += st.kind == LinearStep::kPropagate;
  const int N = 6 * n_states;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(N, N);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(N);
  const Eigen::MatrixXd P0i = P0.inverse();
  A.topLeftCorner(6, 6) += P0i;
  b.head(6) += P0i * x0;
  const Eigen::MatrixXd Qi = Q(c).inverse(), F = Phi(c.dt);
  int k = 0;
  for (const auto& st : steps) {
    if (st.kind == LinearStep::kPropagate) {
      // r = x_{k+1} - F x_k : J = [-F, I]
      Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, 12);
      J.leftCols(6) = -F;
      J.rightCols(6).setIdentity();
      A.block(6 * k, 6 * k, 12, 12) += J.transpose() * Qi * J;
      ++k;
    } else if (st.kind == LinearStep::kMeasurePosition || st.kind == LinearStep::kMeasureVelocity) {
      const Eigen::MatrixXd h = H(st.kind);
      const double r = st.kind == LinearStep::kMeasurePosition ? c.r_pos : c.r_vel;
      A.block(6 * k, 6 * k, 6, 6) += h.transpose() * h / (r * r);
      b.segment(6 * k, 6) += h.transpose() * st.z / (r * r);
    }
  }
  Batch out;
  out.cov = A.inverse();
  out.mean = out.cov * b;
  return out;
}

LinearCase MakeCase(const std::string& name, int n, uint64_t seed, const std::function<bool(int)>& measure_pos,
                    const std::function<bool(int)>& measure_vel, const std::function<bool(int)>& mark) {
  LinearCase c;
  c.name = name;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Eigen::VectorXd truth(6);
  truth << 1, -2, 0.5, 3, 1, -0.2;
  for (int i = 0; i < n; ++i) {
    truth = Phi(c.dt) * truth;
    truth.tail<3>() += Eigen::Vector3d(g(rng), g(rng), g(rng)) * c.q_acc * std::sqrt(c.dt);
    c.steps.push_back({LinearStep::kPropagate, {}});
    if (measure_pos(i))
      c.steps.push_back({LinearStep::kMeasurePosition,
                         truth.head<3>() + Eigen::Vector3d(g(rng), g(rng), g(rng)) * c.r_pos});
    if (measure_vel(i))
      c.steps.push_back({LinearStep::kMeasureVelocity,
                         truth.tail<3>() + Eigen::Vector3d(g(rng), g(rng), g(rng)) * c.r_vel});
    if (mark(i)) c.steps.push_back({LinearStep::kMark, {}});
  }
  return c;
}

std::vector<LinearCase> CuratedCases() {
  const auto every = [](int k) { return [k](int i) { return i % k == 0; }; };
  const auto never = [](int) { return false; };
  return {
      MakeCase("position every step", 40, 1, every(1), never, every(1)),
      MakeCase("position every 5th, marks every step (epochs without updates)", 60, 2, every(5), never, every(1)),
      MakeCase("position and velocity in one epoch", 40, 3, every(3), every(3), every(2)),
      MakeCase("an outage: no measurement for 30 steps", 70, 4, [](int i) { return i < 20 || i >= 50; }, never,
               every(1)),
      MakeCase("several steps composed between epochs", 50, 5, every(4), every(7), every(4)),
      MakeCase("measurements only at the ends", 30, 6, [](int i) { return i == 0 || i == 29; }, never, every(3)),
  };
}

void ExpectEqualsBatch(const LinearCase& c, const std::vector<LinearStep>& steps, const LinearRun& run,
                       const std::vector<int64_t>& seqs, const Eigen::VectorXd& x0, const Eigen::MatrixXd& p0,
                       int state_offset) {
  const Batch batch = SolveBatch(c, steps, x0, p0);
  EpochStore store;
  for (const Epoch& e : run.epochs)
    if (std::find(seqs.begin(), seqs.end(), e.seq) != seqs.end()) store.Append(e);
  int checked = 0;
  store.SmoothBackward([&](const Epoch& e, const SmoothedError& s) {
    const auto it = run.state_of_epoch.find(e.seq);
    if (it == run.state_of_epoch.end()) return;
    const int k = it->second - state_offset;
    const Eigen::VectorXd smoothed = StateOf(e.x_post) + s.dx;
    EXPECT_LT((smoothed - batch.mean.segment(6 * k, 6)).cwiseAbs().maxCoeff(), kLinearTol)
        << c.name << ": mean of state " << k;
    EXPECT_LT((s.P - batch.cov.block(6 * k, 6 * k, 6, 6)).cwiseAbs().maxCoeff(), kLinearTol)
        << c.name << ": covariance of state " << k;
    ++checked;
  });
  EXPECT_GT(checked, 5) << c.name;
}

TEST(RtsSmoother, EqualsBatchLeastSquaresOnLinearGaussianModels) {
  for (const LinearCase& c : CuratedCases()) {
    const LinearRun run = RunLinearFilter(c);
    std::vector<int64_t> seqs;
    for (const Epoch& e : run.epochs) seqs.push_back(e.seq);
    ExpectEqualsBatch(c, c.steps, run, seqs, Eigen::VectorXd::Zero(6), P0(), 0);
  }
}

TEST(RtsSmoother, AChainBreakSmoothsEachPartOnItsOwn) {
  // A break (a reset) after 25 steps: the first part is the batch solution
  // of its own measurements, whatever came after.
  LinearCase c = MakeCase("break", 50, 7, [](int i) { return i % 2 == 0; }, [](int) { return false; },
                          [](int) { return true; });
  size_t cut = 0;
  int props = 0;
  for (; cut < c.steps.size(); ++cut) {
    if (c.steps[cut].kind == LinearStep::kPropagate && ++props == 26) break;
  }
  c.steps.insert(c.steps.begin() + static_cast<ptrdiff_t>(cut), LinearStep{LinearStep::kBreak, {}});
  const LinearRun run = RunLinearFilter(c);
  const std::vector<LinearStep> first(c.steps.begin(), c.steps.begin() + static_cast<ptrdiff_t>(cut));
  std::vector<int64_t> seqs;
  for (const Epoch& e : run.epochs) {
    if (!e.linked && e.seq > 0) break;
    seqs.push_back(e.seq);
  }
  ASSERT_LT(seqs.size(), run.epochs.size()) << "the break started a new chain";
  ExpectEqualsBatch(c, first, run, seqs, Eigen::VectorXd::Zero(6), P0(), 0);
  // And the whole drive smoothed at once gives the first part the same.
  EpochStore all, part;
  for (const Epoch& e : run.epochs) {
    all.Append(e);
    if (e.seq <= seqs.back()) part.Append(e);
  }
  std::map<int64_t, Eigen::VectorXd> from_part;
  part.SmoothBackward([&](const Epoch& e, const SmoothedError& s) { from_part[e.seq] = s.dx; });
  all.SmoothBackward([&](const Epoch& e, const SmoothedError& s) {
    if (from_part.count(e.seq)) {
      EXPECT_EQ(from_part[e.seq], s.dx) << "epoch " << e.seq;
    }
  });
}

TEST(EpochStore, SpillsToDiskWithoutChangingABit) {
  const LinearCase c = CuratedCases()[1];
  const LinearRun run = RunLinearFilter(c);
  EpochStore memory;
  EpochStore spilled({.memory_budget_bytes = 3 * EpochBytes(6)});
  for (const Epoch& e : run.epochs) {
    memory.Append(e);
    spilled.Append(e);
  }
  EXPECT_GT(spilled.bytes_spilled(), 0u);
  EXPECT_LE(spilled.bytes_in_memory(), 3 * EpochBytes(6));
  EXPECT_EQ(memory.bytes_spilled(), 0u);
  std::vector<Eigen::VectorXd> a, b;
  std::vector<Eigen::MatrixXd> pa, pb;
  memory.SmoothBackward([&](const Epoch&, const SmoothedError& s) { a.push_back(s.dx); pa.push_back(s.P); });
  spilled.SmoothBackward([&](const Epoch&, const SmoothedError& s) { b.push_back(s.dx); pb.push_back(s.P); });
  ASSERT_EQ(a.size(), run.epochs.size());
  EXPECT_EQ(a, b);
  EXPECT_EQ(pa, pb);
}

TEST(EpochStore, AnUnwritableSpillFolderIsAClearError) {
  const LinearRun run = RunLinearFilter(CuratedCases()[0]);
  EpochStore store({.memory_budget_bytes = 1, .spill_dir = "/nonexistent/locaid"});
  store.Append(run.epochs[0]);  // the first epoch always fits
  try {
    store.Append(run.epochs[1]);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot create a spill file in '/nonexistent/locaid'"), std::string::npos)
        << e.what();
  }
}

// ---------------------------------------------------------------- the EKF
// Feeds a simulated drive to the filter; `frame(e, pose)` after each frame's
// pose (the caller marks the epoch).
void FeedDrive(Ekf& ekf, const std::vector<test::SimEvent>& ev,
               const std::function<void(const test::SimEvent&, const FusedPose&)>& frame) {
  for (const auto& e : ev) {
    if (e.kind == test::SimEvent::kImu) {
      ekf.PropagateImu(e.imu);
    } else if (e.kind == test::SimEvent::kGps) {
      ekf.UpdateGps(e.gps);
    } else if (e.vo.t_ns != 0) {
      ekf.ProcessVo(e.vo, true);
      frame(e, ekf.Output(e.vo.t_ns, true));
    }
  }
}

struct SmoothedDrive {
  double rmse_forward = 0, rmse_smoothed = 0;        // horizontal, over initialised frames
  double outage_rmse_forward = 0, outage_rmse_smoothed = 0;
  double max_outage_forward = 0, max_outage_smoothed = 0;
  double nees_smoothed = 0;
  int frames = 0;
};

SmoothedDrive RunSmoothed(const test::SimConfig& c, bool use_imu) {
  const auto ev = test::Simulate(c);
  Ekf ekf(test::SimEkfConfig(c, use_imu));
  EpochStore store;
  EpochLog log([&](Epoch&& e) { store.Append(e); });
  ekf.set_epoch_log(&log);
  struct Frame { int64_t epoch; FusedPose pose; Vec3 truth; bool outage; };
  std::vector<Frame> frames;
  FeedDrive(ekf, ev, [&](const test::SimEvent& e, const FusedPose& pose) {
      const int64_t epoch = ekf.MarkEpoch();
      if (ekf.initialized()) frames.push_back({epoch, pose, test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m), e.in_outage});
  });
  log.Finish();
  std::map<int64_t, FusedPose> smoothed;
  std::map<int64_t, const FusedPose*> forward_of;
  for (const Frame& f : frames) forward_of[f.epoch] = &f.pose;
  store.SmoothBackward([&](const Epoch& e, const SmoothedError& s) {
    const auto it = forward_of.find(e.seq);
    if (it != forward_of.end()) smoothed[e.seq] = SmoothedPose(e, s, ekf.error_layout(), *it->second);
  });
  SmoothedDrive d;
  int outage_n = 0, nees_n = 0;
  for (const Frame& f : frames) {
    const FusedPose& sp = smoothed.at(f.epoch);
    EXPECT_TRUE(sp.smoothed);
    const Vec3 ef = f.pose.T_enu_body.translation() - f.truth, es = sp.T_enu_body.translation() - f.truth;
    d.rmse_forward += ef.head<2>().squaredNorm();
    d.rmse_smoothed += es.head<2>().squaredNorm();
    d.nees_smoothed += es.dot(sp.covariance.topLeftCorner<3, 3>().ldlt().solve(es));
    ++nees_n;
    if (f.outage) {
      d.outage_rmse_forward += ef.head<2>().squaredNorm();
      d.outage_rmse_smoothed += es.head<2>().squaredNorm();
      d.max_outage_forward = std::max(d.max_outage_forward, ef.head<2>().norm());
      d.max_outage_smoothed = std::max(d.max_outage_smoothed, es.head<2>().norm());
      ++outage_n;
    }
    ++d.frames;
  }
  d.rmse_forward = std::sqrt(d.rmse_forward / d.frames);
  d.rmse_smoothed = std::sqrt(d.rmse_smoothed / d.frames);
  d.outage_rmse_forward = std::sqrt(d.outage_rmse_forward / std::max(1, outage_n));
  d.outage_rmse_smoothed = std::sqrt(d.outage_rmse_smoothed / std::max(1, outage_n));
  d.nees_smoothed /= std::max(1, nees_n);
  return d;
}

void ExpectSmoothedBetter(bool use_imu) {
  // 6 seeds, 90 s, a 20 s outage in the middle; 1 Hz GPS of 3 m.
  constexpr int kSeeds = 6;
  double f = 0, s = 0, fo = 0, so = 0, nees = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    test::SimConfig c;
    c.duration_s = 90;
    c.seed = 300 + static_cast<uint64_t>(seed);
    c.outage_start_s = 40;
    c.outage_duration_s = 20;
    const SmoothedDrive d = RunSmoothed(c, use_imu);
    ASSERT_GT(d.frames, 500);
    std::cout << (use_imu ? "IMU" : "no IMU") << " seed " << c.seed << ": rmse " << d.rmse_forward << " -> "
              << d.rmse_smoothed << " m, outage rmse " << d.outage_rmse_forward << " -> " << d.outage_rmse_smoothed
              << " m, outage max " << d.max_outage_forward << " -> " << d.max_outage_smoothed << " m, NEES "
              << d.nees_smoothed << "\n";
    f += d.rmse_forward;
    s += d.rmse_smoothed;
    fo += d.outage_rmse_forward;
    so += d.outage_rmse_smoothed;
    nees += d.nees_smoothed;
  }
  EXPECT_LT(s, f) << "smoothed RMSE over the drive, summed over seeds";
  EXPECT_LT(so, fo) << "smoothed RMSE in the outage, summed over seeds";
  // Mean 3-dof NEES over seeds: a consistent smoother sits near 3; frames
  // are strongly correlated, so the bounds are wide (a factor 3 either way).
  nees /= kSeeds;
  EXPECT_GT(nees, 1.0) << "smoother over-pessimistic";
  EXPECT_LT(nees, 9.0) << "smoother over-confident";
}

TEST(RtsSmootherEkf, NeverWorseThanTheFilterOnAverageWithImu) { ExpectSmoothedBetter(true); }
TEST(RtsSmootherEkf, NeverWorseThanTheFilterOnAverageWithoutImu) { ExpectSmoothedBetter(false); }

TEST(RtsSmootherEkf, APositionResetMidDriveBreaksTheChainAndLosesNothing) {
  // From 50 s on every fix is 40 m east of the truth: the gate refuses
  // them, then the filter resets its position to GPS. The smoother must
  // treat the reset as a break: the drive before it smoothed on its own.
  test::SimConfig c;
  c.duration_s = 80;
  c.seed = 321;
  auto ev = test::Simulate(c);
  for (auto& e : ev)
    if (e.kind == test::SimEvent::kGps && e.gps.t_ns > static_cast<int64_t>(50e9))
      e.gps.lon_deg += 40.0 / (111320.0 * std::cos(test::kLat0 * M_PI / 180));
  Ekf ekf(test::SimEkfConfig(c, true));
  OfflineSmoother smoother;
  ekf.set_epoch_log(&smoother.log());
  std::vector<FusedPose> forward;
  std::vector<int64_t> epochs;
  std::vector<Vec3> truth;
  FeedDrive(ekf, ev, [&](const test::SimEvent& e, const FusedPose& pose) {
      forward.push_back(pose);
      epochs.push_back(ekf.MarkEpoch());
      truth.push_back(test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m));
  });
  ASSERT_GT(ekf.stats().gps_resets, 0) << "the jump must make the filter reset";
  const std::vector<FusedPose> smoothed = smoother.Smooth(forward, epochs, ekf.error_layout());
  ASSERT_EQ(smoothed.size(), forward.size());
  double f2 = 0, s2 = 0;
  int n = 0;
  for (size_t i = 0; i < smoothed.size(); ++i) {
    ASSERT_TRUE(smoothed[i].T_enu_body.matrix().allFinite()) << i;
    ASSERT_TRUE(smoothed[i].covariance.allFinite()) << i;
    if (epochs[i] < 0 || forward[i].t_ns > static_cast<int64_t>(45e9)) continue;
    f2 += (forward[i].T_enu_body.translation() - truth[i]).head<2>().squaredNorm();
    s2 += (smoothed[i].T_enu_body.translation() - truth[i]).head<2>().squaredNorm();
    ++n;
  }
  ASSERT_GT(n, 200);
  std::cout << "before the jump: RMSE forward " << std::sqrt(f2 / n) << " m, smoothed " << std::sqrt(s2 / n) << " m\n";
  EXPECT_LT(s2, f2) << "the drive before the reset is smoothed, not pulled 40 m by the fixes after it";
}

// ---------------------------------------------------------------- fixed lag
// One simulated drive filtered with a fixed-lag smoother of `lag_s`: the
// poses it releases (in order), and per release how far the filter was.
struct LagRun {
  std::vector<FusedPose> forward, released;
  std::vector<double> delay_s;  // newest forward time minus the released pose's time
  std::vector<Vec3> truth;      // per forward pose, in the filter's ENU
};
LagRun RunWithLag(const test::SimConfig& c, double lag_s) {
  const auto ev = test::Simulate(c);
  Ekf ekf(test::SimEkfConfig(c, true));
  FixedLagSmoother lag(lag_s, ekf.error_layout());
  EpochLog log([&](Epoch&& e) { lag.AddEpoch(e); });
  ekf.set_epoch_log(&log);
  LagRun run;
  FeedDrive(ekf, ev, [&](const test::SimEvent& e, const FusedPose& pose) {
      run.forward.push_back(pose);
      run.truth.push_back(test::TruthInFilterEnu(ekf, e.truth.x.p_enu_m));
      for (FusedPose& p : lag.AddPose(pose, ekf.MarkEpoch(), log.open())) {
        run.delay_s.push_back(static_cast<double>(pose.t_ns - p.t_ns) * 1e-9);
        run.released.push_back(std::move(p));
      }
  });
  for (FusedPose& p : lag.Flush(log.open())) run.released.push_back(std::move(p));
  return run;
}

std::vector<FusedPose> RunOffline(const test::SimConfig& c) {
  const auto ev = test::Simulate(c);
  Ekf ekf(test::SimEkfConfig(c, true));
  OfflineSmoother smoother;
  ekf.set_epoch_log(&smoother.log());
  std::vector<FusedPose> forward;
  std::vector<int64_t> epochs;
  FeedDrive(ekf, ev, [&](const test::SimEvent& e, const FusedPose& pose) {
      forward.push_back(pose);
      epochs.push_back(ekf.MarkEpoch());
  });
  return smoother.Smooth(forward, epochs, ekf.error_layout());
}

test::SimConfig LagDrive() {
  test::SimConfig c;
  c.duration_s = 60;
  c.seed = 410;
  c.outage_start_s = 25;
  c.outage_duration_s = 15;
  return c;
}

TEST(FixedLagSmoother, ALagLongerThanTheDriveGivesTheOfflineSmoothersPoses) {
  const LagRun lag = RunWithLag(LagDrive(), 1000.0);
  const std::vector<FusedPose> offline = RunOffline(LagDrive());
  ASSERT_EQ(lag.released.size(), offline.size());
  EXPECT_TRUE(lag.delay_s.empty()) << "nothing comes out before the drive ends";
  for (size_t i = 0; i < offline.size(); ++i) {
    ASSERT_EQ(lag.released[i].t_ns, offline[i].t_ns) << i;
    EXPECT_EQ(lag.released[i].T_enu_body.matrix(), offline[i].T_enu_body.matrix()) << "pose " << i;
    EXPECT_EQ(lag.released[i].covariance, offline[i].covariance) << "pose " << i;
  }
}

TEST(FixedLagSmoother, EachPoseComesOutOnceItsLagHasPassedInOrder) {
  const LagRun run = RunWithLag(LagDrive(), 2.0);
  ASSERT_EQ(run.released.size(), run.forward.size()) << "every pose comes out, the last ones at Flush";
  for (size_t i = 0; i < run.released.size(); ++i) {
    EXPECT_EQ(run.released[i].t_ns, run.forward[i].t_ns) << "in order";
    EXPECT_TRUE(run.released[i].smoothed);
  }
  for (double d : run.delay_s) {
    EXPECT_GE(d, 2.0 - 1e-9);
    EXPECT_LT(d, 2.0 + 0.1 + 1e-9) << "out at the first pose past the lag (10 Hz frames)";
  }
  // A 2 s lag already beats the filter over the drive.
  const auto rmse = [&](const std::vector<FusedPose>& poses) {
    double sum2 = 0;
    int n = 0;
    for (size_t i = 0; i < poses.size(); ++i) {
      if (poses[i].mode == Mode::kLost) continue;
      sum2 += (poses[i].T_enu_body.translation() - run.truth[i]).head<2>().squaredNorm();
      ++n;
    }
    return std::sqrt(sum2 / std::max(1, n));
  };
  std::cout << "RMSE forward " << rmse(run.forward) << " m, 2 s lag " << rmse(run.released) << " m\n";
  EXPECT_LT(rmse(run.released), rmse(run.forward));
}

TEST(FixedLagSmoother, RefusesALagThatIsNotPositive) {
  for (double bad : {0.0, -1.0, std::nan("")}) {
    try {
      FixedLagSmoother s(bad, ErrorLayout{6, 3, -1});
      FAIL() << "accepted " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("lag must be > 0 s"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace locaid::fusion
