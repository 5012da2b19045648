// Route mode of the synthetic drive (synth/route_file.hpp, SynthConfig::
// route_poses): a drive along a KITTI odometry ground-truth poses file. The
// OXTS follow the poses within centimetres, are the derivatives of the ground
// truth, a stop holds still while time passes, bad files are refused before
// anything is written, and a route that drives a place again draws it once.
#include "error_of.hpp"
#include "kitti/oxts.hpp"
#include "kitti/oxts_pose.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/timestamps.hpp"
#include "synth/motion.hpp"
#include "synth/route_file.hpp"
#include "synth/spline.hpp"
#include "synth/synth.hpp"
#include "synth/texture.hpp"
#include "synth/world.hpp"
#include "temp_dir.hpp"

#include <GeographicLib/LocalCartesian.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace fs = std::filesystem;
namespace synth = locaid::synth;
namespace kitti = locaid::kitti;
using locaid::test_support::ErrorOf;
using locaid::test_support::ScopedTempDir;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kGravity = 9.81;
// Heights of route mode: the road 1.65 m below the KITTI camera, the IMU 0.93 m above the road.
constexpr double kImuBelowCameraM = 1.65 - 0.93;

// A planar path with a height profile, driven on a speed profile, sampled as
// KITTI odometry poses (world = cam0 at frame 0: x right, y down, z forward).
struct HandMadeRoute {
  std::vector<double> t;
  std::vector<Eigen::Isometry3d> T_world_cam0;
};

// Writes poses (%e like KITTI's files) and times; returns the poses file.
void WriteRoute(const HandMadeRoute& r, const fs::path& poses, const fs::path& times) {
  std::ofstream p(poses), t(times);
  for (size_t i = 0; i < r.t.size(); ++i) {
    const Eigen::Matrix4d M = r.T_world_cam0[i].matrix();
    for (int k = 0; k < 12; ++k) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%e", M(k / 4, k % 4));
      p << (k ? " " : "") << buf;
    }
    p << "\n";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%e", r.t[i]);
    t << buf << "\n";
  }
}

