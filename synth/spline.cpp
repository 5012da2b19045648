#include "synth/spline.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace locaid::synth {
namespace {

// The interval of x (first of its four coefficients) and the parameter in it.
void Locate(double x0, double h, int n, double x, int* i, double* u) {
  const double t = std::clamp((x - x0) / h, 0.0, static_cast<double>(n - 3));
  *i = std::min(static_cast<int>(std::floor(t)), n - 4);
  *u = t - *i;
}

void Weights(double u, double b[4]) {
  const double v = 1 - u, u2 = u * u, u3 = u2 * u;
  b[0] = v * v * v / 6;
  b[1] = (3 * u3 - 6 * u2 + 4) / 6;
  b[2] = (-3 * u3 + 3 * u2 + 3 * u + 1) / 6;
  b[3] = u3 / 6;
}

using SparseMatrix = Eigen::SparseMatrix<double>;
using Triplets = std::vector<Eigen::Triplet<double>>;

Eigen::VectorXd Solve(const SparseMatrix& A, const Eigen::VectorXd& b) {
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(A);
  if (ldlt.info() != Eigen::Success) throw std::invalid_argument("spline fit: singular normal equations");
  return ldlt.solve(b);
}

// Least squares with the coefficients tied in runs (group[j]: the run of
// coefficient j, non-decreasing and contiguous). monotone: runs are merged
// wherever the solution decreases, until it does not.
Eigen::VectorXd SolveTied(const SparseMatrix& A, const Eigen::VectorXd& b, std::vector<int> group, bool monotone) {
  const int m = static_cast<int>(b.size());
  int groups = group.back() + 1;
  for (;;) {
    Triplets t;
    t.reserve(static_cast<size_t>(A.nonZeros()));
    for (int k = 0; k < A.outerSize(); ++k)
      for (SparseMatrix::InnerIterator it(A, k); it; ++it)
        t.emplace_back(group[static_cast<size_t>(it.row())], group[static_cast<size_t>(it.col())], it.value());
    SparseMatrix Ag(groups, groups);
    Ag.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd bg = Eigen::VectorXd::Zero(groups);
    for (int j = 0; j < m; ++j) bg(group[static_cast<size_t>(j)]) += b(j);
    const Eigen::VectorXd g = Solve(Ag, bg);
    std::vector<int> relabel(static_cast<size_t>(groups));
    int next = 0;
    for (int k = 0; k < groups; ++k) {
      if (k > 0 && (!monotone || g(k) >= g(k - 1))) ++next;
      relabel[static_cast<size_t>(k)] = next;
    }
    if (next + 1 == groups) {
      Eigen::VectorXd c(m);
      for (int j = 0; j < m; ++j) c(j) = g(group[static_cast<size_t>(j)]);
      return c;
    }
    for (int& gj : group) gj = relabel[static_cast<size_t>(gj)];
    groups = next + 1;
  }
}

// The runs constant_on asks for: on [a, b] count the coefficients of the
// intervals from a's to b's.
std::vector<int> InitialGroups(const SplineFit& fit) {
  const int m = fit.n_coefficients;
  std::vector<char> tie_next(static_cast<size_t>(m), 0);
  for (const auto& [a, b] : fit.constant_on) {
    int ia = 0, ib = 0;
    double u = 0;
    Locate(fit.x0, fit.h, m, a, &ia, &u);
    Locate(fit.x0, fit.h, m, b, &ib, &u);
    for (int j = ia; j < std::min(ib + 3, m - 1); ++j) tie_next[static_cast<size_t>(j)] = 1;
  }
  std::vector<int> group(static_cast<size_t>(m));
  for (int j = 0, g = 0; j < m; ++j) {
    group[static_cast<size_t>(j)] = g;
    if (!tie_next[static_cast<size_t>(j)]) ++g;
  }
  return group;
}

}  // namespace

UniformCubicSpline::UniformCubicSpline(double x0, double h, std::vector<double> coefficients)
    : x0_(x0), h_(h), c_(std::move(coefficients)) {
  if (c_.size() < 4 || !(h_ > 0)) throw std::invalid_argument("UniformCubicSpline: needs h > 0 and 4+ coefficients");
}

