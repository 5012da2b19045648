#include "synth/motion.hpp"

#include "synth/random.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locaid::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kVibrationSpeed2 = 1.5 * 1.5;  // (m/s)^2: vibrations at half strength at 1.5 m/s (route mode)

// smootherstep and its integral from 0 to u
double Smooth(double u) { return u * u * u * (u * (6 * u - 15) + 10); }
double SmoothIntegral(double u) { return u * u * u * u * (u * (u - 3) + 2.5); }

}  // namespace

Route::Route(const RouteConfig& config) : length_m_(config.length_m) {
  if (!(config.length_m > 0)) throw kitti::Error("synth route: length_m must be > 0");
  Rng rng(config.seed, 1);
  const double max_dev = config.max_heading_dev_deg * kPi / 180.0;
  // Relative heading (to the start heading) decides turn directions.
  double rel = 0, s = 0;
  const double heading_start = rng.Uniform(-kPi, kPi);
  auto add_straight = [&](double len) {
    Piece p; p.s0 = s; p.arc_m = len; p.heading0 = heading_start + rel;
    pieces_.push_back(p); s += len;
  };
  add_straight(rng.Uniform(40, 90));
  while (s < length_m_ + 50) {
    // curve
    const double radius = std::exp(rng.Uniform(std::log(config.min_radius_m), std::log(config.max_radius_m)));
    double angle = rng.Uniform(15, 90) * kPi / 180.0;
    double dir = rng.Chance(0.5) ? 1.0 : -1.0;
    if (std::abs(rel + dir * angle) > max_dev) dir = -dir;
    if (std::abs(rel + dir * angle) > max_dev) angle = std::max(0.0, max_dev - std::abs(rel)) * 0.9 + 0.0;
    if (angle > 5 * kPi / 180) {
      Piece p; p.s0 = s; p.kappa = dir / radius; p.heading0 = heading_start + rel;
      const double total = angle * radius;  // = ramp + arc
      p.ramp_m = std::min(25.0, 0.4 * total);
      p.arc_m = total - p.ramp_m;
      pieces_.push_back(p); s += p.length();
      rel += dir * angle;
    }
    add_straight(rng.Uniform(50, 260));
  }
  // Centerline knots.
  const int n_knots = static_cast<int>(std::ceil(s / knot_step_m_)) + 2;
  knots_.resize(n_knots);
  knots_[0] = Eigen::Vector2d::Zero();
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
  for (int i = 1; i < n_knots; ++i) {
    const double a = (i - 1) * knot_step_m_, b = i * knot_step_m_;
    Eigen::Vector2d acc = Eigen::Vector2d::Zero();
    for (int k = 0; k < 4; ++k) {
      const double h = Heading(0.5 * (a + b) + 0.5 * (b - a) * gx[k]);
      acc += gw[k] * Eigen::Vector2d(std::cos(h), std::sin(h));
    }
    knots_[i] = knots_[i - 1] + 0.5 * (b - a) * acc;
  }
  // Hills.
  for (int i = 0; i < 3; ++i) {
    const double lambda = rng.Uniform(220, 700), grade = rng.Uniform(0.006, 0.018);
    hills_.push_back({grade * lambda / (2 * kPi), 2 * kPi / lambda, rng.Uniform(0, 2 * kPi)});
  }
  // Speed plan on a grid: random cruise targets, curve limits, accel limits, smoothing.
  const int n = static_cast<int>(std::ceil(s / speed_step_m_)) + 2;
  std::vector<double> v(n);
  {
    double seg_end = 0, target = 9;
    bool first = true;
    for (int i = 0; i < n; ++i) {
      const double si = i * speed_step_m_;
      if (si >= seg_end) {
        if (!first && rng.Chance(0.2)) {
          target = rng.Uniform(config.v_min_mps, config.v_min_mps + 2);
          seg_end = si + rng.Uniform(30, 70);
        } else {
          target = first ? 9.0 : rng.Uniform(config.v_min_mps + 3, config.v_max_mps);
          seg_end = si + (first ? rng.Uniform(40, 90) : rng.Uniform(150, 400));
        }
        first = false;
      }
      double vmax = target;
      const double k = std::abs(Kappa(si));
      if (k > 1e-6) vmax = std::min(vmax, std::sqrt(config.lat_accel_max_mps2 / k));
      v[i] = std::clamp(vmax, config.v_min_mps, config.v_max_mps);
    }
    for (int i = n - 2; i >= 0; --i)
      v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2 * config.brake_max_mps2 * speed_step_m_));
    for (int i = 1; i < n; ++i)
      v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2 * config.accel_max_mps2 * speed_step_m_));
    for (int pass = 0; pass < 3; ++pass) {  // box filter 3x ~ gaussian, keeps the start speed
      std::vector<double> w(n);
      const int r = 8;
      for (int i = 0; i < n; ++i) {
        double acc = 0;
        for (int j = -r; j <= r; ++j) acc += v[std::clamp(i + j, 0, n - 1)];
        w[i] = acc / (2 * r + 1);
      }
      v.swap(w);
    }
    for (auto& x : v) x = std::clamp(x, config.v_min_mps, config.v_max_mps);
  }
  speed_ = std::move(v);
}