// ~200 m in 36 s: 8 m/s, braking to a 4 s stop (t 10..14 s), off again at
// 7 m/s into an 80 degree left curve (radius 25 m, 10 m ramps), over a 1.5 m
// rise; 10 Hz with 2 ms time jitter and 3 mm position noise (deterministic).
HandMadeRoute MakeCurveWithStop() {
  auto speed = [](double t) {
    if (t < 6) return 8.0;
    if (t < 10) return 4.0 * (1 + std::cos(kPi * (t - 6) / 4));  // 8 -> 0
    if (t < 14) return 0.0;
    if (t < 19) return 3.5 * (1 - std::cos(kPi * (t - 14) / 5));  // 0 -> 7
    return 7.0;
  };
  auto kappa = [](double s) {
    const double k = 1.0 / 25;
    if (s < 90) return 0.0;
    if (s < 100) return k * (s - 90) / 10;
    if (s < 125) return k;
    if (s < 135) return k * (135 - s) / 10;
    return 0.0;
  };
  auto height = [](double s) { return 0.75 * (1 - std::cos(kPi * s / 200)); };
  HandMadeRoute r;
  std::mt19937 rng(12345);
  auto noise = [&](double amp) { return amp * (2.0 * rng() / 4294967295.0 - 1.0); };
  // Integrate s(t), heading and position finely (1 ms).
  double t = 0, s = 0, psi = 0, e = 0, n = 0;
  const double dt = 0.001;
  for (int frame = 0; frame < 360; ++frame) {
    const double t_frame = frame * 0.1 + (frame > 0 ? noise(0.002) : 0.0);
    while (t < t_frame) {
      const double v = speed(t + dt / 2);
      const double ds = v * dt, psi_mid = psi + 0.5 * ds * kappa(s);
      e += ds * std::cos(psi_mid);
      n += ds * std::sin(psi_mid);
      psi += ds * kappa(s + ds / 2);
      s += ds;
      t += dt;
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    // camera axes in the world: x right = (cos psi, 0, sin psi), y down, z forward = (-sin psi, 0, cos psi)
    T.linear().col(0) = Eigen::Vector3d(std::cos(psi), 0, std::sin(psi));
    T.linear().col(1) = Eigen::Vector3d(0, 1, 0);
    T.linear().col(2) = Eigen::Vector3d(-std::sin(psi), 0, std::cos(psi));
    const double pn = frame > 0 ? 0.003 : 0.0;
    T.translation() = Eigen::Vector3d(-n + noise(pn), -(height(s) - height(0)) + noise(pn), e + noise(pn));
    r.t.push_back(t_frame);
    r.T_world_cam0.push_back(T);
  }
  return r;
}

// What a rendered drive says, on the route's clock (t = time of the start pose + time since image 0).
struct DriveRecords {
  std::vector<double> t_oxts;
  std::vector<kitti::OxtsRecord> oxts;
  std::vector<Eigen::Isometry3d> T_enu_imu;  // from the records, ENU of SynthConfig's origin
  std::vector<Eigen::Vector3d> v_enu;
  std::vector<double> t_image;
  std::vector<Eigen::Isometry3d> gt;  // ground_truth_cam0.txt
};

DriveRecords ReadDrive(const synth::SynthConfig& cfg, const fs::path& drive, double t_start) {
  DriveRecords d;
  const std::vector<int64_t> img = kitti::ReadTimestampsFile(drive / "image_00/timestamps.txt");
  const std::vector<int64_t> ox = kitti::ReadTimestampsFile(drive / "oxts/timestamps.txt");
  const GeographicLib::LocalCartesian enu(cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_alt_m);
  for (size_t k = 0; k < ox.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "%010zu.txt", k);
    d.oxts.push_back(kitti::ReadOxtsFile(drive / "oxts/data" / name));
    d.T_enu_imu.push_back(kitti::OxtsToEnuPose(d.oxts.back(), enu));
    d.v_enu.emplace_back(d.oxts.back().ve_mps, d.oxts.back().vn_mps, d.oxts.back().vu_mps);
    d.t_oxts.push_back(t_start + static_cast<double>(ox[k] - img[0]) * 1e-9);
  }
  for (int64_t t : img) d.t_image.push_back(t_start + static_cast<double>(t - img[0]) * 1e-9);
  d.gt = kitti::ReadKittiPoses(drive / "ground_truth_cam0.txt");
  return d;
}

// The poses' camera position (ENU) at time t, linear between poses.
Eigen::Vector3d CameraAt(const synth::RoutePoses& p, double t) {
  const auto it = std::upper_bound(p.t_s.begin(), p.t_s.end(), t);
  const size_t k = std::clamp<size_t>(static_cast<size_t>(it - p.t_s.begin()), 1, p.t_s.size() - 1);
  const double f = (t - p.t_s[k - 1]) / (p.t_s[k] - p.t_s[k - 1]);
  return (1 - f) * p.camera_enu[k - 1] + f * p.camera_enu[k];
}

struct Deviation {
  double rms = 0, max = 0;
  void Add(double e) {
    rms += e * e;
    max = std::max(max, std::abs(e));
    ++n;
  }
  double Rms() const { return n ? std::sqrt(rms / n) : 0; }
  int n = 0;
};

// How far the OXTS positions lie from the poses: horizontally, and in height
// (the IMU 0.72 m below KITTI's camera).
void MeasureFollowing(const DriveRecords& d, const synth::RoutePoses& poses, Deviation* horizontal,
                      Deviation* vertical) {
  for (size_t k = 0; k < d.oxts.size(); ++k) {
    const Eigen::Vector3d cam = CameraAt(poses, d.t_oxts[k]);
    const Eigen::Vector3d p = d.T_enu_imu[k].translation();
    horizontal->Add((p.head<2>() - cam.head<2>()).norm());
    vertical->Add(p.z() - (cam.z() - kImuBelowCameraM));
  }
}

