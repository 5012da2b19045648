// Numerical health of the EKF under the worst inputs it can meet (issue 7):
// long GPS outages with VO loss, bursts of rejected GPS jumps (long enough to
// hit the forced-acceptance path), intermittent GPS, a MEMS-grade IMU fed to
// the default (RT3003-tuned) filter, very noisy and very precise GPS. After
// EVERY event (IMU sample, fix, frame) the covariance must be finite,
// symmetric (relative asymmetry < kMaxRelAsymmetry after the filter's own
// symmetrisation), its navigation block positive definite (LLT succeeds and
// the smallest eigenvalue is > 0), the full matrix (with the VO clone, which
// is an exact copy right after cloning) positive semi-definite, and every
// output (pose, velocity, covariance, lat/lon/alt) finite.
//
// Bad numbers (NaN/Inf in a GPS fix, a VO measurement or an IMU sample) must
// be refused (std::invalid_argument naming the field) or ignored/counted,
// never absorbed into the state.
#include "fusion/ekf.hpp"
#include "sim/scenario.hpp"
#include "sim.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace locaid::fusion {
namespace {

using test::SimConfig;
using test::SimEvent;
using test::Simulate;

constexpr double kMaxRelAsymmetry = 1e-9;
constexpr double kMaxRelNegativeEigen = 1e-9;   // full matrix: PSD up to round-off
constexpr double kMaxRotationOrthoError = 1e-6;  // |R^T R - I|
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Collects the first failure (with its time and what was fed) and the extremes.
class HealthMonitor {
 public:
  explicit HealthMonitor(std::string name) : name_(std::move(name)) {}

  void Check(const Ekf& ekf, const FusedPose& pose, int64_t t_ns, const char* after) {
    ++checks_;
    const std::string at = name_ + " t=" + std::to_string(static_cast<double>(t_ns) * 1e-9) + " s after " + after;
    if (!pose.T_enu_body.matrix().allFinite() || !pose.v_enu_mps.allFinite() || !pose.covariance.allFinite() ||
        !std::isfinite(pose.lat_deg) || !std::isfinite(pose.lon_deg) || !std::isfinite(pose.alt_m) ||
        std::isnan(pose.seconds_since_gps)) {
      Fail(at + ": non-finite output");
    }
    if (!ekf.initialized()) return;
    const NominalState& x = ekf.state();
    if (!x.p_enu_m.allFinite() || !x.v_enu_mps.allFinite() || !x.R_enu_body.allFinite() ||
        !x.accel_bias_mps2.allFinite() || !x.gyro_bias_radps.allFinite()) {
      Fail(at + ": non-finite state");
      return;
    }
    const double ortho = (x.R_enu_body.transpose() * x.R_enu_body - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (ortho > kMaxRotationOrthoError) Fail(at + ": R_enu_body not orthonormal (" + std::to_string(ortho) + ")");
    const Eigen::MatrixXd& P = ekf.covariance();
    if (!P.allFinite()) {
      Fail(at + ": non-finite covariance");
      return;
    }
    const double scale = P.cwiseAbs().maxCoeff();
    const double asym = (P - P.transpose()).cwiseAbs().maxCoeff() / scale;
    worst_asym_ = std::max(worst_asym_, asym);
    if (!(asym < kMaxRelAsymmetry)) Fail(at + ": relative asymmetry " + std::to_string(asym));
    const int nav = P.rows() > kPoseStates ? kImuStates : kPoseStates;
    const Eigen::MatrixXd Pn = P.topLeftCorner(nav, nav);
    if (Eigen::LLT<Eigen::MatrixXd>(Pn).info() != Eigen::Success) Fail(at + ": navigation block not PD (LLT)");
    const double nav_min = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Pn, Eigen::EigenvaluesOnly)
                               .eigenvalues()
                               .minCoeff();
    min_nav_eig_ = std::min(min_nav_eig_, nav_min);
    if (!(nav_min > 0)) Fail(at + ": navigation block min eigenvalue " + std::to_string(nav_min));
    const Eigen::VectorXd ev =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P, Eigen::EigenvaluesOnly).eigenvalues();
    if (ev.minCoeff() < -kMaxRelNegativeEigen * ev.maxCoeff()) {
      Fail(at + ": full covariance min eigenvalue " + std::to_string(ev.minCoeff()));
    }
    max_pos_sigma_ = std::max(max_pos_sigma_, std::sqrt(P.topLeftCorner<3, 3>().trace()));
  }

