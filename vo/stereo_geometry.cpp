#include "vo/stereo_geometry.hpp"
#include "core/stereo_camera.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace locaid::vo {

Eigen::Isometry3d ExpSE3(const Vector6d& delta) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d phi = delta.tail<3>();
  const double angle = phi.norm();
  if (angle > 1e-12) T.linear() = Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
  T.translation() = delta.head<3>();
  return T;
}

Vector6d LogSE3(const Eigen::Isometry3d& T) {
  Vector6d out;
  out.head<3>() = T.translation();
  const Eigen::AngleAxisd aa(T.rotation());
  out.tail<3>() = aa.angle() * aa.axis();
  return out;
}

Eigen::Isometry3d ScaleMotion(const Eigen::Isometry3d& T, double s) {
  return ExpSE3(s * LogSE3(T));
}

bool IsFinite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

Matrix6d LargeCovariance() { return Matrix6d::Identity(); }

Eigen::Vector3d TriangulateStereo(const StereoCamera& camera, double u_left, double v_left,
                                  double u_right) {
  const double disparity = u_left - u_right;
  const double z = camera.fx * camera.baseline_m / disparity;
  return {(u_left - camera.cx) * z / camera.fx, (v_left - camera.cy) * z / camera.fy, z};
}

int ProjectRows(const StereoCamera& cam, const Eigen::Vector3d& q,
                const Eigen::Vector2d& uv_left, double u_right, bool has_right,
                double min_depth_m, Eigen::Ref<Eigen::Vector3d> r, Eigen::Matrix3d& dproj) {
  if (!(q.z() > min_depth_m)) return 0;
  const double iz = 1.0 / q.z();
  dproj << cam.fx * iz, 0, -cam.fx * q.x() * iz * iz,  //
      0, cam.fy * iz, -cam.fy * q.y() * iz * iz,       //
      cam.fx * iz, 0, -cam.fx * (q.x() - cam.baseline_m) * iz * iz;
  r(0) = cam.fx * q.x() * iz + cam.cx - uv_left.x();
  r(1) = cam.fy * q.y() * iz + cam.cy - uv_left.y();
  r(2) = cam.fx * (q.x() - cam.baseline_m) * iz + cam.cx - u_right;
  return has_right ? 3 : 2;
}

namespace {

struct Linearization {
  Matrix6d H = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  double weighted_sq = 0;
  int rows = 0;
  int inliers = 0;
};

using Rows = Eigen::Matrix<double, 6, 1>;
using RowsJ = Eigen::Matrix<double, 6, 6>;

// Residual rows of one observation at T_ref_curr and their Jacobians w.r.t.
// delta (T_ref_curr * Exp(delta)): the forward rows (p_ref in the current
// images) first, then, when reverse and ob.has_reverse, the rows of p_curr in
// the reference images. Returns the row count (0: forward point behind).
int Residuals(const StereoObservation& ob, const StereoCamera& cam,
              const Eigen::Isometry3d& T_ref_curr, const Eigen::Isometry3d& T_curr_ref,
              double min_depth_m, bool reverse, Rows& r, RowsJ& J) {
  Eigen::Matrix3d dproj;
  const Eigen::Vector3d q = T_curr_ref * ob.p_ref;
  int rows = ProjectRows(cam, q, ob.uv_left, ob.u_right, ob.has_right, min_depth_m,
                         r.segment<3>(0), dproj);
  if (rows == 0) return 0;
  // d q / d delta = [-I, [q]x].
  Eigen::Matrix<double, 3, 6> dq;
  dq.leftCols<3>() = -Eigen::Matrix3d::Identity();
  dq.rightCols<3>() << 0, -q.z(), q.y(), q.z(), 0, -q.x(), -q.y(), q.x(), 0;
  J.topRows<3>() = dproj * dq;
  if (!(reverse && ob.has_reverse)) return rows;
  // Reverse: s = T_ref_curr * p_curr; d s / d delta = R [I, -[p_curr]x].
  const Eigen::Vector3d s = T_ref_curr * ob.p_curr;
  Eigen::Vector3d rr;
  const int rev = ProjectRows(cam, s, ob.uv_ref_left, ob.u_ref_right, true, min_depth_m, rr, dproj);
  if (rev == 0) return rows;
  const Eigen::Vector3d& p = ob.p_curr;
  Eigen::Matrix<double, 3, 6> ds;
  ds.leftCols<3>() = Eigen::Matrix3d::Identity();
  ds.rightCols<3>() << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;
  ds = T_ref_curr.linear() * ds;
  // Forward rows are compacted to `rows`; reverse rows follow.
  r.segment<3>(rows) = rr;
  J.middleRows<3>(rows) = dproj * ds;
  return rows + 3;
}

double MaxAbs(const Rows& r, int rows) {
  double m = 0;
  for (int k = 0; k < rows; ++k) m = std::max(m, std::abs(r(k)));
  return m;
}

Linearization Linearize(const std::vector<StereoObservation>& obs, const std::vector<char>& use,
                        const StereoCamera& cam, const Eigen::Isometry3d& T_ref_curr,
                        const RefineOptions& opt, bool reverse) {
  Linearization lin;
  const Eigen::Isometry3d T_curr_ref = T_ref_curr.inverse();
  Rows r;
  RowsJ J;
  for (size_t i = 0; i < obs.size(); ++i) {
    if (!use[i]) continue;
    const int rows = Residuals(obs[i], cam, T_ref_curr, T_curr_ref, opt.min_depth_m, reverse, r, J);
    if (rows == 0) continue;
    ++lin.inliers;
    for (int k = 0; k < rows; ++k) {
      const double a = std::abs(r(k));
      const double w = a <= opt.huber_px ? 1.0 : opt.huber_px / a;
      lin.H.noalias() += w * J.row(k).transpose() * J.row(k);
      lin.b.noalias() -= w * J.row(k).transpose() * r(k);
      lin.weighted_sq += w * r(k) * r(k);
      ++lin.rows;
    }
  }
  return lin;
}

Matrix6d CovarianceFrom(const Linearization& lin, const RefineOptions& opt, double* sigma_px) {
  const int dof = std::max(lin.rows - 6, 1);
  const double sigma2 = std::max(lin.weighted_sq / dof, opt.min_sigma_px * opt.min_sigma_px);
  if (sigma_px) *sigma_px = std::sqrt(sigma2);
  Eigen::LDLT<Matrix6d> ldlt(lin.H);
  if (ldlt.info() != Eigen::Success || lin.rows < 6) return LargeCovariance();
  Matrix6d cov = sigma2 * ldlt.solve(Matrix6d::Identity());
  cov = 0.5 * (cov + cov.transpose());
  if (!cov.allFinite() || cov.diagonal().minCoeff() <= 0) return LargeCovariance();
  return cov;
}

}  // namespace