// How far the ground truth's IMU positions lie from the poses at the image
// times: the ground truth (world = cam0 at image 0) is put into ENU with the
// first OXTS record, carried to the first image's time by its velocity and
// yaw rate.
void MeasureGroundTruth(const DriveRecords& d, const Eigen::Isometry3d& T_cam0_imu, const synth::RoutePoses& poses,
                        Deviation* horizontal, Deviation* vertical) {
  const double dt = d.t_image[0] - d.t_oxts[0];
  Eigen::Isometry3d T_enu_imu0 = d.T_enu_imu[0];
  T_enu_imu0.translation() += d.v_enu[0] * dt;
  T_enu_imu0.linear() = Eigen::AngleAxisd(d.oxts[0].wu_radps * dt, Eigen::Vector3d::UnitZ()) * T_enu_imu0.linear();
  const Eigen::Isometry3d T_enu_world = T_enu_imu0 * T_cam0_imu.inverse();
  for (size_t k = 0; k < d.gt.size(); ++k) {
    const Eigen::Vector3d p = (T_enu_world * d.gt[k] * T_cam0_imu).translation();
    const Eigen::Vector3d cam = CameraAt(poses, d.t_image[k]);
    horizontal->Add((p.head<2>() - cam.head<2>()).norm());
    vertical->Add(p.z() - (cam.z() - kImuBelowCameraM));
  }
}

// The OXTS records against their own positions and attitudes: velocity vs
// the derivative of the positions (3-point, exact for quadratics on uneven
// spacing), the change of velocity vs the integral of the specific force
// rotated to ENU less gravity (trapezoid), the change of yaw vs the integral
// of the yaw rate wu. Returns the worst error of each.
struct Consistency {
  Deviation velocity, dv, dyaw;
};
Consistency MeasureConsistency(const DriveRecords& d) {
  Consistency c;
  const size_t n = d.oxts.size();
  const Eigen::Vector3d g(0, 0, kGravity);
  auto accel_enu = [&](size_t k) {
    const kitti::OxtsRecord& r = d.oxts[k];
    return Eigen::Vector3d(d.T_enu_imu[k].linear() * Eigen::Vector3d(r.ax_mps2, r.ay_mps2, r.az_mps2) - g);
  };
  for (size_t k = 1; k + 1 < n; ++k) {
    const double hm = d.t_oxts[k] - d.t_oxts[k - 1], hp = d.t_oxts[k + 1] - d.t_oxts[k];
    const Eigen::Vector3d pm = d.T_enu_imu[k - 1].translation(), p0 = d.T_enu_imu[k].translation(),
                          pp = d.T_enu_imu[k + 1].translation();
    const Eigen::Vector3d v = ((pp - p0) * hm / hp + (p0 - pm) * hp / hm) / (hm + hp);
    c.velocity.Add((v - d.v_enu[k]).norm());
  }
  for (size_t k = 0; k + 1 < n; ++k) {
    const double h = d.t_oxts[k + 1] - d.t_oxts[k];
    c.dv.Add((d.v_enu[k + 1] - d.v_enu[k] - 0.5 * h * (accel_enu(k) + accel_enu(k + 1))).norm());
    const double dyaw = std::remainder(d.oxts[k + 1].yaw_rad - d.oxts[k].yaw_rad, 2 * kPi);
    c.dyaw.Add(dyaw - 0.5 * h * (d.oxts[k].wu_radps + d.oxts[k + 1].wu_radps));
  }
  return c;
}

// Small images: the test is about the trajectory, not the pictures.
synth::SynthConfig RouteConfig(const fs::path& poses, const fs::path& times) {
  synth::SynthConfig cfg;
  cfg.seed = 5;
  cfg.width = 160;
  cfg.height = 48;
  cfg.frames = 0;  // up to the last pose
  cfg.route_poses = poses;
  cfg.route_times = times;
  return cfg;
}

class SynthRouteTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScopedTempDir("synth_route");
    WriteRoute(MakeCurveWithStop(), *dir_ / "poses.txt", *dir_ / "times.txt");
    cfg_ = new synth::SynthConfig(RouteConfig(*dir_ / "poses.txt", *dir_ / "times.txt"));
    summary_ = new synth::SynthSummary(synth::GenerateDrive(*cfg_, *dir_ / "drive"));
    poses_ = new synth::RoutePoses(synth::ReadRoutePoses(*dir_ / "poses.txt", *dir_ / "times.txt"));
    drive_ = new DriveRecords(ReadDrive(*cfg_, summary_->drive_dir, 0.0));
  }
  static void TearDownTestSuite() {
    delete drive_;
    delete poses_;
    delete summary_;
    delete cfg_;
    delete dir_;
  }
  static ScopedTempDir* dir_;
  static synth::SynthConfig* cfg_;
  static synth::SynthSummary* summary_;
  static synth::RoutePoses* poses_;
  static DriveRecords* drive_;
};
ScopedTempDir* SynthRouteTest::dir_ = nullptr;
synth::SynthConfig* SynthRouteTest::cfg_ = nullptr;
synth::SynthSummary* SynthRouteTest::summary_ = nullptr;
synth::RoutePoses* SynthRouteTest::poses_ = nullptr;
DriveRecords* SynthRouteTest::drive_ = nullptr;

