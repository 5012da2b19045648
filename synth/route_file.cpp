#include "synth/route_file.hpp"

#include "kitti/pose_io.hpp"
#include "kitti/timestamps.hpp"
#include "kitti/types.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace locaid::synth {
namespace {

std::string Num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

// Anchors of the raw track: a pose becomes one when it lies this far from the
// previous anchor, so that standing still adds no length.
constexpr double kAnchorStepM = 0.5;
constexpr double kMinTrackM = 5.0;
// A stop: the poses' progress over +-kRestWindow poses is below kRestSpeed for
// kStopMinS or longer. The progress is held constant inside it, kStopSettleS
// from its ends (where the vehicle comes to rest and moves off, smoothly).
constexpr size_t kRestWindow = 3;
constexpr double kRestSpeed = 0.03, kStopMinS = 0.8, kStopSettleS = 0.2;

int Coefficients(double x0, double x1, double h) { return static_cast<int>(std::ceil((x1 - x0) / h)) + 3; }

}  // namespace

Eigen::Matrix3d EnuFromKittiWorld() {
  Eigen::Matrix3d R;
  R << 0, 0, 1,   // east  = forward (z)
      -1, 0, 0,   // north = left (-x)
      0, -1, 0;   // up    = -y
  return R;
}

RoutePoses ReadRoutePoses(const std::filesystem::path& poses_path, const std::filesystem::path& times_path) {
  std::vector<Eigen::Isometry3d> poses;
  try {
    poses = kitti::ReadKittiPoses(poses_path);
  } catch (const kitti::Error& e) {
    throw kitti::Error(std::string("synth: route poses: ") + e.what());
  }
  if (poses.size() < 2)
    throw kitti::Error("synth: route: " + poses_path.string() + " has " + std::to_string(poses.size()) +
                       " pose(s), fewer than 2");
  RoutePoses out;
  if (times_path.empty()) {
    for (size_t i = 0; i < poses.size(); ++i) out.t_s.push_back(0.1 * static_cast<double>(i));
  } else {
    try {
      out.t_s = kitti::ReadOdometryTimes(times_path);
    } catch (const kitti::Error& e) {
      throw kitti::Error(std::string("synth: route times: ") + e.what());
    }
    if (out.t_s.size() != poses.size())
      throw kitti::Error("synth: route: " + poses_path.string() + " has " + std::to_string(poses.size()) +
                         " poses but " + times_path.string() + " has " + std::to_string(out.t_s.size()) +
                         " times");
    for (size_t i = 1; i < out.t_s.size(); ++i)
      if (!(out.t_s[i] > out.t_s[i - 1]))  // times.txt has no blank line inside: line i + 1 is time i
        throw kitti::Error("synth: route times: " + times_path.string() + ":" + std::to_string(i + 1) + ": time " +
                           Num(out.t_s[i]) + " s is not after the previous one (" + Num(out.t_s[i - 1]) + " s)");
  }
  const Eigen::Matrix3d R = EnuFromKittiWorld();
  for (const Eigen::Isometry3d& T : poses) out.camera_enu.push_back(R * T.translation());
  return out;
}

