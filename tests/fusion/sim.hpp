// Simulated car drive for the filter tests: smooth planar-ish trajectory with
// consistent IMU (specific force, angular rate), degraded GPS and noisy VO.
#pragma once

#include "fusion/ekf.hpp"
#include "fusion/ekf_models.hpp"
#include "fusion/geodesy.hpp"
#include "fusion/types.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <vector>

namespace locaid::fusion::test {

struct SimConfig {
  double duration_s = 120;
  double imu_rate_hz = 100, frame_rate_hz = 10, gps_rate_hz = 1;
  double gps_sigma_h_m = 3.0, gps_sigma_v_m = 5.0;
  double accel_noise = 0.02, gyro_noise = 0.0005;  // densities
  Vec3 accel_bias = Vec3(0.02, -0.01, 0.015), gyro_bias = Vec3(2e-4, -1e-4, 3e-4);
  // Per frame (~0.8 m): 1 cm and 0.2 mrad, a few times worse than good stereo VO
  // (KITTI leaders: ~1 % and ~0.003 deg/m).
  double vo_sigma_t_m = 0.01, vo_sigma_rot_rad = 0.0002;
  double outage_start_s = -1, outage_duration_s = 0;
  uint64_t seed = 1;
};

struct SimTruth {
  int64_t t_ns;
  NominalState x;
};

// Event stream in time order.
struct SimEvent {
  enum Kind { kImu, kGps, kFrame } kind;
  ImuSample imu;
  GpsFix gps;
  VoMeasurement vo;
  SimTruth truth;  // truth at the event time
  bool in_outage = false;
};

inline constexpr double kLat0 = 49.0, kLon0 = 8.4, kAlt0 = 110.0;

// A fix at the true position p_enu plus white noise of the config's sigmas
// (E, N, U drawn in that order; the caller's distribution, which caches
// every second draw, so a drive's noise sequence stays one sequence).
inline GpsFix NoisyFix(const EnuFrame& geo, const SimConfig& c, int64_t t_ns, const Vec3& p_enu,
                       std::mt19937_64& rng, std::normal_distribution<double>& n01) {
  GpsFix fix;
  const Vec3 noisy = p_enu + Vec3(c.gps_sigma_h_m * n01(rng), c.gps_sigma_h_m * n01(rng),
                                  c.gps_sigma_v_m * n01(rng));
  fix.t_ns = t_ns;
  geo.ToGeodetic(noisy, fix.lat_deg, fix.lon_deg, fix.alt_m);
  fix.sigma_h_m = c.gps_sigma_h_m;
  fix.sigma_v_m = c.gps_sigma_v_m;
  return fix;
}

// The filter's settings for a simulated drive: the sim's IMU noise, wide
// bias priors, and the isotropic VO noise the sim draws (not the real
// camera's anisotropic model).
inline EkfConfig SimEkfConfig(const SimConfig& c, bool use_imu) {
  EkfConfig e;
  e.imu.enabled = use_imu;
  e.imu.accel_noise_mps2_sqrt_hz = c.accel_noise;
  e.imu.gyro_noise_radps_sqrt_hz = c.gyro_noise;
  e.startup.accel_bias_sigma_mps2 = 0.05;
  e.startup.gyro_bias_sigma_radps = 0.001;
  e.vo.cov_scale = 5.0;
  e.vo.sigma_lateral_per_m = e.vo.sigma_vertical_per_m = e.vo.sigma_t_per_m;
  return e;
}

inline std::vector<SimEvent> Simulate(const SimConfig& c) {
  std::mt19937_64 rng(c.seed);
  std::normal_distribution<double> n01;
  EnuFrame geo;
  geo.SetOrigin(kLat0, kLon0, kAlt0);
  const double g = 9.81;
  const double dt_int = 0.001;  // truth integration step
  const int imu_every = static_cast<int>(std::lround(1.0 / (c.imu_rate_hz * dt_int)));
  const int frame_every = static_cast<int>(std::lround(1.0 / (c.frame_rate_hz * dt_int)));
  const int gps_every = static_cast<int>(std::lround(1.0 / (c.gps_rate_hz * dt_int)));
  double yaw = 0.7, speed = 8.0, pitch = 0.0;
  Vec3 p = Vec3::Zero();
  std::vector<SimEvent> ev;
  Eigen::Isometry3d T_prev_frame = Eigen::Isometry3d::Identity();
  int64_t t_prev_frame = 0;
  const int steps = static_cast<int>(c.duration_s / dt_int);
  for (int k = 0; k <= steps; ++k) {
    const double t = k * dt_int;
    const double yaw_rate = 0.12 * std::sin(0.05 * t) + 0.05 * std::sin(0.23 * t + 1.0);
    const double accel = 0.6 * std::sin(0.11 * t);
    const double pitch_rate = 0.01 * std::cos(0.07 * t);
    const Mat3 R = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix() *
                   Eigen::AngleAxisd(-pitch, Vec3::UnitY()).toRotationMatrix();
    const Vec3 v = R * Vec3(speed, 0, 0);
    const Vec3 a_enu = R * Vec3(accel, speed * yaw_rate * std::cos(pitch), speed * pitch_rate);
    const Vec3 w_body(0, -pitch_rate, 0);
    const Vec3 w_body_full = w_body + R.transpose() * Vec3(0, 0, yaw_rate);
    const int64_t t_ns = static_cast<int64_t>(std::llround(t * 1e9));
    NominalState truth;
    truth.p_enu_m = p; truth.v_enu_mps = v; truth.R_enu_body = R;
    truth.accel_bias_mps2 = c.accel_bias; truth.gyro_bias_radps = c.gyro_bias;
    const bool outage = c.outage_start_s >= 0 && t >= c.outage_start_s &&
                        t < c.outage_start_s + c.outage_duration_s;
    if (k % imu_every == 0) {
      SimEvent e{SimEvent::kImu, {}, {}, {}, {t_ns, truth}, outage};
      const double dt_imu = 1.0 / c.imu_rate_hz;
      e.imu.t_ns = t_ns;
      e.imu.accel_mps2 = R.transpose() * (a_enu - Vec3(0, 0, -g)) + c.accel_bias;
      e.imu.gyro_radps = w_body_full + c.gyro_bias;
      for (int i = 0; i < 3; ++i) {
        e.imu.accel_mps2[i] += c.accel_noise / std::sqrt(dt_imu) * n01(rng);
        e.imu.gyro_radps[i] += c.gyro_noise / std::sqrt(dt_imu) * n01(rng);
      }
      ev.push_back(e);
    }
    if (k % gps_every == 0 && !outage) {
      SimEvent e{SimEvent::kGps, {}, {}, {}, {t_ns, truth}, outage};
      e.gps = NoisyFix(geo, c, t_ns, p, rng, n01);
      ev.push_back(e);
    }
    if (k % frame_every == 0) {
      Eigen::Isometry3d T_now = Eigen::Isometry3d::Identity();
      T_now.linear() = R; T_now.translation() = p;
      SimEvent e{SimEvent::kFrame, {}, {}, {}, {t_ns, truth}, outage};
      const Eigen::Isometry3d T_rel = T_prev_frame.inverse() * T_now;
      Vec6 n;
      for (int i = 0; i < 3; ++i) { n[i] = c.vo_sigma_t_m * n01(rng); n[i + 3] = c.vo_sigma_rot_rad * n01(rng); }
      e.vo.t_prev_ns = t_prev_frame; e.vo.t_ns = t_ns;
      e.vo.T_prev_curr = T_rel;
      e.vo.T_prev_curr.translation() += T_rel.linear() * n.head<3>();
      e.vo.T_prev_curr.linear() = T_rel.linear() * ExpSO3(n.tail<3>());
      e.vo.covariance.setZero();
      e.vo.covariance.diagonal() << Vec3::Constant(c.vo_sigma_t_m * c.vo_sigma_t_m),
          Vec3::Constant(c.vo_sigma_rot_rad * c.vo_sigma_rot_rad);
      if (k == 0) e.vo.T_prev_curr = Eigen::Isometry3d::Identity();
      ev.push_back(e);
      T_prev_frame = T_now; t_prev_frame = t_ns;
    }
    // Integrate truth.
    p += v * dt_int + 0.5 * a_enu * dt_int * dt_int;
    speed += accel * dt_int;
    yaw += yaw_rate * dt_int;
    pitch += pitch_rate * dt_int;
  }
  return ev;
}

// Truth position expressed in the filter's ENU frame (origin at its first fix).
inline Vec3 TruthInFilterEnu(const Ekf& ekf, const Vec3& p_sim_enu) {
  EnuFrame geo;
  geo.SetOrigin(kLat0, kLon0, kAlt0);
  double lat, lon, alt;
  geo.ToGeodetic(p_sim_enu, lat, lon, alt);
  return ekf.enu().ToEnu(lat, lon, alt);
}

struct RunStats {
  double nees_sum = 0; int nees_n = 0;
  double rmse_h_sum2 = 0; int rmse_n = 0;
  double outage_end_error_m = -1, outage_distance_m = 0;
  double reconverge_s = -1;
  bool finite = true, spd = true, symmetric = true;
  std::vector<Mode> modes;
};

// Feeds the events to the filter; NEES over frames after init (skipping the
// first `settle_s` seconds after init).
inline RunStats RunFilter(Ekf& ekf, const std::vector<SimEvent>& ev, const SimConfig& c,
                          double settle_s = 10.0) {
  RunStats s;
  std::optional<int64_t> init_ns;
  Vec3 last_truth = Vec3::Zero();
  bool was_outage = false;
  std::optional<int64_t> outage_end_ns;
  for (const auto& e : ev) {
    if (e.kind == SimEvent::kImu) ekf.PropagateImu(e.imu);
    else if (e.kind == SimEvent::kGps) ekf.UpdateGps(e.gps);
    else {
      if (e.vo.t_ns == 0) { last_truth = e.truth.x.p_enu_m; continue; }
      ekf.ProcessVo(e.vo, true);
      const FusedPose pose = ekf.Output(e.vo.t_ns, true);
      if (!ekf.initialized()) { last_truth = e.truth.x.p_enu_m; continue; }
      if (!init_ns) init_ns = e.vo.t_ns;
      s.modes.push_back(pose.mode);
      const auto& P = ekf.covariance();
      if (!P.allFinite() || !pose.T_enu_body.matrix().allFinite()) s.finite = false;
      if ((P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * (1 + P.cwiseAbs().maxCoeff())) s.symmetric = false;
      // The navigation block must be positive definite; with the clone the
      // full matrix is only semi-definite right after cloning (exact copy).
      const int nav = P.rows() > 6 ? 15 : 6;
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es_nav(P.topLeftCorner(nav, nav));
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P);
      if (es_nav.eigenvalues().minCoeff() <= 0) s.spd = false;
      if (es.eigenvalues().minCoeff() < -1e-9 * es.eigenvalues().maxCoeff()) s.spd = false;
      const Vec3 gt = TruthInFilterEnu(ekf, e.truth.x.p_enu_m);
      const Vec3 err = pose.T_enu_body.translation() - gt;
      if (static_cast<double>(e.vo.t_ns - *init_ns) * 1e-9 > settle_s) {
        s.nees_sum += err.dot(pose.covariance.topLeftCorner<3, 3>().ldlt().solve(err));
        ++s.nees_n;
      }
      if (!e.in_outage) { s.rmse_h_sum2 += err.head<2>().squaredNorm(); ++s.rmse_n; }
      if (std::getenv("LOCAID_SIM_TRACE"))
        std::printf("trace t %.1f err %.2f %.2f %.2f sig %.2f %.2f mode %s\n", e.vo.t_ns * 1e-9, err.x(), err.y(), err.z(),
                    std::sqrt(pose.covariance(0, 0)), std::sqrt(pose.covariance(1, 1)), ToString(pose.mode));
      if (e.in_outage) {
        s.outage_distance_m += (e.truth.x.p_enu_m - last_truth).norm();
        s.outage_end_error_m = err.head<2>().norm();
      }
      if (was_outage && !e.in_outage) outage_end_ns = e.vo.t_ns;
      if (outage_end_ns && s.reconverge_s < 0 && err.head<2>().norm() <= 2 * c.gps_sigma_h_m)
        s.reconverge_s = static_cast<double>(e.vo.t_ns - *outage_end_ns) * 1e-9;
      was_outage = e.in_outage;
    }
    if (e.kind == SimEvent::kFrame) last_truth = e.truth.x.p_enu_m;
  }
  return s;
}

}  // namespace locaid::fusion::test