TEST_F(SynthRouteTest, DrivesTheWholeRouteAtTheFrameRate) {
  // 360 poses over 35.9 s at 10 Hz: images up to the last pose.
  EXPECT_EQ(summary_->frames, 359);
  EXPECT_EQ(summary_->route_first_pose, 0);
  EXPECT_NEAR(summary_->route_last_pose, 358, 1);  // the last image at 35.8 s, pose 358 at 35.8 +- 0.002 s
  EXPECT_FALSE(summary_->route_cut);
  EXPECT_NEAR(summary_->distance_m, 199.1, 0.5);  // 48 + 16 + 17.5 + 7 * 16.8 m
  EXPECT_NEAR(summary_->min_speed_mps, 0.0, 1e-6);
  EXPECT_NEAR(summary_->max_speed_mps, 8.0, 0.1);
  ASSERT_EQ(drive_->t_image.size(), 359u);
  ASSERT_EQ(drive_->gt.size(), 359u);
  for (size_t k = 1; k < drive_->t_image.size(); ++k)
    EXPECT_NEAR(drive_->t_image[k] - drive_->t_image[k - 1], 0.1, 0.004) << "frame " << k;
  EXPECT_TRUE(drive_->gt[0].isApprox(Eigen::Isometry3d::Identity(), 1e-9));
}

TEST_F(SynthRouteTest, OxtsPositionsFollowThePosesWithinCentimetres) {
  Deviation horizontal, vertical;
  MeasureFollowing(*drive_, *poses_, &horizontal, &vertical);
  // The poses carry 3 mm of noise; the curve's ramps and the stop are followed.
  EXPECT_LT(horizontal.Rms(), 0.01);
  EXPECT_LT(horizontal.max, 0.03);
  EXPECT_LT(vertical.Rms(), 0.01);
  EXPECT_LT(vertical.max, 0.03);
  // The ground truth is the same trajectory (its IMU positions).
  Deviation gt_horizontal, gt_vertical;
  MeasureGroundTruth(*drive_, summary_->T_cam0_imu, *poses_, &gt_horizontal, &gt_vertical);
  EXPECT_LT(gt_horizontal.max, 0.03);
  EXPECT_LT(gt_vertical.max, 0.03);
}

TEST_F(SynthRouteTest, OxtsAreTheDerivativesOfTheTrajectory) {
  const Consistency c = MeasureConsistency(*drive_);
  // Velocity: 3-point derivative of the positions (error ~ jerk * h^2 / 6).
  EXPECT_LT(c.velocity.max, 0.02);
  // Change of velocity over 0.1 s: the specific force's noise (0.03 m/s^2 an
  // axis) and bias (~0.02 m/s^2 an axis) make ~0.006 m/s (seed 5: 0.006 RMS,
  // 0.016 at most).
  EXPECT_LT(c.dv.Rms(), 0.012);
  EXPECT_LT(c.dv.max, 0.03);
  // Change of yaw: gyro noise 8e-4 rad/s and bias 2e-4 rad/s over 0.1 s.
  EXPECT_LT(c.dyaw.max, 5e-4);
}