  void Report() const {
    std::printf("[health] %-34s checks %7ld  worst rel asym %.2e  min nav eig %.2e  max pos sigma %.1f m\n",
                name_.c_str(), checks_, worst_asym_, min_nav_eig_, max_pos_sigma_);
  }
  bool ok() const { return first_failure_.empty(); }
  const std::string& first_failure() const { return first_failure_; }
  long checks() const { return checks_; }

 private:
  void Fail(const std::string& what) {
    if (first_failure_.empty()) first_failure_ = what;
  }
  std::string name_;
  std::string first_failure_;
  long checks_ = 0;
  double worst_asym_ = 0, min_nav_eig_ = kInf, max_pos_sigma_ = 0;
};

// What is done to the simulated sensors on top of SimConfig.
struct Torture {
  // GPS jumps: every `jump_every_s` a burst of `jump_burst_fixes` consecutive
  // fixes displaced by `jump_m` (random direction).
  double jump_every_s = 0, jump_m = 0;
  int jump_burst_fixes = 0;
  // Intermittent GPS: no fix while fmod(t, period) < off.
  double gps_off_period_s = 0, gps_off_s = 0;
  // VO lost (vo_ok = false) in [vo_lost_start_s, vo_lost_start_s + vo_lost_s).
  double vo_lost_start_s = -1, vo_lost_s = 0;
  bool mems_imu = false;
};

struct RunResult {
  int gps_fed = 0, jump_fixes = 0, frames = 0, vo_lost_frames = 0;
  bool initialized = false;
  std::vector<std::pair<double, double>> pos_sigma_by_time;  // (t_s, sigma_h) per frame
};

RunResult Drive(Ekf& ekf, const std::vector<SimEvent>& events, const Torture& t, HealthMonitor& health,
                uint64_t seed) {
  RunResult r;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(0, 2 * M_PI);
  sim::Scenario mems;
  mems.imu_grade = sim::ImuGrade::kMems;
  mems.imu_accel_bias_sigma_mps2 = 0.2;       // poor consumer MEMS
  mems.imu_gyro_bias_sigma_radps = 0.005;     // ~0.3 deg/s
  mems.imu_accel_noise_mps2_sqrt_hz = 0.05;
  mems.imu_gyro_noise_radps_sqrt_hz = 0.003;
  mems.seed = seed;
  sim::ImuDegrader degrader(mems);
  int burst_left = 0;
  double next_burst_s = t.jump_every_s;
  Eigen::Vector2d jump = Eigen::Vector2d::Zero();
  EnuFrame local;
  for (const SimEvent& e : events) {
    const double ts = static_cast<double>(e.truth.t_ns) * 1e-9;
    if (e.kind == SimEvent::kImu) {
      ekf.PropagateImu(t.mems_imu ? degrader.Apply(e.imu) : e.imu);
      health.Check(ekf, ekf.Output(e.imu.t_ns, true), e.imu.t_ns, "imu");
    } else if (e.kind == SimEvent::kGps) {
      if (t.gps_off_period_s > 0 && std::fmod(ts, t.gps_off_period_s) < t.gps_off_s) continue;
      GpsFix fix = e.gps;
      if (t.jump_every_s > 0 && ekf.initialized() && ts >= next_burst_s && burst_left == 0) {
        burst_left = t.jump_burst_fixes;
        next_burst_s += t.jump_every_s;
        const double a = angle(rng);
        jump = t.jump_m * Eigen::Vector2d(std::cos(a), std::sin(a));
      }
      if (burst_left > 0) {
        --burst_left;
        ++r.jump_fixes;
        local.SetOrigin(fix.lat_deg, fix.lon_deg, fix.alt_m);
        local.ToGeodetic(Vec3(jump.x(), jump.y(), 0), fix.lat_deg, fix.lon_deg, fix.alt_m);
      }
      ekf.UpdateGps(fix);
      ++r.gps_fed;
      health.Check(ekf, ekf.Output(fix.t_ns, true), fix.t_ns, "gps");
    } else if (e.vo.t_ns > 0) {
      const bool vo_ok = !(t.vo_lost_start_s >= 0 && ts >= t.vo_lost_start_s && ts < t.vo_lost_start_s + t.vo_lost_s);
      ekf.ProcessVo(e.vo, vo_ok);
      ++r.frames;
      r.vo_lost_frames += vo_ok ? 0 : 1;
      const FusedPose pose = ekf.Output(e.vo.t_ns, vo_ok);
      health.Check(ekf, pose, e.vo.t_ns, vo_ok ? "frame" : "frame (VO lost)");
      if (ekf.initialized()) {
        r.pos_sigma_by_time.emplace_back(ts, std::sqrt(pose.covariance(0, 0) + pose.covariance(1, 1)));
      }
    }
  }
  r.initialized = ekf.initialized();
  return r;
}