double UniformCubicSpline::x_max() const { return x0_ + h_ * (static_cast<double>(c_.size()) - 3); }

double UniformCubicSpline::operator()(double x) const {
  double f = 0;
  Eval(x, &f, nullptr, nullptr);
  return f;
}

void UniformCubicSpline::Eval(double x, double* f, double* df, double* d2f) const {
  int i = 0;
  double u = 0;
  Locate(x0_, h_, static_cast<int>(c_.size()), x, &i, &u);
  const double* c = c_.data() + i;
  if (f) {
    double b[4];
    Weights(u, b);
    *f = c[0] * b[0] + c[1] * b[1] + c[2] * b[2] + c[3] * b[3];
  }
  if (df) {
    const double v = 1 - u;
    *df = (-c[0] * v * v + c[1] * (3 * u * u - 4 * u) + c[2] * (-3 * u * u + 2 * u + 1) + c[3] * u * u) / (2 * h_);
  }
  if (d2f) *d2f = (c[0] * (1 - u) + c[1] * (3 * u - 2) + c[2] * (1 - 3 * u) + c[3] * u) / (h_ * h_);
}

std::vector<UniformCubicSpline> FitSplines(const std::vector<double>& x,
                                           const std::vector<std::vector<double>>& ys,
                                           const std::vector<double>& w, const SplineFit& fit) {
  const int m = fit.n_coefficients;
  if (m < 4 || !(fit.h > 0)) throw std::invalid_argument("spline fit: needs h > 0 and 4+ coefficients");
  if (!w.empty() && w.size() != x.size()) throw std::invalid_argument("spline fit: weights and x differ in size");
  for (const auto& y : ys)
    if (y.size() != x.size()) throw std::invalid_argument("spline fit: x and y differ in size");
  Triplets t;
  t.reserve(16 * (x.size() + static_cast<size_t>(m)));
  std::vector<Eigen::VectorXd> rhs(ys.size(), Eigen::VectorXd::Zero(m));
  for (size_t k = 0; k < x.size(); ++k) {
    int i = 0;
    double u = 0, b[4];
    Locate(fit.x0, fit.h, m, x[k], &i, &u);
    Weights(u, b);
    const double wk = w.empty() ? 1.0 : w[k];
    for (int a = 0; a < 4; ++a) {
      for (int c = 0; c < 4; ++c) t.emplace_back(i + a, i + c, wk * b[a] * b[c]);
      for (size_t ch = 0; ch < ys.size(); ++ch) rhs[ch](i + a) += wk * b[a] * ys[ch][k];
    }
  }
  const double d[4] = {-1, 3, -3, 1};  // third difference
  if (!fit.lambda_scale.empty() && fit.lambda_scale.size() != static_cast<size_t>(m - 3))
    throw std::invalid_argument("spline fit: lambda_scale needs n_coefficients - 3 values");
  for (int r = 0; r + 3 < m && fit.lambda > 0; ++r) {
    const double lambda = fit.lambda * (fit.lambda_scale.empty() ? 1.0 : fit.lambda_scale[static_cast<size_t>(r)]);
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 4; ++c) t.emplace_back(r + a, r + c, lambda * d[a] * d[c]);
  }
  SparseMatrix A(m, m);
  A.setFromTriplets(t.begin(), t.end());
  std::vector<UniformCubicSpline> out;
  std::vector<Eigen::VectorXd> coefficients;
  if (fit.monotone || !fit.constant_on.empty()) {
    for (const Eigen::VectorXd& b : rhs) coefficients.push_back(SolveTied(A, b, InitialGroups(fit), fit.monotone));
  } else {
    Eigen::SimplicialLDLT<SparseMatrix> ldlt(A);
    if (ldlt.info() != Eigen::Success) throw std::invalid_argument("spline fit: singular normal equations");
    for (const Eigen::VectorXd& b : rhs) coefficients.push_back(ldlt.solve(b));
  }
  for (const Eigen::VectorXd& c : coefficients)
    out.emplace_back(fit.x0, fit.h, std::vector<double>(c.data(), c.data() + c.size()));
  return out;
}

}  // namespace locaid::synth