TEST_F(SynthRouteTest, StopHoldsStillWhileTimePasses) {
  int at_rest = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < drive_->oxts.size(); ++k) {
    if (drive_->t_oxts[k] < 10.6 || drive_->t_oxts[k] > 13.4) continue;  // the poses stand still 10..14 s
    const kitti::OxtsRecord& r = drive_->oxts[k];
    const Eigen::Vector3d p = drive_->T_enu_imu[k].translation();
    if (at_rest++ == 0) first = p;
    EXPECT_LT((p - first).norm(), 1e-3) << "record " << k;
    EXPECT_LT(drive_->v_enu[k].norm(), 1e-6) << "record " << k;
    // Only gravity (and the sensor's noise and bias): no vibration at rest.
    const Eigen::Vector3d g_body = drive_->T_enu_imu[k].linear().transpose() * Eigen::Vector3d(0, 0, kGravity);
    EXPECT_LT((Eigen::Vector3d(r.ax_mps2, r.ay_mps2, r.az_mps2) - g_body).norm(), 0.2) << "record " << k;
    EXPECT_LT(Eigen::Vector3d(r.wx_radps, r.wy_radps, r.wz_radps).norm(), 0.005) << "record " << k;
  }
  EXPECT_GE(at_rest, 27);  // 2.8 s of records at 10 Hz: the clock goes on
}

// A slice of KITTI odometry sequence 00 (frames 500..650: a slow turn and the
// sequence's one stop), when the shared data are there.
TEST(SynthRouteKittiTest, Sequence00SliceFollowsThePoses) {
  const fs::path kitti_dir = fs::path(LOCAID_SHARED_DATA) / "odometry";
  const fs::path poses = kitti_dir / "poses/00.txt", times = kitti_dir / "sequences/00/times.txt";
  if (!fs::exists(poses) || !fs::exists(times)) GTEST_SKIP() << "shared KITTI odometry data absent: " << poses;
  const ScopedTempDir dir("synth_route_00");
  synth::SynthConfig cfg = RouteConfig(poses, times);
  cfg.route_start_frame = 500;
  cfg.frames = 150;
  const synth::SynthSummary s = synth::GenerateDrive(cfg, dir / "drive");
  EXPECT_EQ(s.frames, 150);
  EXPECT_EQ(s.route_first_pose, 500);
  const synth::RoutePoses route = synth::ReadRoutePoses(poses, times);
  const DriveRecords d = ReadDrive(cfg, s.drive_dir, route.t_s[500]);
  Deviation horizontal, vertical;
  MeasureFollowing(d, route, &horizontal, &vertical);
  EXPECT_LT(horizontal.Rms(), 0.03);
  EXPECT_LT(horizontal.max, 0.08);
  EXPECT_LT(vertical.Rms(), 0.03);
  EXPECT_LT(vertical.max, 0.08);
  Deviation gt_horizontal, gt_vertical;
  MeasureGroundTruth(d, s.T_cam0_imu, route, &gt_horizontal, &gt_vertical);
  EXPECT_LT(gt_horizontal.Rms(), 0.03);
  EXPECT_LT(gt_vertical.Rms(), 0.03);
  const Consistency c = MeasureConsistency(d);
  EXPECT_LT(c.velocity.max, 0.03);
  EXPECT_LT(c.dv.Rms(), 0.012);
  EXPECT_LT(c.dv.max, 0.03);
  EXPECT_LT(c.dyaw.max, 1e-3);
}

