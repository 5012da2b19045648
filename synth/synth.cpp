#include "synth/synth.hpp"

#include "synth/motion.hpp"
#include "synth/random.hpp"
#include "synth/renderer.hpp"
#include "synth/route_file.hpp"
#include "synth/texture.hpp"
#include "synth/world.hpp"

#include "kitti/calib.hpp"
#include "kitti/oxts.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/timestamps.hpp"

#include <GeographicLib/LocalCartesian.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <regex>
#include <system_error>

namespace locaid::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

// "25" and "25..30" for error messages (%g: no trailing zeros).
std::string Num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}
std::string Range(double lo, double hi) { return Num(lo) + ".." + Num(hi); }

// Calibration values carry 7 significant digits ("%e"), like the real KITTI
// files: the rig is defined by the rounded numbers (kitti/'s writer then
// writes them exactly).
double Round(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%e", x);
  return std::strtod(buf, nullptr);
}

template <int R, int C>
Eigen::Matrix<double, R, C> RoundM(const Eigen::Matrix<double, R, C>& m) {
  Eigen::Matrix<double, R, C> r;
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) r(i, j) = Round(m(i, j));
  return r;
}

Eigen::Matrix3d SmallRot(double rx, double ry, double rz) {
  return (Eigen::AngleAxisd(rz, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(ry, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rx, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Matrix3d Orthonormal(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw kitti::Error("synth: cannot write '" + path.string() + "': " + std::strerror(errno));
  f << text;
  if (!f.flush()) throw kitti::Error("synth: write failed for '" + path.string() + "'");
}

void MakeDirs(const std::filesystem::path& p) {
  std::error_code ec;
  std::filesystem::create_directories(p, ec);
  if (ec || !std::filesystem::is_directory(p))
    throw kitti::Error("synth: cannot create folder '" + p.string() + "': " +
                (ec ? ec.message() : std::string("not a directory")));
}

std::string Index10(int i) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%010d", i);
  return buf;
}

// oxts/dataformat.txt of KITTI raw drives, verbatim (including its "ay:" typo for az).
const char* kDataFormat =
    "lat:   latitude of the oxts-unit (deg)\n"
    "lon:   longitude of the oxts-unit (deg)\n"
    "alt:   altitude of the oxts-unit (m)\n"
    "roll:  roll angle (rad),    0 = level, positive = left side up,      range: -pi   .. +pi\n"
    "pitch: pitch angle (rad),   0 = level, positive = front down,        range: -pi/2 .. +pi/2\n"
    "yaw:   heading (rad),       0 = east,  positive = counter clockwise, range: -pi   .. +pi\n"
    "vn:    velocity towards north (m/s)\n"
    "ve:    velocity towards east (m/s)\n"
    "vf:    forward velocity, i.e. parallel to earth-surface (m/s)\n"
    "vl:    leftward velocity, i.e. parallel to earth-surface (m/s)\n"
    "vu:    upward velocity, i.e. perpendicular to earth-surface (m/s)\n"
    "ax:    acceleration in x, i.e. in direction of vehicle front (m/s^2)\n"
    "ay:    acceleration in y, i.e. in direction of vehicle left (m/s^2)\n"
    "ay:    acceleration in z, i.e. in direction of vehicle top (m/s^2)\n"
    "af:    forward acceleration (m/s^2)\n"
    "al:    leftward acceleration (m/s^2)\n"
    "au:    upward acceleration (m/s^2)\n"
    "wx:    angular rate around x (rad/s)\n"
    "wy:    angular rate around y (rad/s)\n"
    "wz:    angular rate around z (rad/s)\n"
    "wf:    angular rate around forward axis (rad/s)\n"
    "wl:    angular rate around leftward axis (rad/s)\n"
    "wu:    angular rate around upward axis (rad/s)\n"
    "pos_accuracy:  velocity accuracy (north/east in m)\n"
    "vel_accuracy:  velocity accuracy (north/east in m/s)\n"
    "navstat:       navigation status (see navstat_to_string)\n"
    "numsats:       number of satellites tracked by primary GPS receiver\n"
    "posmode:       position mode of primary GPS receiver (see gps_mode_to_string)\n"
    "velmode:       velocity mode of primary GPS receiver (see gps_mode_to_string)\n"
    "orimode:       orientation mode of primary GPS receiver (see gps_mode_to_string)\n";

}  // namespace

SynthCalib MakeSynthCalib(int width, int height) {
  SynthCalib c;
  const double f = Round(721.5377 * width / 1242.0), cx = Round(609.5593 * width / 1242.0),
               cy = Round(172.854 * height / 375.0);
  const double pos_x[4] = {0.0, 0.5371, -0.0598, 0.4762};  // rectified camera centres along x (m)
  const Eigen::Matrix3d R_rect_00 = RoundM<3, 3>(SmallRot(0.00431, -0.00744, 0.00986));
  const Eigen::Matrix3d R_0x[4] = {Eigen::Matrix3d::Identity(), SmallRot(-0.0087, -0.0307, -0.0188),
                                   SmallRot(-0.0034, -0.0046, 0.0052), SmallRot(-0.0018, -0.0243, -0.0170)};
  c.cam_to_cam.calib_time = "17-May-2024 09:12:31";
  c.cam_to_cam.corner_dist = Round(0.0995);
  for (int i = 0; i < 4; ++i) {
    kitti::CameraCalib& cam = c.cam_to_cam.cams[static_cast<size_t>(i)];
    cam.S = cam.S_rect = Eigen::Vector2d(width, height);
    cam.K << f, 0, cx, 0, f, cy, 0, 0, 1;
    cam.D.setZero();
    cam.R = RoundM<3, 3>(R_0x[i]);
    cam.R_rect = RoundM<3, 3>(R_rect_00 * cam.R.transpose());
    cam.T = RoundM<3, 1>(cam.R * R_rect_00.transpose() * Eigen::Vector3d(-pos_x[i], 0, 0));
    cam.P_rect << f, 0, cx, Round(-f * pos_x[i]), 0, f, cy, 0, 0, 0, 1, 0;
  }
  // velodyne -> cam0 (unrectified): axes swap plus a small mounting rotation
  Eigen::Matrix3d base;
  base << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Matrix3d R_cv = RoundM<3, 3>(SmallRot(0.01481, 0.0006, 0.0075) * base);
  const Eigen::Vector3d t_cv = RoundM<3, 1>(Eigen::Vector3d(-0.0041, -0.0757, -0.2731));
  c.velo_to_cam.calib_time = "17-May-2024 10:02:44";
  const Eigen::Matrix3d R_vi = RoundM<3, 3>(SmallRot(0.01475, -0.00208, -0.00079));
  const Eigen::Vector3d t_vi = RoundM<3, 1>(Eigen::Vector3d(-0.8102, 0.3188, -0.8021));
  c.imu_to_velo.calib_time = "17-May-2024 10:40:05";
  Eigen::Isometry3d& T_cv = c.velo_to_cam.T_to_from;
  Eigen::Isometry3d& T_vi = c.imu_to_velo.T_to_from;
  Eigen::Isometry3d T_rect = Eigen::Isometry3d::Identity();
  T_cv.linear() = R_cv;
  T_cv.translation() = t_cv;
  T_vi.linear() = R_vi;
  T_vi.translation() = t_vi;
  T_rect.linear() = R_rect_00;
  Eigen::Isometry3d T = T_rect * T_cv * T_vi;
  T.linear() = Orthonormal(T.linear());
  c.T_cam0_imu = T;
  c.stereo.fx = c.stereo.fy = f;
  c.stereo.cx = cx;
  c.stereo.cy = cy;
  c.stereo.baseline_m = -Round(-f * pos_x[1]) / f;
  c.stereo.width = width;
  c.stereo.height = height;
  return c;
}

namespace {
// Midnight (UTC, ns) of a YYYY_MM_DD date; throws kitti::Error for anything
// that is not a calendar date.
int64_t MidnightNs(const std::string& date) {
  if (!std::regex_match(date, std::regex("[0-9]{4}_[0-9]{2}_[0-9]{2}")))
    throw kitti::Error("synth: date '" + date + "' is not YYYY_MM_DD");
  std::string dashes = date;
  std::replace(dashes.begin(), dashes.end(), '_', '-');
  return kitti::ParseTimestamp(dashes + " 00:00:00.0", "synth: date");
}
}  // namespace

void ValidateSynthConfig(const SynthConfig& cfg) {
  const bool route = !cfg.route_poses.empty();
  if (!std::isfinite(cfg.length_m)) throw kitti::Error("synth: length_m must be finite");
  if (!(cfg.noise_sigma_dn >= 0 && cfg.noise_sigma_dn <= 50))
    throw kitti::Error("synth: noise_sigma_dn must be in [0, 50] (got " + std::to_string(cfg.noise_sigma_dn) + ")");
  if (route && cfg.length_m <= 0 && (cfg.frames < 0 || cfg.frames == 1))
    throw kitti::Error("synth: frames must be >= 2, or 0 for the whole route (got " + std::to_string(cfg.frames) + ")");
  if (!route && cfg.length_m <= 0 && cfg.frames < 2) throw kitti::Error("synth: frames must be >= 2 (got " + std::to_string(cfg.frames) + ")");
  if (route && cfg.route_start_frame < 0)
    throw kitti::Error("synth: route start frame must be >= 0 (got " + std::to_string(cfg.route_start_frame) + ")");
  if (!route && !cfg.route_times.empty()) throw kitti::Error("synth: route times given without a route poses file");
  if (cfg.length_m > 100000) throw kitti::Error("synth: length_m must be <= 100000");
  if (cfg.width < 64 || cfg.width > 4096 || cfg.height < 48 || cfg.height > 4096)
    throw kitti::Error("synth: image size " + std::to_string(cfg.width) + "x" + std::to_string(cfg.height) +
                " out of range (64..4096 x 48..4096)");
  if (!(cfg.frame_rate_hz > 0.5 && cfg.frame_rate_hz <= 100)) throw kitti::Error("synth: frame_rate_hz must be in (0.5, 100]");
  MidnightNs(cfg.date);  // a real date, checked before anything is written
  if (cfg.png_compression < -1 || cfg.png_compression > 9) throw kitti::Error("synth: png_compression must be -1..9");
  if (!(cfg.speed_min_mps >= 1 && cfg.speed_min_mps <= cfg.speed_max_mps && cfg.speed_max_mps <= 60))
    throw kitti::Error("synth: speed range " + Range(cfg.speed_min_mps, cfg.speed_max_mps) +
                " m/s is not 1 <= min <= max <= 60");
  if (!(cfg.curve_radius_min_m >= 10 && cfg.curve_radius_min_m <= cfg.curve_radius_max_m &&
        cfg.curve_radius_max_m <= 10000))
    throw kitti::Error("synth: curve radius range " + Range(cfg.curve_radius_min_m, cfg.curve_radius_max_m) +
                " m is not 10 <= min <= max <= 10000");
}

namespace {

// The route, the vehicle on it and how much of it is rendered.
struct DrivePlan {
  std::unique_ptr<Route> route;
  std::unique_ptr<VehicleMotion> motion;
  int frames = 0;
  double world_duration_s = 0;  // how long the oncoming traffic must last
  int route_first_pose = -1, route_last_pose = -1;
  bool route_cut = false;
};

// A generated route (RouteConfig from the seed and the speed and curve
// ranges) with the vehicle on its speed plan.
DrivePlan PlanGeneratedDrive(const SynthConfig& cfg, double dt, double lead_s) {
  DrivePlan plan;
  RouteConfig rc;
  rc.seed = cfg.seed;
  rc.v_min_mps = cfg.speed_min_mps;
  rc.v_max_mps = cfg.speed_max_mps;
  rc.min_radius_m = cfg.curve_radius_min_m;
  rc.max_radius_m = cfg.curve_radius_max_m;
  const double duration_bound = cfg.length_m > 0 ? cfg.length_m / rc.v_min_mps + 5 : (cfg.frames - 1) * dt + 1;
  rc.length_m = (cfg.length_m > 0 ? cfg.length_m : rc.v_max_mps * duration_bound) + rc.v_max_mps * lead_s + 330;
  plan.route = std::make_unique<Route>(rc);
  plan.motion = std::make_unique<VehicleMotion>(*plan.route, MotionConfig{}, cfg.seed, duration_bound + lead_s + 2);
  plan.frames = cfg.frames;
  if (cfg.length_m > 0) {
    const double t_end = plan.motion->TimeAtS(plan.motion->S(lead_s) + cfg.length_m);
    if (t_end < 0) throw kitti::Error("synth: internal: route too short for length_m");
    plan.frames = static_cast<int>(std::ceil((t_end - lead_s) * cfg.frame_rate_hz)) + 1;
  }
  plan.world_duration_s = duration_bound + lead_s + 2;
  return plan;
}

// Route mode: the track and progress fitted to the poses file; the drive
// starts at pose route_start_frame (image 0 at its time, the motion's clock
// lead_s earlier) and ends with the frames, the length or the poses.
DrivePlan PlanRouteDrive(const SynthConfig& cfg, double dt, double lead_s) {
  const RoutePoses poses = ReadRoutePoses(cfg.route_poses, cfg.route_times);
  const int n = static_cast<int>(poses.t_s.size());
  const int k0 = cfg.route_start_frame;
  if (k0 > n - 2)
    throw kitti::Error("synth: route start frame " + std::to_string(k0) + " out of range: " +
                       cfg.route_poses.string() + " has " + std::to_string(n) + " poses (start frames 0.." +
                       std::to_string(n - 2) + ")");
  const RouteFit fit(poses);
  DrivePlan plan;
  const double t_start = poses.t_s[static_cast<size_t>(k0)];
  // The last image, its jitter and its OXTS record's offset stay before the last pose.
  const double margin_s = cfg.frame_jitter_max_s + cfg.oxts_time_offset_max_s + 0.01;
  const int frames_max = static_cast<int>(std::floor((fit.t_last() - t_start - margin_s) * cfg.frame_rate_hz)) + 1;
  if (frames_max < 2)
    throw kitti::Error("synth: route: from start frame " + std::to_string(k0) + " the poses last " +
                       Num(fit.t_last() - t_start) + " s, too short for 2 frames at " +
                       Num(cfg.frame_rate_hz) + " Hz");
  plan.frames = frames_max;
  if (cfg.length_m > 0) {
    const double t_end = fit.TimeAtS(fit.S(t_start) + cfg.length_m, t_start);
    const int asked = t_end < 0 ? frames_max + 1 : static_cast<int>(std::ceil((t_end - t_start) * cfg.frame_rate_hz)) + 1;
    plan.frames = std::min(frames_max, asked);
    plan.route_cut = asked > frames_max;
  } else if (cfg.frames > 0) {
    plan.frames = std::min(frames_max, cfg.frames);
    plan.route_cut = cfg.frames > frames_max;
  }
  const double t_base = t_start - lead_s;  // the motion's t = 0
  const double t_end = t_start + (plan.frames - 1) * dt + 1.0;
  plan.route_first_pose = k0;
  plan.route_last_pose = static_cast<int>(
      std::upper_bound(poses.t_s.begin(), poses.t_s.end(), t_start + (plan.frames - 1) * dt) - poses.t_s.begin() - 1);
  // The Route covers what the camera sees from the first to the last frame.
  const WorldConfig wc;
  TrackGeometry track = fit.track();
  track.s_begin = std::max(track.s_begin + 2, fit.S(t_base) - wc.view_behind_m - 30);
  track.s_end = std::min(track.s_end - 2, fit.S(t_end) + wc.view_ahead_m + 60);
  track.center_shift_m = -MotionConfig{}.lane_offset_m;
  plan.route = std::make_unique<Route>(track);
  constexpr double kProgressStepS = 0.01;
  const int samples = static_cast<int>(std::ceil((t_end - t_base) / kProgressStepS)) + 3;
  std::vector<double> s(static_cast<size_t>(samples)), v(s.size()), a(s.size());
  for (size_t k = 0; k < s.size(); ++k) {
    fit.Progress(t_base + static_cast<double>(k) * kProgressStepS, &s[k], &v[k], &a[k]);
    s[k] -= track.s_begin;
  }
  plan.motion = std::make_unique<VehicleMotion>(*plan.route, MotionConfig{}, cfg.seed, kProgressStepS, std::move(s),
                                                std::move(v), std::move(a));
  plan.world_duration_s = plan.motion->duration_s();
  return plan;
}

}  // namespace

SynthSummary GenerateDrive(const SynthConfig& cfg, const std::filesystem::path& out_dir,
                           const std::function<void(int, int)>& progress) {
  ValidateSynthConfig(cfg);

  const SynthCalib calib = MakeSynthCalib(cfg.width, cfg.height);
  const double dt = 1.0 / cfg.frame_rate_hz;
  const double lead_s = 1.0;  // the car is already moving 1 s before the first image
  const DrivePlan plan =
      cfg.route_poses.empty() ? PlanGeneratedDrive(cfg, dt, lead_s) : PlanRouteDrive(cfg, dt, lead_s);
  const Route& route = *plan.route;
  const VehicleMotion& motion = *plan.motion;
  const int frames = plan.frames;

  // Timestamps (ns since midnight), seconds relative to the first image.
  Rng trng(cfg.seed, 9);
  const int64_t t0_ns = int64_t{13} * 3600 * 1000000000LL + int64_t{trng.Int(0, 3599)} * 1000000000LL;
  std::vector<double> t_img(frames), t_oxts(frames);
  std::vector<int64_t> img_ns(frames), oxts_ns(frames);
  for (int k = 0; k < frames; ++k) {
    t_img[k] = k * dt + (k > 0 ? trng.Uniform(-cfg.frame_jitter_max_s, cfg.frame_jitter_max_s) : 0.0);
    img_ns[k] = t0_ns + std::llround(t_img[k] * 1e9);
    t_img[k] = (img_ns[k] - t0_ns) * 1e-9;  // exactly what the file says
    oxts_ns[k] = img_ns[k] + std::llround(trng.Uniform(-cfg.oxts_time_offset_max_s, cfg.oxts_time_offset_max_s) * 1e9);
    t_oxts[k] = (oxts_ns[k] - t0_ns) * 1e-9;
  }

  SynthSummary sum;
  sum.date_dir = out_dir;
  char drive[64];
  std::snprintf(drive, sizeof drive, "%s_drive_%04d_sync", cfg.date.c_str(), cfg.drive_number);
  sum.drive_dir = out_dir / drive;
  sum.frames = frames;
  sum.route_first_pose = plan.route_first_pose;
  sum.route_last_pose = plan.route_last_pose;
  sum.route_cut = plan.route_cut;
  sum.camera = calib.stereo;
  sum.T_cam0_imu = calib.T_cam0_imu;

  const auto& D = sum.drive_dir;
  for (const char* sub : {"image_00/data", "image_01/data", "oxts/data"}) MakeDirs(D / sub);
  // The KITTI files through kitti/'s writers (dataformat.txt is fixed text).
  kitti::WriteCamToCam(out_dir / "calib_cam_to_cam.txt", calib.cam_to_cam);
  kitti::WriteVeloToCam(out_dir / "calib_velo_to_cam.txt", calib.velo_to_cam);
  kitti::WriteImuToVelo(out_dir / "calib_imu_to_velo.txt", calib.imu_to_velo);
  WriteFile(D / "oxts/dataformat.txt", kDataFormat);
  {
    // Time stamps on the drive's date (the times above are since its midnight).
    const int64_t midnight_ns = MidnightNs(cfg.date);
    std::vector<int64_t> image_stamps(frames), oxts_stamps(frames);
    for (int k = 0; k < frames; ++k) {
      image_stamps[k] = midnight_ns + img_ns[k];
      oxts_stamps[k] = midnight_ns + oxts_ns[k];
    }
    kitti::WriteTimestampsFile(D / "image_00/timestamps.txt", image_stamps);
    kitti::WriteTimestampsFile(D / "image_01/timestamps.txt", image_stamps);
    kitti::WriteTimestampsFile(D / "oxts/timestamps.txt", oxts_stamps);
  }

  // The set-up steps report frame 0, so a caller can cancel before the first frame.
  if (progress) progress(0, frames);
  const std::vector<MipTexture> textures = MakeTextures(cfg.seed, [&] {
    if (progress) progress(0, frames);
  });
  World world(route, textures, cfg.seed, plan.world_duration_s);
  if (progress) progress(0, frames);
  sum.static_polygons = world.num_static_polys();
  Intrinsics K{calib.stereo.fx, calib.stereo.fy, calib.stereo.cx, calib.stereo.cy, cfg.width, cfg.height};
  Renderer renderer(K, &textures);
  renderer.anisotropic = cfg.anisotropic_filtering;
  const GeographicLib::LocalCartesian enu(cfg.origin_lat_deg, cfg.origin_lon_deg, cfg.origin_alt_m);
  const Eigen::Isometry3d T_imu_cam0 = calib.T_cam0_imu.inverse();
  Eigen::Isometry3d T_cam0_cam1 = Eigen::Isometry3d::Identity();
  T_cam0_cam1.translation().x() = calib.stereo.baseline_m;

  Rng prng(cfg.seed, 21);
  const double ph1 = prng.Uniform(0, 2 * kPi), ph2 = prng.Uniform(0, 2 * kPi), ph3 = prng.Uniform(0, 2 * kPi);
  const double lr_gain = 1.0 - prng.Uniform(0.01, 0.04), lr_offset = prng.Uniform(-2, 2);
  const Eigen::Vector3d acc_bias(prng.Normal() * 0.02, prng.Normal() * 0.02, prng.Normal() * 0.02);
  const Eigen::Vector3d gyro_bias(prng.Normal() * 2e-4, prng.Normal() * 2e-4, prng.Normal() * 2e-4);
  // -1: OpenCV's fast PNG path (SUB filter, zlib level 1, RLE strategy); 0..9: zlib level with
  // libpng's adaptive filters (smaller, slower).
  std::vector<int> png_params;
  if (cfg.png_compression >= 0) png_params = {cv::IMWRITE_PNG_COMPRESSION, cfg.png_compression};

  std::vector<Eigen::Isometry3d> gt_kitti;
  std::vector<kitti::StampedPose> gt_tum;
  Eigen::Isometry3d T_enu_world = Eigen::Isometry3d::Identity();
  std::vector<const Poly*> polys;
  cv::Mat img;
  sum.min_speed_mps = 1e9;
  for (int k = 0; k < frames; ++k) {
    const double tau = lead_s + t_img[k];
    const Eigen::Isometry3d T_enu_cam0 = motion.T_enu_imu(tau) * T_imu_cam0;
    if (k == 0) T_enu_world = T_enu_cam0;
    const Eigen::Isometry3d T_world_cam0 = T_enu_world.inverse() * T_enu_cam0;
    gt_kitti.push_back(T_world_cam0);
    gt_tum.push_back({t_img[k], T_world_cam0});
    const double speed = std::max(0.0, motion.SpeedAt(tau));  // route mode: ~1e-13 below 0 at a stop
    sum.min_speed_mps = std::min(sum.min_speed_mps, speed);
    sum.max_speed_mps = std::max(sum.max_speed_mps, speed);

    // Images.
    world.Collect(motion.S(tau), tau, T_enu_cam0.translation(), polys);
    Photometry ph;
    ph.gain = 1.0 + 0.07 * std::sin(2 * kPi * tau / 29.0 + ph1) + 0.03 * std::sin(2 * kPi * tau / 9.7 + ph2) +
              0.01 * std::sin(2 * kPi * tau / 2.3 + ph3);
    ph.noise_sigma_dn = cfg.noise_sigma_dn;
    ph.noise_seed = cfg.seed * 1000003ULL + static_cast<uint64_t>(k) * 2;
    renderer.Render(polys, T_enu_cam0, ph, img);
    const std::string name = Index10(k);
    if (!cv::imwrite((D / "image_00/data" / (name + ".png")).string(), img, png_params))
      throw kitti::Error("synth: cannot write " + (D / "image_00/data" / (name + ".png")).string());
    ph.gain *= lr_gain;
    ph.offset_dn = lr_offset;
    ph.noise_seed += 1;
    renderer.Render(polys, T_enu_cam0 * T_cam0_cam1, ph, img);
    if (!cv::imwrite((D / "image_01/data" / (name + ".png")).string(), img, png_params))
      throw kitti::Error("synth: cannot write " + (D / "image_01/data" / (name + ".png")).string());

    // OXTS record at its own time stamp.
    const double to = lead_s + t_oxts[k];
    const ImuKinematics kin = KinematicsAt(motion, to);
    Rng nrng(cfg.seed, 1000 + static_cast<uint64_t>(k));
    kitti::OxtsRecord r;
    const Eigen::Vector3d p = kin.T_enu_imu.translation();
    enu.Reverse(p.x(), p.y(), p.z(), r.lat_deg, r.lon_deg, r.alt_m);
    const Eigen::Vector3d rpy = RollPitchYaw(kin.T_enu_imu.linear());
    r.roll_rad = rpy.x();
    r.pitch_rad = rpy.y();
    r.yaw_rad = rpy.z();
    r.vn_mps = kin.v_enu_mps.y();
    r.ve_mps = kin.v_enu_mps.x();
    r.vu_mps = kin.v_enu_mps.z();
    r.vf_mps = r.ve_mps * std::cos(r.yaw_rad) + r.vn_mps * std::sin(r.yaw_rad);
    r.vl_mps = -r.ve_mps * std::sin(r.yaw_rad) + r.vn_mps * std::cos(r.yaw_rad);
    const Eigen::Vector3d f = kin.f_imu_mps2 + acc_bias +
                              Eigen::Vector3d(nrng.Normal(), nrng.Normal(), nrng.Normal()) * 0.03;
    const Eigen::Vector3d w = kin.w_imu_radps + gyro_bias +
                              Eigen::Vector3d(nrng.Normal(), nrng.Normal(), nrng.Normal()) * 8e-4;
    const Eigen::Matrix3d R_level = AttitudeFromRpy(r.roll_rad, r.pitch_rad, 0.0);  // body -> heading frame
    const Eigen::Vector3d f_flu = R_level * f, w_flu = R_level * w;
    r.ax_mps2 = f.x(); r.ay_mps2 = f.y(); r.az_mps2 = f.z();
    r.af_mps2 = f_flu.x(); r.al_mps2 = f_flu.y(); r.au_mps2 = f_flu.z();
    r.wx_radps = w.x(); r.wy_radps = w.y(); r.wz_radps = w.z();
    r.wf_radps = w_flu.x(); r.wl_radps = w_flu.y(); r.wu_radps = w_flu.z();
    r.pos_accuracy_m = 0.26 + 0.08 * std::sin(to / 17.0 + ph1);
    r.vel_accuracy_mps = 0.032 + 0.004 * std::sin(to / 11.0 + ph2);
    r.navstat = 4;
    r.numsats = 8 + static_cast<int>(std::floor(2.99 * (0.5 + 0.5 * std::sin(to / 23.0 + ph3))));
    r.posmode = r.velmode = (std::sin(to / 31.0 + ph2) > 0.3) ? 5 : 4;
    r.orimode = 0;
    WriteFile(D / "oxts/data" / (name + ".txt"), kitti::WriteOxtsLine(r) + "\n");
    if (progress) progress(k + 1, frames);
  }
  kitti::WriteKittiPoses(D / "ground_truth_cam0.txt", gt_kitti);
  kitti::WriteTumPoses(D / "ground_truth_cam0.tum", gt_tum);
  sum.duration_s = t_img.back();
  sum.distance_m = motion.S(lead_s + t_img.back()) - motion.S(lead_s);
  return sum;
}

}  // namespace locaid::synth