double SigmaAt(const RunResult& r, double t_s) {
  for (const auto& [t, s] : r.pos_sigma_by_time)
    if (t >= t_s) return s;
  return kNaN;
}

struct Case {
  const char* name;
  SimConfig sim;
  Torture torture;
};

std::vector<Case> WorstCases() {
  std::vector<Case> cases;
  {  // 150 s outage (10 Hz / 1.5 m GPS around it) with 10 s of VO loss inside.
    Case c{"outage-150s+vo-lost-10s", {}, {}};
    c.sim.duration_s = 260;
    c.sim.gps_rate_hz = 10;
    c.sim.gps_sigma_h_m = 1.5;
    c.sim.outage_start_s = 60;
    c.sim.outage_duration_s = 150;
    c.sim.seed = 71;
    c.torture.vo_lost_start_s = 150;
    c.torture.vo_lost_s = 10;
    cases.push_back(c);
  }
  {  // Bursts of 12 fixes 40 m off (more than gps_reset_after_rejections:
     // the reset-to-GPS path runs too, and the reset back when they end).
    Case c{"jump-bursts-12x40m", {}, {}};
    c.sim.duration_s = 150;
    c.sim.gps_rate_hz = 5;
    c.sim.seed = 72;
    c.torture.jump_every_s = 15;
    c.torture.jump_m = 40;
    c.torture.jump_burst_fixes = 12;
    cases.push_back(c);
  }
  {  // Intermittent 1 Hz GPS (7 s off every 12 s), MEMS IMU, 10 m noise.
    Case c{"intermittent+mems+10m-noise", {}, {}};
    c.sim.duration_s = 200;
    c.sim.gps_rate_hz = 1;
    c.sim.gps_sigma_h_m = 10;
    c.sim.gps_sigma_v_m = 15;
    c.sim.vo_sigma_t_m = 0.05;
    c.sim.vo_sigma_rot_rad = 0.002;
    c.sim.seed = 73;
    c.torture.gps_off_period_s = 12;
    c.torture.gps_off_s = 7;
    c.torture.mems_imu = true;
    cases.push_back(c);
  }
  {  // Very precise 10 Hz GPS (2 cm): tiny variances, ill-conditioned P.
    Case c{"precise-gps-2cm", {}, {}};
    c.sim.duration_s = 90;
    c.sim.gps_rate_hz = 10;
    c.sim.gps_sigma_h_m = 0.02;
    c.sim.gps_sigma_v_m = 0.03;
    c.sim.seed = 74;
    cases.push_back(c);
  }
  {  // Everything at once: MEMS, 130 s outage, jump bursts, 5 s VO loss.
    Case c{"mems+outage-130s+jumps", {}, {}};
    c.sim.duration_s = 240;
    c.sim.gps_rate_hz = 2;
    c.sim.gps_sigma_h_m = 4;
    c.sim.outage_start_s = 70;
    c.sim.outage_duration_s = 130;
    c.sim.seed = 75;
    c.torture.jump_every_s = 25;
    c.torture.jump_m = 60;
    c.torture.jump_burst_fixes = 10;
    c.torture.vo_lost_start_s = 120;
    c.torture.vo_lost_s = 5;
    c.torture.mems_imu = true;
    cases.push_back(c);
  }
  return cases;
}

class EkfNumericalHealth : public ::testing::TestWithParam<bool> {};