// Every way a route file can be wrong is refused, naming file, line and
// reason, before anything is written.
TEST(SynthRouteErrorsTest, BadRouteFilesAreRefusedBeforeWriting) {
  const ScopedTempDir dir("synth_route_errors");
  const HandMadeRoute good = MakeCurveWithStop();
  WriteRoute(good, dir / "poses.txt", dir / "times.txt");
  const fs::path out = dir / "out";
  auto error = [&](const synth::SynthConfig& cfg) {
    const std::string e = ErrorOf<kitti::Error>([&] { synth::GenerateDrive(cfg, out); });
    EXPECT_FALSE(fs::exists(out)) << e;
    return e;
  };
  const std::string P = (dir / "poses.txt").string(), T = (dir / "times.txt").string();
  synth::SynthConfig cfg = RouteConfig(dir / "missing.txt", "");
  EXPECT_EQ(error(cfg), "synth: route poses: " + (dir / "missing.txt").string() +
                            ": cannot open for reading: No such file or directory");
  // Line 17 with 11 numbers.
  {
    std::ifstream in(P);
    std::ofstream bad(dir / "bad.txt");
    int line = 0;
    for (std::string l; std::getline(in, l);) bad << (++line == 17 ? l.substr(0, l.rfind(' ')) : l) << "\n";
  }
  cfg = RouteConfig(dir / "bad.txt", T);
  EXPECT_EQ(error(cfg), "synth: route poses: " + (dir / "bad.txt").string() +
                            ":17: 11 numbers, expected 12 (KITTI 3x4 row-major)");
  // One time fewer than poses.
  {
    std::ifstream in(T);
    std::ofstream short_times(dir / "short.txt");
    std::string l;
    for (int i = 0; i < 359 && std::getline(in, l); ++i) short_times << l << "\n";
  }
  cfg = RouteConfig(dir / "poses.txt", dir / "short.txt");
  EXPECT_EQ(error(cfg), "synth: route: " + P + " has 360 poses but " + (dir / "short.txt").string() + " has 359 times");
  // Line 5 repeats line 4's time.
  {
    std::ofstream same(dir / "same.txt");
    for (int line = 1; line <= 360; ++line) same << 0.1 * (line == 5 ? 3 : line - 1) << "\n";
  }
  cfg = RouteConfig(dir / "poses.txt", dir / "same.txt");
  EXPECT_EQ(error(cfg), "synth: route times: " + (dir / "same.txt").string() +
                            ":5: time 0.3 s is not after the previous one (0.3 s)");
  // A single pose.
  {
    std::ifstream in(P);
    std::string l;
    std::getline(in, l);
    std::ofstream(dir / "one.txt") << l << "\n";
  }
  cfg = RouteConfig(dir / "one.txt", "");
  EXPECT_EQ(error(cfg), "synth: route: " + (dir / "one.txt").string() + " has 1 pose(s), fewer than 2");
  // Start frame past the last pose that has one after it.
  cfg = RouteConfig(dir / "poses.txt", dir / "times.txt");
  cfg.route_start_frame = 359;
  EXPECT_EQ(error(cfg), "synth: route start frame 359 out of range: " + P + " has 360 poses (start frames 0..358)");
  cfg.route_start_frame = -1;
  EXPECT_EQ(error(cfg), "synth: route start frame must be >= 0 (got -1)");
  // Poses that stay in one place make no road.
  {
    std::ofstream still(dir / "still.txt");
    for (int i = 0; i < 20; ++i) still << "1 0 0 0 0 1 0 0 0 0 1 " << 0.01 * i << "\n";
  }
  cfg = RouteConfig(dir / "still.txt", "");
  EXPECT_EQ(error(cfg), "synth: route: the poses move 0 m horizontally, less than 5 m");
}