Route::Route(const TrackGeometry& track) : track_(track), length_m_(track.s_end - track.s_begin) {
  if (!(length_m_ > 0)) throw kitti::Error("synth route: the track is empty");
}

void Route::TrackAt(double s, Eigen::Vector2d* p, Eigen::Vector2d* d1, Eigen::Vector2d* d2) const {
  const double x = track_->s_begin + s;
  double e = 0, n = 0, de = 0, dn = 0, d2e = 0, d2n = 0;
  track_->east.Eval(x, p ? &e : nullptr, &de, d2 ? &d2e : nullptr);
  track_->north.Eval(x, p ? &n : nullptr, &dn, d2 ? &d2n : nullptr);
  if (p) *p = Eigen::Vector2d(e, n);
  if (d1) *d1 = Eigen::Vector2d(de, dn);
  if (d2) *d2 = Eigen::Vector2d(d2e, d2n);
}

const Route::Piece& Route::PieceAt(double s) const {
  auto it = std::upper_bound(pieces_.begin(), pieces_.end(), s,
                             [](double x, const Piece& p) { return x < p.s0; });
  if (it == pieces_.begin()) return pieces_.front();
  return *(it - 1);
}

double Route::Kappa(double s) const {
  if (track_) {
    Eigen::Vector2d d1, d2;
    TrackAt(s, nullptr, &d1, &d2);
    return (d1.x() * d2.y() - d1.y() * d2.x()) / std::pow(d1.squaredNorm(), 1.5);
  }
  const Piece& p = PieceAt(s);
  if (p.kappa == 0) return 0;
  const double x = s - p.s0;
  if (x < p.ramp_m) return p.kappa * Smooth(std::max(0.0, x / p.ramp_m));
  if (x < p.ramp_m + p.arc_m) return p.kappa;
  const double u = std::min(1.0, (x - p.ramp_m - p.arc_m) / p.ramp_m);
  return p.kappa * (1 - Smooth(u));
}

double Route::Heading(double s) const {
  if (track_) {
    Eigen::Vector2d d1;
    TrackAt(s, nullptr, &d1, nullptr);
    return std::atan2(d1.y(), d1.x());
  }
  const Piece& p = PieceAt(s);
  if (p.kappa == 0) return p.heading0;
  const double x = std::min(s - p.s0, p.length());
  if (x <= 0) return p.heading0;
  if (x < p.ramp_m) return p.heading0 + p.kappa * p.ramp_m * SmoothIntegral(x / p.ramp_m);
  if (x < p.ramp_m + p.arc_m) return p.heading0 + p.kappa * (0.5 * p.ramp_m + x - p.ramp_m);
  const double u = (x - p.ramp_m - p.arc_m) / p.ramp_m;
  return p.heading0 + p.kappa * (0.5 * p.ramp_m + p.arc_m + p.ramp_m * (u - SmoothIntegral(u)));
}

