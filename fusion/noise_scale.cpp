#include "fusion/noise_scale.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace locaid::fusion {

namespace {

// E[min(z^2, c^2)] for z ~ N(0, 1): P(|z| < c) - 2 c phi(c) + c^2 P(|z| >= c).
double ClippedSquareMean(double c) {
  if (!(c > 0) || !std::isfinite(c)) return 1.0;
  const double inside = std::erf(c / std::numbers::sqrt2);
  const double phi = std::exp(-0.5 * c * c) / std::sqrt(2 * std::numbers::pi);
  return inside - 2 * c * phi + c * c * (1 - inside);
}

}  // namespace

NoiseScaleEstimator::NoiseScaleEstimator(int axes, NoiseScaleConfig config)
    : config_(config),
      clip_correction_(ClippedSquareMean(config.clip_sigmas)),
      mean_(Eigen::VectorXd::Ones(axes)),
      scale_(Eigen::VectorXd::Ones(axes)),
      samples_(Eigen::VectorXd::Zero(axes)),
      weight_(Eigen::VectorXd::Constant(axes, std::max(0.0, config.prior_samples))) {
  config_.min_scale = std::max(1e-9, config_.min_scale);
  config_.max_scale = std::max(config_.min_scale, config_.max_scale);
  config_.window_samples = std::max(1.0, config_.window_samples);
  config_.prior_samples = std::max(0.0, config_.prior_samples);
  scale_ = mean_.cwiseMax(config_.min_scale).cwiseMin(config_.max_scale);
}

void NoiseScaleEstimator::Add(int axis, double r, double predicted_var, double model_var) {
  if (axis < 0 || axis >= scale_.size()) return;
  if (!std::isfinite(r) || !std::isfinite(predicted_var) || !std::isfinite(model_var)) return;
  if (model_var <= 0 || predicted_var < 0) return;
  // The innovation's variance as the filter predicts it now, and r^2 clipped
  // at clip_sigmas of it (unbiased again for Gaussian innovations).
  const double total = predicted_var + scale_[axis] * model_var;
  const double c2 = config_.clip_sigmas * config_.clip_sigmas;
  const double r2 = config_.clip_sigmas > 0 ? std::min(r * r, c2 * total) / clip_correction_ : r * r;
  const double sample = (r2 - predicted_var) / model_var;
  // A sample's weight is its information about lambda relative to one whose
  // prediction is exact ((model / total)^2, at most 1): when the prediction
  // dominates the innovation the sample says little about the sensor.
  const double weight = std::pow(scale_[axis] * model_var / total, 2);
  samples_[axis] += 1;
  if (!(weight > 0)) return;
  weight_[axis] = std::min(weight_[axis] + weight, config_.window_samples);
  // The mean itself stays within the bounds, so that a long run at a bound
  // does not take as long to undo.
  mean_[axis] =
      std::clamp(mean_[axis] + weight / weight_[axis] * (sample - mean_[axis]), config_.min_scale, config_.max_scale);
  scale_[axis] = mean_[axis];
}

}  // namespace locaid::fusion