// A 40 m x 40 m block with 5 m corners (left turns tighter than the road is
// wide on its inside) driven 2.5 times round: the world holds three passes
// over each place, and the view (200 m ahead, 30 m behind) spans more than a
// lap; yet wherever the camera is, each point of the road is drawn by one
// road triangle at most, and the road under and ahead of the camera is drawn.
TEST(SynthRouteWorldTest, ARouteDrivenAgainDrawsEachPlaceOnce) {
  // The block's track: 30 m straights and quarter circles of 5 m, counter-clockwise.
  const double straight = 30, radius = 5, lap = 4 * straight + 2 * kPi * radius, speed = 5;
  auto track_at = [&](double s) {
    s = std::fmod(s, lap);
    Eigen::Vector2d p(0, 0);
    double heading = 0;
    for (int side = 0; side < 4; ++side) {
      const Eigen::Vector2d dir(std::cos(heading), std::sin(heading)), left(-dir.y(), dir.x());
      if (s <= straight) return Eigen::Vector2d(p + s * dir);
      p += straight * dir;
      s -= straight;
      const double arc = kPi / 2 * radius;
      if (s <= arc) {
        const double a = s / radius;
        return Eigen::Vector2d(p + radius * (std::sin(a) * dir + (1 - std::cos(a)) * left));
      }
      p += radius * (dir + left);
      s -= arc;
      heading += kPi / 2;
    }
    return p;
  };
  synth::RoutePoses poses;
  for (int i = 0; i * 0.1 * speed < 2.5 * lap; ++i) {
    poses.t_s.push_back(i * 0.1);
    const Eigen::Vector2d p = track_at(i * 0.1 * speed);
    poses.camera_enu.emplace_back(p.x(), p.y(), 1.65);
  }
  const synth::RouteFit fit(poses);
  synth::TrackGeometry track = fit.track();
  track.s_begin = 0;
  track.s_end = 2.5 * lap;
  const synth::Route route(track);
  const std::vector<synth::MipTexture> textures = synth::MakeTextures(3);
  synth::World world(route, textures, 3, 60);
  auto inside = [](const synth::Poly& p, const Eigen::Vector2d& q) {
    double sign = 0;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector2d a = p.p[static_cast<size_t>(i)].head<2>(), b = p.p[static_cast<size_t>((i + 1) % 3)].head<2>();
      const double c = (b - a).x() * (q - a).y() - (b - a).y() * (q - a).x();
      if (c * sign < 0) return false;
      if (c != 0) sign = c;
    }
    return true;
  };
  std::vector<const synth::Poly*> polys;
  for (double s_cam = 5; s_cam < 2.5 * lap; s_cam += 25) {
    world.Collect(s_cam, 0, route.Point(s_cam, -1.75, 1.65), polys);
    std::vector<const synth::Poly*> road;
    for (const synth::Poly* p : polys)
      if (p->tex == synth::kTexRoad && p->n == 3) road.push_back(p);
    auto count = [&](const Eigen::Vector2d& q) {
      return std::count_if(road.begin(), road.end(), [&](const synth::Poly* p) { return inside(*p, q); });
    };
    int overlaps = 0;
    for (const synth::Poly* p : road) {
      const Eigen::Vector2d centroid = (p->p[0] + p->p[1] + p->p[2]).head<2>() / 3;
      overlaps += count(centroid) > 1;
    }
    EXPECT_EQ(overlaps, 0) << "s_cam " << s_cam << ": road triangles drawn over each other";
    for (double ahead : {0.0, 10.0, 40.0, 80.0}) {
      if (s_cam + ahead < route.length_m() - 5) {
        EXPECT_EQ(count(route.Point(s_cam + ahead, -1.75, 0).head<2>()), 1) << "s_cam " << s_cam << " + " << ahead;
      }
    }
  }
}

// The spline fit under route mode: a third-order penalty leaves a quadratic
// as it is; the monotone fit never goes down, and holds still where asked.
TEST(SynthSplineTest, PenaltyKeepsQuadraticsAndMonotoneFitHoldsStill) {
  std::vector<double> x, y, steps;
  for (int i = 0; i <= 200; ++i) {
    const double xi = 0.1 * i;
    x.push_back(xi);
    y.push_back(3 + 2 * xi - 0.25 * xi * xi);
    steps.push_back(xi < 8 ? xi : xi < 12 ? 8.0 : 8 + (xi - 12));  // moving, standing still, moving
  }
  synth::SplineFit fit;
  fit.x0 = -0.5;
  fit.h = 0.5;
  fit.n_coefficients = 45;  // up to 20.5
  fit.lambda = 1e4;
  const synth::UniformCubicSpline q = synth::FitSplines(x, {y}, {}, fit).front();
  for (double xi = 0; xi <= 20; xi += 0.37) {
    double f = 0, df = 0, d2f = 0;
    q.Eval(xi, &f, &df, &d2f);
    EXPECT_NEAR(f, 3 + 2 * xi - 0.25 * xi * xi, 1e-6) << xi;
    EXPECT_NEAR(df, 2 - 0.5 * xi, 1e-6) << xi;
    EXPECT_NEAR(d2f, -0.5, 1e-6) << xi;
  }
  fit.monotone = true;
  fit.lambda = 30;
  for (bool hold : {false, true}) {
    if (hold) fit.constant_on = {{8.5, 11.5}};
    const synth::UniformCubicSpline m = synth::FitSplines(x, {steps}, {}, fit).front();
    double prev = -1e9;
    for (double xi = 0; xi <= 20; xi += 0.01) {
      double f = 0, df = 0;
      m.Eval(xi, &f, &df, nullptr);
      EXPECT_GE(f, prev - 1e-12) << xi;
      prev = f;
      if (hold && xi >= 8.5 && xi <= 11.5) {
        EXPECT_NEAR(df, 0.0, 1e-9) << xi;
      }
      if (std::abs(xi - 4) < 0.005 || std::abs(xi - 16) < 0.005) {
        EXPECT_NEAR(df, 1.0, 0.05) << xi;  // moving, 4 from the corners
      }
    }
  }
}

}  // namespace