Eigen::Vector2d Route::Center(double s) const {
  if (track_) {
    Eigen::Vector2d p, d1;
    TrackAt(s, &p, &d1, nullptr);
    return p + track_->center_shift_m * Eigen::Vector2d(-d1.y(), d1.x()).normalized();
  }
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
  const int last = static_cast<int>(knots_.size()) - 1;
  const int i = std::clamp(static_cast<int>(std::floor(s / knot_step_m_)), 0, last);
  const double a = i * knot_step_m_;
  if (s == a) return knots_[i];
  Eigen::Vector2d acc = Eigen::Vector2d::Zero();
  for (int k = 0; k < 4; ++k) {
    const double h = Heading(0.5 * (a + s) + 0.5 * (s - a) * gx[k]);
    acc += gw[k] * Eigen::Vector2d(std::cos(h), std::sin(h));
  }
  return knots_[i] + 0.5 * (s - a) * acc;
}

double Route::Elevation(double s) const {
  if (track_) return track_->road_height(track_->s_begin + s);
  double z = 0;
  for (const auto& w : hills_) z += w.amp_m * (std::sin(w.omega * s + w.phase) - std::sin(w.phase));
  return z;
}

double Route::Grade(double s) const {
  if (track_) {
    double g = 0;
    track_->road_height.Eval(track_->s_begin + s, nullptr, &g, nullptr);
    return g;
  }
  double g = 0;
  for (const auto& w : hills_) g += w.amp_m * w.omega * std::cos(w.omega * s + w.phase);
  return g;
}

namespace {
// Catmull-Rom on a uniform grid, value and derivative.
void CatmullRom(const std::vector<double>& y, double step, double s, double* value, double* slope) {
  const int n = static_cast<int>(y.size());
  const double x = std::clamp(s / step, 0.0, n - 1.000001);
  const int i = static_cast<int>(x);
  const double u = x - i;
  auto at = [&](int k) { return y[std::clamp(k, 0, n - 1)]; };
  const double p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
  const double m1 = 0.5 * (p2 - p0), m2 = 0.5 * (p3 - p1);
  const double u2 = u * u, u3 = u2 * u;
  if (value)
    *value = (2 * u3 - 3 * u2 + 1) * p1 + (u3 - 2 * u2 + u) * m1 + (-2 * u3 + 3 * u2) * p2 + (u3 - u2) * m2;
  if (slope)
    *slope = ((6 * u2 - 6 * u) * p1 + (3 * u2 - 4 * u + 1) * m1 + (-6 * u2 + 6 * u) * p2 + (3 * u2 - 2 * u) * m2) / step;
}
}  // namespace

double Route::Speed(double s) const {
  if (track_) return 0;
  double v = 0;
  CatmullRom(speed_, speed_step_m_, s, &v, nullptr);
  return v;
}
double Route::SpeedSlope(double s) const {
  if (track_) return 0;
  double d = 0;
  CatmullRom(speed_, speed_step_m_, s, nullptr, &d);
  return d;
}

Eigen::Vector3d Route::Point(double s, double d, double h) const {
  const Eigen::Vector2d c = Center(s);
  const double psi = Heading(s);
  return Eigen::Vector3d(c.x() - d * std::sin(psi), c.y() + d * std::cos(psi), Elevation(s) + h);
}

// ---------------------------------------------------------------------------

