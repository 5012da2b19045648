#include "vo/window_ba.hpp"
#include "core/stereo_camera.hpp"

#include "vo/stereo_geometry.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace locaid::vo {
namespace {

using Matrix63d = Eigen::Matrix<double, 6, 3>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;

// Linearised residual of one observation: r = predicted - measured (rows u, v,
// u_right; the last row is zero for a left-only observation).
struct Linearised {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  Eigen::Matrix3d J_pc = Eigen::Matrix3d::Zero();  // d r / d p_c
  Eigen::Vector3d p_c = Eigen::Vector3d::Zero();
  bool valid = false;
};

Linearised Linearise(const WindowObservation& o, const Eigen::Isometry3d& T_c_w,
                     const Eigen::Vector3d& p_w, const StereoCamera& cam,
                     double min_depth_m) {
  Linearised l;
  l.p_c = T_c_w * p_w;
  if (!l.p_c.allFinite()) return l;
  const int rows = ProjectRows(cam, l.p_c, o.uv_left, o.u_right, o.has_right, min_depth_m, l.r, l.J_pc);
  if (rows == 0) return l;
  if (rows == 2) {  // left only: the u_right row does not count
    l.r(2) = 0;
    l.J_pc.row(2).setZero();
  }
  l.valid = true;
  return l;
}

double HuberWeight(double e, double k) { return e <= k ? 1.0 : k / e; }
double HuberCost(double e, double k) { return e <= k ? e * e : 2 * k * e - k * k; }

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

struct State {
  std::vector<Eigen::Isometry3d> T_c_w;
  std::vector<Eigen::Vector3d> p_w;
};

class Solver {
 public:
  Solver(const WindowProblem& problem, const StereoCamera& cam, const WindowOptions& opt)
      : problem_(problem), cam_(cam), opt_(opt) {
    const int frames = static_cast<int>(problem.T_w_c.size());
    fixed_ = std::clamp(problem.fixed_frames, 0, frames);
    n_poses_ = frames - fixed_;
    // Points seen from at least two distinct frames carry pose information.
    std::vector<int> first_frame(problem.p_w.size(), -1);
    std::vector<char> multi(problem.p_w.size(), 0);
    for (const WindowObservation& o : problem.observations) {
      int& f = first_frame[static_cast<size_t>(o.point)];
      if (f < 0) f = o.frame;
      else if (f != o.frame) multi[static_cast<size_t>(o.point)] = 1;
    }
    std::vector<int> point_slot(problem.p_w.size(), -1);  // point -> slot, -1 when unused
    for (size_t i = 0; i < problem.observations.size(); ++i) {
      const WindowObservation& o = problem.observations[i];
      if (!multi[static_cast<size_t>(o.point)]) continue;
      int& slot = point_slot[static_cast<size_t>(o.point)];
      if (slot < 0) {
        slot = static_cast<int>(point_obs_.size());
        point_obs_.emplace_back();
        points_.push_back(o.point);
      }
      point_obs_[static_cast<size_t>(slot)].push_back(static_cast<int>(i));
    }
    used_observations_ = 0;
    for (const auto& v : point_obs_) used_observations_ += static_cast<int>(v.size());
  }

  int points_used() const { return static_cast<int>(points_.size()); }
  int observations_used() const { return used_observations_; }

  double Cost(const State& s) const {
    double cost = 0;
    for (const auto& obs : point_obs_)
      for (int i : obs) {
        const WindowObservation& o = problem_.observations[static_cast<size_t>(i)];
        const Linearised l = Linearise(o, s.T_c_w[static_cast<size_t>(o.frame)],
                                       s.p_w[static_cast<size_t>(o.point)], cam_, opt_.min_depth_m);
        if (l.valid) cost += HuberCost(l.r.norm(), opt_.huber_px);
      }
    return cost;
  }

  // Builds the normal equations at s (Huber weights), then solves the damped
  // system; returns false when it is singular or not finite.
  void Build(const State& s) {
    const int np = 6 * n_poses_;
    H_pp_.setZero(np, np);
    b_p_.setZero(np);
    H_ll_.assign(points_.size(), Eigen::Matrix3d::Zero());
    b_l_.assign(points_.size(), Eigen::Vector3d::Zero());
    H_pl_.assign(points_.size(), {});
    for (size_t k = 0; k < points_.size(); ++k) {
      const int pt = points_[k];
      for (int i : point_obs_[k]) {
        const WindowObservation& o = problem_.observations[static_cast<size_t>(i)];
        const Eigen::Isometry3d& T = s.T_c_w[static_cast<size_t>(o.frame)];
        const Linearised l = Linearise(o, T, s.p_w[static_cast<size_t>(pt)], cam_, opt_.min_depth_m);
        if (!l.valid) continue;
        const double w = HuberWeight(l.r.norm(), opt_.huber_px);
        const Eigen::Matrix3d J_l = l.J_pc * T.linear();
        H_ll_[k] += w * J_l.transpose() * J_l;
        b_l_[k] += w * J_l.transpose() * l.r;
        if (o.frame < fixed_) continue;
        Matrix36d dpc_dxi;
        dpc_dxi << Eigen::Matrix3d::Identity(), -Skew(l.p_c);
        const Matrix36d J_p = l.J_pc * dpc_dxi;
        const int c = 6 * (o.frame - fixed_);
        H_pp_.block<6, 6>(c, c) += w * J_p.transpose() * J_p;
        b_p_.segment<6>(c) += w * J_p.transpose() * l.r;
        H_pl_[k].emplace_back(o.frame - fixed_, w * J_p.transpose() * J_l);
      }
    }
  }