TEST_P(EkfNumericalHealth, CovarianceStaysSymmetricPositiveDefiniteAndOutputsFiniteInTheWorstScenarios) {
  const bool use_imu = GetParam();
  for (const Case& c : WorstCases()) {
    SCOPED_TRACE(c.name);
    const auto events = Simulate(c.sim);
    EkfConfig config;  // production defaults: the filter does not know the data is bad
    config.imu.enabled = use_imu;
    Ekf ekf(config);
    HealthMonitor health(std::string(use_imu ? "imu/" : "no-imu/") + c.name);
    const RunResult r = Drive(ekf, events, c.torture, health, c.sim.seed);
    health.Report();
    std::printf("[health] %-34s fixes fed %d (jumped %d): used %d, rejected %d; frames %d (VO lost %d)\n", c.name,
                r.gps_fed, r.jump_fixes, ekf.stats().gps_used, ekf.stats().gps_rejected, r.frames, r.vo_lost_frames);
    ASSERT_TRUE(r.initialized);
    EXPECT_TRUE(health.ok()) << health.first_failure();
    EXPECT_GT(health.checks(), r.frames);
    if (c.torture.jump_burst_fixes > 0) {
      EXPECT_GT(r.jump_fixes, 0);
      EXPECT_GT(ekf.stats().gps_rejected, 0) << "jump bursts were never rejected";
    }
    if (c.torture.vo_lost_s > 0) {
      EXPECT_GT(r.vo_lost_frames, 0);
    }
    if (c.sim.outage_duration_s > 0 && c.torture.jump_burst_fixes == 0) {
      // (With jump bursts a forced acceptance may inflate P right after the outage.)
      // The outage grows the uncertainty and GPS afterwards brings it back:
      // the filter neither froze nor diverged.
      const double before = SigmaAt(r, c.sim.outage_start_s - 1);
      const double end = SigmaAt(r, c.sim.outage_start_s + c.sim.outage_duration_s - 0.5);
      const double after = SigmaAt(r, c.sim.outage_start_s + c.sim.outage_duration_s + 20);
      std::printf("[health] %-34s pos sigma before/end/after outage %.2f / %.2f / %.2f m\n", c.name, before, end,
                  after);
      EXPECT_GT(end, 2 * before);
      EXPECT_LT(after, 0.5 * end);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(ImuAndNoImu, EkfNumericalHealth, ::testing::Values(true, false),
                         [](const auto& info) { return info.param ? std::string("Imu") : std::string("NoImu"); });

// ------------------------------------------------------------- bad numbers

// Runs `feed`; the filter may refuse the input with std::invalid_argument
// whose message names `field`. Any other exception fails the test. Returns
// whether it threw.
bool FeedBad(const std::function<void()>& feed, const std::string& field) {
  try {
    feed();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos)
        << "error does not name '" << field << "': " << e.what();
    return true;
  }
  return false;
}

// Runs the first `until_s` seconds of a plain drive. Returns the index of the
// next event and the time of the last frame.
struct Partial {
  size_t next = 0;
  int64_t last_frame_ns = 0;
};
// One simulated event into the filter, as the pipeline feeds it.
void FeedEvent(Ekf& ekf, const SimEvent& e) {
  if (e.kind == SimEvent::kImu) ekf.PropagateImu(e.imu);
  else if (e.kind == SimEvent::kGps) ekf.UpdateGps(e.gps);
  else if (e.vo.t_ns > 0) ekf.ProcessVo(e.vo, true);
}

Partial RunUntil(Ekf& ekf, const std::vector<SimEvent>& ev, double until_s) {
  Partial p;
  for (; p.next < ev.size(); ++p.next) {
    const SimEvent& e = ev[p.next];
    if (static_cast<double>(e.truth.t_ns) * 1e-9 > until_s) break;
    FeedEvent(ekf, e);
    if (e.kind == SimEvent::kFrame && e.vo.t_ns > 0) p.last_frame_ns = e.vo.t_ns;
  }
  return p;
}

// Feeds events from *next on until the next one of `kind` (left unfed).
void FeedUntil(Ekf& ekf, const std::vector<SimEvent>& ev, size_t* next, SimEvent::Kind kind) {
  while (*next < ev.size() && ev[*next].kind != kind) FeedEvent(ekf, ev[(*next)++]);
}

Ekf EkfFor(bool use_imu) {
  EkfConfig config;
  config.imu.enabled = use_imu;
  return Ekf(config);
}

void ExpectFiniteFilter(const Ekf& ekf) {
  EXPECT_TRUE(ekf.state().p_enu_m.allFinite() && ekf.state().v_enu_mps.allFinite() &&
              ekf.state().R_enu_body.allFinite())
      << "NaN/Inf absorbed into the state";
  EXPECT_TRUE(ekf.covariance().allFinite()) << "NaN/Inf absorbed into the covariance";
}

// The rest of the drive must stay healthy and end GPS_FUSED near the truth.
void FinishHealthy(Ekf& ekf, const std::vector<SimEvent>& ev, size_t from, const std::string& name) {
  constexpr double kMaxFinalErrorM = 5.0;
  HealthMonitor health(name);
  Torture none;
  const std::vector<SimEvent> rest(ev.begin() + static_cast<std::ptrdiff_t>(from), ev.end());
  Drive(ekf, rest, none, health, 1);
  EXPECT_TRUE(health.ok()) << health.first_failure();
  ASSERT_TRUE(ekf.initialized());
  const Vec3 gt = test::TruthInFilterEnu(ekf, ev.back().truth.x.p_enu_m);
  EXPECT_LT((ekf.state().p_enu_m - gt).head<2>().norm(), kMaxFinalErrorM) << name;
}

SimConfig ShortDrive(uint64_t seed) {
  SimConfig c;
  c.duration_s = 60;
  c.gps_rate_hz = 5;
  c.seed = seed;
  return c;
}

class EkfBadNumbers : public ::testing::TestWithParam<bool> {};

TEST_P(EkfBadNumbers, NonFiniteGpsFixIsRejectedAndCountedNotAbsorbed) {
  const bool use_imu = GetParam();
  const auto ev = Simulate(ShortDrive(81));
  struct Bad {
    const char* name;
    const char* field;
    std::function<void(GpsFix&)> spoil;
  };
  const std::vector<Bad> bads = {
      {"nan-lat", "lat_deg", [](GpsFix& f) { f.lat_deg = kNaN; }},
      {"inf-lon", "lon_deg", [](GpsFix& f) { f.lon_deg = kInf; }},
      {"inf-alt", "alt_m", [](GpsFix& f) { f.alt_m = -kInf; }},
      {"nan-sigma-h", "sigma_h_m", [](GpsFix& f) { f.sigma_h_m = kNaN; }},
      {"inf-sigma-h", "sigma_h_m", [](GpsFix& f) { f.sigma_h_m = kInf; }},
      {"nan-sigma-v", "sigma_v_m", [](GpsFix& f) { f.sigma_v_m = kNaN; }},
      {"inf-sigma-v", "sigma_v_m", [](GpsFix& f) { f.sigma_v_m = kInf; }},
  };
  for (const Bad& b : bads) {
    SCOPED_TRACE(b.name);
    Ekf ekf = EkfFor(use_imu);
    const Partial p = RunUntil(ekf, ev, 30);
    ASSERT_TRUE(ekf.initialized());
    // A valid fix at the state time (no propagation happens) with one bad field.
    GpsFix fix;
    fix.t_ns = p.last_frame_ns;
    ekf.enu().ToGeodetic(ekf.state().p_enu_m, fix.lat_deg, fix.lon_deg, fix.alt_m);
    b.spoil(fix);
    const Vec3 p_before = ekf.state().p_enu_m;
    const Eigen::MatrixXd P_before = ekf.covariance();
    const int rejected_before = ekf.stats().gps_rejected, used_before = ekf.stats().gps_used;
    GpsUpdate update;
    const bool threw = FeedBad([&] { update = ekf.UpdateGps(fix); }, b.field);
    if (!threw) {
      EXPECT_FALSE(update.used);
      EXPECT_TRUE(update.rejected);
      EXPECT_EQ(ekf.stats().gps_rejected, rejected_before + 1) << "a refused fix must be counted";
    }
    EXPECT_EQ(ekf.stats().gps_used, used_before);
    EXPECT_TRUE(ekf.state().p_enu_m == p_before) << "position moved: " << ekf.state().p_enu_m.transpose();
    EXPECT_TRUE(ekf.covariance().allFinite()) << "NaN/Inf absorbed into the covariance";
    EXPECT_TRUE(ekf.covariance() == P_before) << "covariance changed by a refused fix";
    FinishHealthy(ekf, ev, p.next, std::string(use_imu ? "imu/" : "no-imu/") + "gps-" + b.name);
  }
}

TEST_P(EkfBadNumbers, NonFiniteFirstFixDoesNotPoisonTheEnuOrigin) {
  // The ENU origin is taken from the first fix the filter sees: a NaN there
  // would make every later fix and output NaN.
  const bool use_imu = GetParam();
  const auto ev = Simulate(ShortDrive(82));
  Ekf ekf = EkfFor(use_imu);
  GpsFix bad;
  bad.t_ns = 0;
  bad.lat_deg = kNaN;
  bad.lon_deg = 8.4;
  bad.alt_m = 110;
  GpsUpdate update;
  FeedBad([&] { update = ekf.UpdateGps(bad); }, "lat_deg");
  EXPECT_FALSE(update.used);
  EXPECT_TRUE(update.rejected);
  FinishHealthy(ekf, ev, 0, use_imu ? "imu/nan-first-fix" : "no-imu/nan-first-fix");
  EXPECT_TRUE(std::isfinite(ekf.enu().origin_lat_deg()));
  EXPECT_NEAR(ekf.enu().origin_lat_deg(), test::kLat0, 1e-3);
}

TEST_P(EkfBadNumbers, NonFiniteVoMeasurementIsNotAbsorbed) {
  const bool use_imu = GetParam();
  const auto ev = Simulate(ShortDrive(83));
  struct Bad {
    const char* name;
    const char* field;
    std::function<void(VoMeasurement&)> spoil;
  };
  const std::vector<Bad> bads = {
      {"nan-covariance", "covariance", [](VoMeasurement& m) { m.covariance(2, 2) = kNaN; }},
      {"inf-covariance", "covariance", [](VoMeasurement& m) { m.covariance(4, 4) = kInf; }},
      {"nan-translation", "T_prev_curr", [](VoMeasurement& m) { m.T_prev_curr.translation().x() = kNaN; }},
      {"inf-rotation", "T_prev_curr", [](VoMeasurement& m) { m.T_prev_curr.linear()(0, 1) = kInf; }},
  };
  for (const Bad& b : bads) {
    SCOPED_TRACE(b.name);
    Ekf ekf = EkfFor(use_imu);
    Partial p = RunUntil(ekf, ev, 30);
    ASSERT_TRUE(ekf.initialized());
    // Replace the next frame's measurement by a spoiled copy.
    FeedUntil(ekf, ev, &p.next, SimEvent::kFrame);
    ASSERT_LT(p.next, ev.size());
    VoMeasurement m = ev[p.next++].vo;
    b.spoil(m);
    const int vo_rejected_before = ekf.stats().vo_rejected;
    const bool threw = FeedBad([&] { ekf.ProcessVo(m, true); }, b.field);
    ExpectFiniteFilter(ekf);
    const FusedPose out = ekf.Output(m.t_ns, true);
    EXPECT_TRUE(out.T_enu_body.matrix().allFinite() && out.covariance.allFinite() && std::isfinite(out.lat_deg));
    if (use_imu && !threw) {
      EXPECT_EQ(ekf.stats().vo_rejected, vo_rejected_before + 1) << "refused VO must be counted";
    }
    FinishHealthy(ekf, ev, p.next, std::string(use_imu ? "imu/" : "no-imu/") + b.name);
  }
}

TEST_P(EkfBadNumbers, NonFiniteImuSampleIsNotAbsorbed) {
  const bool use_imu = GetParam();
  const auto ev = Simulate(ShortDrive(84));
  struct Bad {
    const char* name;
    const char* field;
    std::function<void(ImuSample&)> spoil;
  };
  const std::vector<Bad> bads = {
      {"inf-accel", "accel_mps2", [](ImuSample& s) { s.accel_mps2.z() = kInf; }},
      {"nan-gyro", "gyro_radps", [](ImuSample& s) { s.gyro_radps.x() = kNaN; }},
  };
  for (const Bad& b : bads) {
    SCOPED_TRACE(b.name);
    Ekf ekf = EkfFor(use_imu);
    Partial p = RunUntil(ekf, ev, 30);
    ASSERT_TRUE(ekf.initialized());
    FeedUntil(ekf, ev, &p.next, SimEvent::kImu);
    ASSERT_LT(p.next, ev.size());
    ImuSample s = ev[p.next++].imu;
    b.spoil(s);
    FeedBad([&] { ekf.PropagateImu(s); }, b.field);
    // The next good sample propagates over the interval the bad one opened.
    FeedUntil(ekf, ev, &p.next, SimEvent::kImu);
    ASSERT_LT(p.next, ev.size());
    ekf.PropagateImu(ev[p.next++].imu);
    ExpectFiniteFilter(ekf);
    FinishHealthy(ekf, ev, p.next, std::string(use_imu ? "imu/" : "no-imu/") + b.name);
  }
}

INSTANTIATE_TEST_SUITE_P(ImuAndNoImu, EkfBadNumbers, ::testing::Values(true, false),
                         [](const auto& info) { return info.param ? std::string("Imu") : std::string("NoImu"); });

}  // namespace
}  // namespace locaid::fusion