RouteFit::RouteFit(const RoutePoses& poses, const RouteFitConfig& cfg) : t_(poses.t_s) {
  const size_t n = poses.camera_enu.size();
  std::vector<Eigen::Vector2d> q(n);
  std::vector<double> height(n);
  for (size_t i = 0; i < n; ++i) {
    q[i] = poses.camera_enu[i].head<2>();
    height[i] = poses.camera_enu[i].z() - cfg.camera_height_m;
  }
  // 1. Anchors: the raw track without the standing still.
  std::vector<Eigen::Vector2d> anchor{q[0]};
  std::vector<double> anchor_u{0.0};
  std::vector<size_t> last_anchor(n, 0);
  for (size_t i = 1; i < n; ++i) {
    const double d = (q[i] - anchor.back()).norm();
    if (d >= kAnchorStepM) {
      anchor_u.push_back(anchor_u.back() + d);
      anchor.push_back(q[i]);
    }
    last_anchor[i] = anchor.size() - 1;
  }
  const double length = anchor_u.back();
  if (length < kMinTrackM)
    throw kitti::Error("synth: route: the poses move " + Num(length) + " m horizontally, less than " +
                       Num(kMinTrackM) + " m");
  // 2. Each pose's place on the anchor polyline (the segments before and after its anchor).
  std::vector<double> us, east, north, heights;
  for (size_t i = 0; i < n; ++i) {
    double best = 1e300, u = 0;
    for (size_t k = last_anchor[i] == 0 ? 0 : last_anchor[i] - 1; k <= last_anchor[i] && k + 1 < anchor.size(); ++k) {
      const Eigen::Vector2d d = anchor[k + 1] - anchor[k];
      const double len = d.norm();
      const double f = std::clamp((q[i] - anchor[k]).dot(d) / (len * len), 0.0, 1.0);
      const double dist = (anchor[k] + f * d - q[i]).norm();
      if (dist < best) {
        best = dist;
        u = anchor_u[k] + f * len;
      }
    }
    us.push_back(u);
    east.push_back(q[i].x());
    north.push_back(q[i].y());
    heights.push_back(height[i]);
  }
  // 3. Straight lead-in and lead-out along the first and last 5 m.
  size_t a0 = 0, a1 = anchor.size() - 1;
  while (a0 + 1 < anchor.size() && anchor_u[a0] < kMinTrackM) ++a0;
  while (a1 > 0 && anchor_u[a1] > length - kMinTrackM) --a1;
  const Eigen::Vector2d dir_in = (anchor[a0] - anchor.front()).normalized();
  const Eigen::Vector2d dir_out = (anchor.back() - anchor[a1]).normalized();
  for (double k = 1; k <= cfg.lead_in_m; k += 1) {
    us.push_back(-k);
    const Eigen::Vector2d p = anchor.front() - k * dir_in;
    east.push_back(p.x());
    north.push_back(p.y());
    heights.push_back(height.front());
  }
  for (double k = 1; k <= cfg.lead_out_m; k += 1) {
    us.push_back(length + k);
    const Eigen::Vector2d p = anchor.back() + k * dir_out;
    east.push_back(p.x());
    north.push_back(p.y());
    heights.push_back(height.back());
  }
  // 4. Smooth track over u.
  SplineFit fit;
  fit.h = cfg.knot_m;
  fit.x0 = -cfg.lead_in_m - 2 * fit.h;
  fit.n_coefficients = Coefficients(fit.x0, length + cfg.lead_out_m + 2 * fit.h, fit.h);
  fit.lambda = std::pow(cfg.track_smoothing_m / cfg.knot_m, 6);
  // Faster stretches smoothed over longer distances: the lateral acceleration
  // (v^2 times the curvature) would carry the poses' noise times v^2. Each
  // penalty row gets the highest speed of the poses at it (the nearest
  // row's where none are), the smoothing length grows as speed^0.8 above
  // track_smoothing_speed_mps.
  {
    const size_t rows = static_cast<size_t>(fit.n_coefficients - 3);
    std::vector<double> row_speed(rows, -1);
    for (size_t i = 0; i < n; ++i) {
      const size_t a = i >= 2 ? i - 2 : 0, b = std::min(n - 1, i + 2);
      const double v = (us[b] - us[a]) / (t_[b] - t_[a]);
      const long r = std::lround((us[i] - fit.x0) / fit.h - 0.5);
      double& rv = row_speed[static_cast<size_t>(std::clamp(r, 0L, static_cast<long>(rows) - 1))];
      rv = std::max(rv, v);
    }
    for (size_t r = 1; r < rows; ++r)
      if (row_speed[r] < 0) row_speed[r] = row_speed[r - 1];
    for (size_t r = rows - 1; r-- > 0;)
      if (row_speed[r] < 0) row_speed[r] = row_speed[r + 1];
    for (double v : row_speed)
      fit.lambda_scale.push_back(std::pow(std::max(1.0, v / cfg.track_smoothing_speed_mps), 0.8 * 6));
  }
  const std::vector<UniformCubicSpline> en = FitSplines(us, {east, north}, {}, fit);
  fit.lambda = std::pow(cfg.height_smoothing_m / cfg.knot_m, 6);
  fit.lambda_scale.clear();
  const UniformCubicSpline h_u = FitSplines(us, {heights}, {}, fit).front();
  // 5. The same curve on its arc length s (s = 0 at u = 0): dense samples, refitted.
  auto speed = [&](double u) {
    double de = 0, dn = 0;
    en[0].Eval(u, nullptr, &de, nullptr);
    en[1].Eval(u, nullptr, &dn, nullptr);
    return std::hypot(de, dn);
  };
  const double du = 0.25, g = 0.5 / std::sqrt(3.0);
  std::vector<double> ss{0.0}, se, sn, sh;
  const double u_begin = -cfg.lead_in_m, u_end = length + cfg.lead_out_m;
  double s_at_zero = 0;
  for (double u = u_begin; u < u_end; u += du) {
    const double b = std::min(u + du, u_end);
    ss.push_back(ss.back() + 0.5 * (b - u) * (speed(u + (0.5 - g) * (b - u)) + speed(u + (0.5 + g) * (b - u))));
    if (u <= 0 && b > 0) s_at_zero = ss[ss.size() - 2] + (ss.back() - ss[ss.size() - 2]) * (0 - u) / (b - u);
  }
  std::vector<double> u_of(ss.size());
  for (size_t k = 0; k < ss.size(); ++k) {
    u_of[k] = std::min(u_begin + du * static_cast<double>(k), u_end);
    ss[k] -= s_at_zero;
    se.push_back(en[0](u_of[k]));
    sn.push_back(en[1](u_of[k]));
    sh.push_back(h_u(u_of[k]));
  }
  SplineFit refit;
  refit.h = 0.5 * cfg.knot_m;
  refit.x0 = std::floor(ss.front()) - refit.h;
  refit.n_coefficients = Coefficients(refit.x0, ss.back() + refit.h, refit.h);
  refit.lambda = 1e-6;
  std::vector<UniformCubicSpline> track = FitSplines(ss, {se, sn, sh}, {}, refit);
  track_.east = std::move(track[0]);
  track_.north = std::move(track[1]);
  track_.road_height = std::move(track[2]);
  track_.s_begin = ss.front();
  track_.s_end = ss.back();
  // 6. Each pose's s: from its u, then onto the track (Newton on (P(s) - q) . P'(s) = 0).
  for (size_t i = 0; i < n; ++i) {
    const auto it = std::upper_bound(u_of.begin(), u_of.end(), us[i]);
    const size_t k = std::clamp<size_t>(static_cast<size_t>(it - u_of.begin()), 1, u_of.size() - 1);
    double s = ss[k - 1] + (ss[k] - ss[k - 1]) * (us[i] - u_of[k - 1]) / (u_of[k] - u_of[k - 1]);
    for (int iter = 0; iter < 4; ++iter) {
      double e = 0, de = 0, d2e = 0, nn = 0, dn = 0, d2n = 0;
      track_.east.Eval(s, &e, &de, &d2e);
      track_.north.Eval(s, &nn, &dn, &d2n);
      const Eigen::Vector2d r(e - q[i].x(), nn - q[i].y());
      const double f = r.x() * de + r.y() * dn, df = de * de + dn * dn + r.x() * d2e + r.y() * d2n;
      if (!(df > 0.1)) break;
      s -= f / df;
    }
    pose_s_.push_back(std::clamp(s, track_.s_begin, track_.s_end));
  }
  // 7. Progress s(t): monotone, so the vehicle never backs up, and constant
  // inside every stop: a run of kStopMinS or longer of poses whose progress
  // over +-kRestWindow poses is below kRestSpeed.
  SplineFit pf;
  auto at_rest = [&](size_t i) {
    const size_t a = i >= kRestWindow ? i - kRestWindow : 0, b = std::min(n - 1, i + kRestWindow);
    return std::abs(pose_s_[b] - pose_s_[a]) < kRestSpeed * (t_[b] - t_[a]);
  };
  for (size_t i = 0; i < n;) {
    size_t j = i;
    while (j < n && at_rest(j)) ++j;
    if (j > i && t_[j - 1] - t_[i] >= kStopMinS) pf.constant_on.emplace_back(t_[i] + kStopSettleS, t_[j - 1] - kStopSettleS);
    i = j + 1;
  }
  pf.h = cfg.knot_s;
  pf.x0 = t_.front() - cfg.time_margin_s - pf.h;
  pf.n_coefficients = Coefficients(pf.x0, t_.back() + cfg.time_margin_s + pf.h, pf.h);
  pf.lambda = std::pow(cfg.time_smoothing_s / cfg.knot_s, 6);
  pf.monotone = true;
  progress_ = FitSplines(t_, {pose_s_}, {}, pf).front();
}

void RouteFit::Progress(double t, double* s, double* v, double* a) const { progress_.Eval(t, s, v, a); }

double RouteFit::S(double t) const { return progress_(t); }

double RouteFit::TimeAtS(double s, double t_from) const {
  constexpr double kStep = 0.01;
  double t0 = t_from;
  if (S(t0) >= s) return t0;
  for (double t1 = t0 + kStep; t0 < t_last(); t0 = t1, t1 += kStep) {
    t1 = std::min(t1, t_last());
    if (S(t1) >= s) {
      for (int i = 0; i < 40; ++i) {
        const double m = 0.5 * (t0 + t1);
        (S(m) >= s ? t1 : t0) = m;
      }
      return t1;
    }
  }
  return -1;
}

}  // namespace locaid::synth