  bool Solve(double lambda, Eigen::VectorXd& d_pose, std::vector<Eigen::Vector3d>& d_point) const {
    const int np = 6 * n_poses_;
    Eigen::MatrixXd S = H_pp_;
    for (int i = 0; i < np; ++i) S(i, i) += lambda * S(i, i) + 1e-9;
    Eigen::VectorXd rhs = -b_p_;
    std::vector<Eigen::Matrix3d> H_ll_inv(points_.size());
    for (size_t k = 0; k < points_.size(); ++k) {
      Eigen::Matrix3d H = H_ll_[k];
      for (int i = 0; i < 3; ++i) H(i, i) += lambda * H(i, i) + 1e-9;
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(H);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
      H_ll_inv[k] = ldlt.solve(Eigen::Matrix3d::Identity());
      const auto& blocks = H_pl_[k];
      for (const auto& [fa, Ha] : blocks) {
        const Matrix63d HaHinv = Ha * H_ll_inv[k];
        rhs.segment<6>(6 * fa) += HaHinv * b_l_[k];
        for (const auto& [fb, Hb] : blocks) S.block<6, 6>(6 * fa, 6 * fb) -= HaHinv * Hb.transpose();
      }
    }
    d_pose.setZero(np);
    if (np > 0) {
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
      d_pose = ldlt.solve(rhs);
      if (!d_pose.allFinite()) return false;
    }
    d_point.assign(points_.size(), Eigen::Vector3d::Zero());
    for (size_t k = 0; k < points_.size(); ++k) {
      Eigen::Vector3d r = -b_l_[k];
      for (const auto& [f, H] : H_pl_[k]) r -= H.transpose() * d_pose.segment<6>(6 * f);
      d_point[k] = H_ll_inv[k] * r;
      if (!d_point[k].allFinite()) return false;
    }
    return true;
  }

  State Apply(const State& s, const Eigen::VectorXd& d_pose,
              const std::vector<Eigen::Vector3d>& d_point) const {
    State n = s;
    for (int f = 0; f < n_poses_; ++f)
      n.T_c_w[static_cast<size_t>(fixed_ + f)] =
          ExpSE3(d_pose.segment<6>(6 * f)) * s.T_c_w[static_cast<size_t>(fixed_ + f)];
    for (size_t k = 0; k < points_.size(); ++k)
      n.p_w[static_cast<size_t>(points_[k])] += d_point[k];
    return n;
  }

 private:
  const WindowProblem& problem_;
  const StereoCamera& cam_;
  const WindowOptions& opt_;
  int fixed_ = 0, n_poses_ = 0, used_observations_ = 0;
  std::vector<int> points_;                     // slot -> point
  std::vector<std::vector<int>> point_obs_;     // slot -> observation indices
  Eigen::MatrixXd H_pp_;
  Eigen::VectorXd b_p_;
  std::vector<Eigen::Matrix3d> H_ll_;
  std::vector<Eigen::Vector3d> b_l_;
  std::vector<std::vector<std::pair<int, Matrix63d>>> H_pl_;
};

}  // namespace

WindowResult SolveWindow(WindowProblem& problem, const StereoCamera& camera,
                         const WindowOptions& options) {
  WindowResult result;
  result.outlier.assign(problem.observations.size(), 0);
  for (const WindowObservation& o : problem.observations)
    if (o.frame < 0 || o.frame >= static_cast<int>(problem.T_w_c.size()) || o.point < 0 ||
        o.point >= static_cast<int>(problem.p_w.size()))
      return result;  // malformed: nothing changed
  Solver solver(problem, camera, options);
  result.points_used = solver.points_used();
  result.observations_used = solver.observations_used();

  State state;
  for (const Eigen::Isometry3d& T : problem.T_w_c) state.T_c_w.push_back(T.inverse());
  state.p_w = problem.p_w;
  double cost = solver.Cost(state);
  result.initial_cost = cost;
  double lambda = 1e-4;
  bool built = false;
  Eigen::VectorXd d_pose;
  std::vector<Eigen::Vector3d> d_point;
  for (int it = 0; it < options.iterations && result.points_used > 0; ++it) {
    ++result.iterations;
    if (!built) {
      solver.Build(state);
      built = true;
    }
    if (!solver.Solve(lambda, d_pose, d_point)) {
      lambda *= 10;
      continue;
    }
    State next = solver.Apply(state, d_pose, d_point);
    const double next_cost = solver.Cost(next);
    if (std::isfinite(next_cost) && next_cost <= cost) {
      const bool converged = cost - next_cost < 1e-6 * std::max(cost, 1e-12);
      state = std::move(next);
      cost = next_cost;
      built = false;
      lambda = std::max(lambda * 0.1, 1e-8);
      if (converged) break;
    } else {
      lambda *= 10;
    }
  }
  result.final_cost = cost;
  for (const Eigen::Isometry3d& T : state.T_c_w)
    if (!IsFinite(T)) return result;
  for (size_t f = 0; f < state.T_c_w.size(); ++f) problem.T_w_c[f] = state.T_c_w[f].inverse();
  problem.p_w = state.p_w;
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    const WindowObservation& o = problem.observations[i];
    const Linearised l = Linearise(o, state.T_c_w[static_cast<size_t>(o.frame)],
                                   state.p_w[static_cast<size_t>(o.point)], camera,
                                   options.min_depth_m);
    result.outlier[i] = !l.valid || l.r.norm() > options.outlier_px;
  }
  result.ok = true;
  return result;
}

}  // namespace locaid::vo
