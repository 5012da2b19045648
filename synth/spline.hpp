// Cubic B-splines on uniform knots and their penalised least-squares fit
// (P-splines, Eilers & Marx): the smooth functions a measured route is
// turned into (synth/route_file.hpp), so that positions, velocities and
// accelerations are exact derivatives of one C2 function.
#pragma once

#include <utility>
#include <vector>

namespace locaid::synth {

// f(x) = sum_j c_j B((x - x0) / h - j + 1), B the cubic B-spline basis: on
// the interval [x0 + i h, x0 + (i + 1) h] the coefficients c_i .. c_i+3 count.
// Defined on [x_min, x_max] = [x0, x0 + (n - 3) h] (n coefficients); outside,
// x is clamped to it. C2: value, slope and curvature are continuous.
class UniformCubicSpline {
 public:
  UniformCubicSpline() = default;
  UniformCubicSpline(double x0, double h, std::vector<double> coefficients);

  double x_min() const { return x0_; }
  double x_max() const;
  double h() const { return h_; }
  const std::vector<double>& coefficients() const { return c_; }

  double operator()(double x) const;
  // Value and the first two derivatives at x (any pointer may be null).
  void Eval(double x, double* f, double* df, double* d2f) const;

 private:
  double x0_ = 0, h_ = 1;
  std::vector<double> c_;
};

struct SplineFit {
  double x0 = 0, h = 1;  // knots x0 + j h
  int n_coefficients = 4;
  // Roughness penalty: lambda * sum of squared third differences of the
  // coefficients. A third-order penalty leaves quadratics (constant
  // acceleration, constant curvature) unbiased; the smoothing length is about
  // h * (lambda / data points per knot)^(1/6).
  double lambda = 0;
  // Per third difference r (coefficients r .. r+3; n_coefficients - 3 of
  // them): a factor on lambda there. Empty: 1 everywhere.
  std::vector<double> lambda_scale;
  // Non-decreasing coefficients, hence a non-decreasing function (runs of
  // equal coefficients: the function is constant where only they count).
  bool monotone = false;
  // Intervals [a, b] of x on which the function is constant (the
  // coefficients that count there are one).
  std::vector<std::pair<double, double>> constant_on;
};

// Fits one spline per channel to (x[i], ys[c][i]) with weights w (empty: 1),
// minimising sum w (f(x) - y)^2 + lambda * penalty. Every x must lie in the
// spline's range. Throws std::invalid_argument for mismatched sizes or fewer
// than 4 coefficients.
std::vector<UniformCubicSpline> FitSplines(const std::vector<double>& x,
                                           const std::vector<std::vector<double>>& ys,
                                           const std::vector<double>& w, const SplineFit& fit);

}  // namespace locaid::synth