VehicleMotion::VehicleMotion(const Route& route, const MotionConfig& config, uint64_t seed,
                             double duration_s)
    : route_(route), cfg_(config), duration_s_(duration_s) {
  const int n = static_cast<int>(std::ceil(duration_s / dt_)) + 3;
  s_.resize(n); v_.resize(n); a_.resize(n);
  double s = 0;
  const double s_max = route.length_m() - 1;
  auto f = [&](double x) { return route.Speed(std::min(x, s_max)); };
  for (int k = 0; k < n; ++k) {
    s_[k] = s;
    v_[k] = f(s);
    a_[k] = v_[k] * route.SpeedSlope(std::min(s, s_max));
    const double k1 = f(s), k2 = f(s + 0.5 * dt_ * k1), k3 = f(s + 0.5 * dt_ * k2), k4 = f(s + dt_ * k3);
    s += dt_ / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  InitDynamics(seed);
}

VehicleMotion::VehicleMotion(const Route& route, const MotionConfig& config, uint64_t seed, double dt_s,
                             std::vector<double> s, std::vector<double> v, std::vector<double> a)
    : route_(route), cfg_(config), dt_(dt_s), s_(std::move(s)), v_(std::move(v)), a_(std::move(a)) {
  if (!route.follows_track()) throw kitti::Error("synth motion: a measured progress needs a Route on a track");
  if (s_.size() < 2 || v_.size() != s_.size() || a_.size() != s_.size() || !(dt_ > 0))
    throw kitti::Error("synth motion: the progress needs 2+ samples of s, v and a and dt > 0");
  duration_s_ = dt_ * static_cast<double>(s_.size() - 1);
  InitDynamics(seed);
}

void VehicleMotion::InitDynamics(uint64_t seed) {
  Rng rng(seed, 2);
  auto make = [&](std::vector<Osc>& o, double amp) {
    for (int i = 0; i < 3; ++i)
      o.push_back({amp * rng.Uniform(0.4, 0.8), 2 * kPi * rng.Uniform(1.0, 2.8), rng.Uniform(0, 2 * kPi)});
  };
  make(heave_, cfg_.heave_amp_m);
  make(pitch_vib_, cfg_.pitch_vib_amp_rad);
  make(roll_vib_, cfg_.roll_vib_amp_rad);
  wander_phase_[0] = rng.Uniform(0, 2 * kPi);
  wander_phase_[1] = rng.Uniform(0, 2 * kPi);
}

namespace {
struct Quintic { double p, v, a; };
Quintic EvalQuintic(double p0, double v0, double a0, double p1, double v1, double a1, double h, double u) {
  const double u2 = u * u, u3 = u2 * u, u4 = u3 * u, u5 = u4 * u;
  const double H0 = 1 - 10 * u3 + 15 * u4 - 6 * u5, H1 = u - 6 * u3 + 8 * u4 - 3 * u5,
               H2 = 0.5 * u2 - 1.5 * u3 + 1.5 * u4 - 0.5 * u5, H3 = 0.5 * u3 - u4 + 0.5 * u5,
               H4 = -4 * u3 + 7 * u4 - 3 * u5, H5 = 10 * u3 - 15 * u4 + 6 * u5;
  const double D0 = -30 * u2 + 60 * u3 - 30 * u4, D1 = 1 - 18 * u2 + 32 * u3 - 15 * u4,
               D2 = u - 4.5 * u2 + 6 * u3 - 2.5 * u4, D3 = 1.5 * u2 - 4 * u3 + 2.5 * u4,
               D4 = -12 * u2 + 28 * u3 - 15 * u4, D5 = 30 * u2 - 60 * u3 + 30 * u4;
  const double E0 = -60 * u + 180 * u2 - 120 * u3, E1 = -36 * u + 96 * u2 - 60 * u3,
               E2 = 1 - 9 * u + 18 * u2 - 10 * u3, E3 = 3 * u - 12 * u2 + 10 * u3,
               E4 = -24 * u + 84 * u2 - 60 * u3, E5 = 60 * u - 180 * u2 + 120 * u3;
  Quintic q;
  q.p = H0 * p0 + H1 * h * v0 + H2 * h * h * a0 + H3 * h * h * a1 + H4 * h * v1 + H5 * p1;
  q.v = (D0 * p0 + D1 * h * v0 + D2 * h * h * a0 + D3 * h * h * a1 + D4 * h * v1 + D5 * p1) / h;
  q.a = (E0 * p0 + E1 * h * v0 + E2 * h * h * a0 + E3 * h * h * a1 + E4 * h * v1 + E5 * p1) / (h * h);
  return q;
}
}  // namespace

#define LOCAID_SYNTH_QUINTIC(t)                                                        \
  const int n = static_cast<int>(s_.size());                                           \
  const double x = std::clamp((t) / dt_, 0.0, n - 1.000001);                           \
  const int i = static_cast<int>(x);                                                   \
  const Quintic q = EvalQuintic(s_[i], v_[i], a_[i], s_[i + 1], v_[i + 1], a_[i + 1], dt_, x - i)

double VehicleMotion::S(double t) const { LOCAID_SYNTH_QUINTIC(t); return q.p; }
double VehicleMotion::SpeedAt(double t) const { LOCAID_SYNTH_QUINTIC(t); return q.v; }
double VehicleMotion::AccelAt(double t) const { LOCAID_SYNTH_QUINTIC(t); return q.a; }
#undef LOCAID_SYNTH_QUINTIC

double VehicleMotion::TimeAtS(double s) const {
  auto it = std::lower_bound(s_.begin(), s_.end(), s);
  if (it == s_.end()) return -1;
  if (it == s_.begin()) return 0;
  const int k = static_cast<int>(it - s_.begin());
  const double frac = (s - s_[k - 1]) / std::max(1e-12, s_[k] - s_[k - 1]);
  return (k - 1 + frac) * dt_;
}

double VehicleMotion::LaneOffset(double s) const {
  return cfg_.lane_offset_m + 0.10 * std::sin(2 * kPi * s / 97.0 + wander_phase_[0]) +
         0.05 * std::sin(2 * kPi * s / 41.0 + wander_phase_[1]);
}
double VehicleMotion::LaneOffsetSlope(double s) const {
  return 0.10 * 2 * kPi / 97.0 * std::cos(2 * kPi * s / 97.0 + wander_phase_[0]) +
         0.05 * 2 * kPi / 41.0 * std::cos(2 * kPi * s / 41.0 + wander_phase_[1]);
}

Eigen::Isometry3d VehicleMotion::T_enu_imu(double t) const {
  const double s = S(t), v = SpeedAt(t), a = AccelAt(t);
  // On a track the vehicle keeps to it (no lane wander), and its body stops
  // vibrating as it stops (vib: 0 at rest, ~1 above a few m/s; 1 otherwise).
  const bool track = route_.follows_track();
  const double d = track ? cfg_.lane_offset_m : LaneOffset(s), dd = track ? 0.0 : LaneOffsetSlope(s);
  const double vib = track ? v * v / (v * v + kVibrationSpeed2) : 1.0;
  const double kappa = route_.Kappa(s), psi = route_.Heading(s);
  const Eigen::Vector2d c = route_.Center(s);
  auto osc = [t](const std::vector<Osc>& o) {
    double x = 0;
    for (const auto& e : o) x += e.amp * std::sin(e.omega * t + e.phase);
    return x;
  };
  const double yaw = psi + std::atan2(dd, 1 - kappa * d);
  const double pitch = -std::atan(route_.Grade(s)) - cfg_.pitch_per_accel * a + vib * osc(pitch_vib_);
  const double roll = cfg_.roll_per_lat_accel * v * v * kappa + vib * osc(roll_vib_);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = AttitudeFromRpy(roll, pitch, yaw);
  T.translation() = Eigen::Vector3d(c.x() - d * std::sin(psi), c.y() + d * std::cos(psi),
                                    route_.Elevation(s) + cfg_.imu_height_m + vib * osc(heave_));
  return T;
}

ImuKinematics KinematicsAt(const VehicleMotion& motion, double t, double gravity_mps2) {
  const double h = 0.005;
  const Eigen::Isometry3d Tm = motion.T_enu_imu(t - h), T0 = motion.T_enu_imu(t),
                          Tp = motion.T_enu_imu(t + h);
  ImuKinematics k;
  k.T_enu_imu = T0;
  k.v_enu_mps = (Tp.translation() - Tm.translation()) / (2 * h);
  const Eigen::Vector3d a_enu =
      (Tp.translation() - 2 * T0.translation() + Tm.translation()) / (h * h);
  k.f_imu_mps2 = T0.linear().transpose() * (a_enu + Eigen::Vector3d(0, 0, gravity_mps2));
  const Eigen::AngleAxisd aa(Tm.linear().transpose() * Tp.linear());
  k.w_imu_radps = aa.axis() * aa.angle() / (2 * h);
  return k;
}

Eigen::Matrix3d AttitudeFromRpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d RollPitchYaw(const Eigen::Matrix3d& R) {
  const double pitch = -std::asin(std::clamp(R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

}  // namespace locaid::synth