PoseRefinement RefineStereoPose(const std::vector<StereoObservation>& obs,
                                const StereoCamera& cam,
                                const Eigen::Isometry3d& T_ref_curr_init,
                                const RefineOptions& opt) {
  PoseRefinement out;
  out.T_ref_curr = T_ref_curr_init;
  std::vector<char> use(obs.size(), 1);
  Eigen::Isometry3d T = T_ref_curr_init;
  Linearization lin;
  for (int round = 0; round < opt.rounds; ++round) {
    // Inlier selection at the current estimate.
    const Eigen::Isometry3d T_curr_ref = T.inverse();
    Rows r;
    RowsJ J;
    for (size_t i = 0; i < obs.size(); ++i) {
      const int rows = Residuals(obs[i], cam, T, T_curr_ref, opt.min_depth_m, opt.reverse, r, J);
      use[i] = rows > 0 && MaxAbs(r, rows) <= opt.outlier_px * (round == 0 ? 2.0 : 1.0);
    }
    for (int it = 0; it < opt.iterations; ++it) {
      lin = Linearize(obs, use, cam, T, opt, opt.reverse);
      if (lin.inliers < 3) return out;
      const Vector6d delta = lin.H.ldlt().solve(lin.b);
      if (!delta.allFinite()) return out;
      T = T * ExpSE3(delta);
      if (delta.head<3>().norm() < 1e-7 && delta.tail<3>().norm() < 1e-8) break;
    }
  }
  // Final inlier set and linearisation at the solution.
  {
    const Eigen::Isometry3d T_curr_ref = T.inverse();
    Rows r;
    RowsJ J;
    for (size_t i = 0; i < obs.size(); ++i) {
      const int rows = Residuals(obs[i], cam, T, T_curr_ref, opt.min_depth_m, opt.reverse, r, J);
      use[i] = rows > 0 && MaxAbs(r, rows) <= opt.outlier_px;
    }
  }
  // Covariance from the forward rows only: the reverse rows reuse the same
  // pixels, so counting them would halve the variance without new information.
  lin = Linearize(obs, use, cam, T, opt, false);
  if (!IsFinite(T) || lin.inliers < 3) return out;
  out.T_ref_curr = T;
  out.inlier = use;
  out.inliers = lin.inliers;
  out.covariance = CovarianceFrom(lin, opt, &out.sigma_px);
  out.ok = true;
  return out;
}

Matrix6d PoseCovariance(const std::vector<StereoObservation>& obs, const StereoCamera& cam,
                        const Eigen::Isometry3d& T_ref_curr, const RefineOptions& opt) {
  const std::vector<char> use(obs.size(), 1);
  const Linearization lin = Linearize(obs, use, cam, T_ref_curr, opt, false);
  return CovarianceFrom(lin, opt, nullptr);
}

}  // namespace locaid::vo
