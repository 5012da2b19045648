// Measurement noise learned from the filter's own innovations (covariance
// matching). A sensor's noise model R0 (the VO model of Ekf::VoNoise, a GPS
// fix's stated sigma) is multiplied per axis by a learned scale lambda. For an
// innovation r_i with predicted variance (H P H')_ii,
//   E[r_i^2] = (H P H')_ii + lambda_i R0_ii,
// so each innovation gives a sample (r_i^2 - (H P H')_ii) / R0_ii of lambda_i.
// The samples are averaged, each weighted by the information it carries
// about lambda ((lambda R0_ii / total)^2, in units of an exactly predicted
// sample: when the prediction dominates the innovation the sample
// says little): the prior (lambda = 1, the model as configured) counts as
// prior_samples samples, then an exponential average over about
// window_samples of them forgets old ones. Each r_i^2 is clipped at clip_sigmas^2
// times its current predicted total (an outlier moves the scale by a bounded
// step; the clipping's bias on Gaussian innovations is divided out), and the
// scale stays within [min_scale, max_scale].
//
// Callers decide when the samples are trustworthy: the filter learns the VO
// noise only while GPS holds the state (an outage would teach it its own
// drift) and the GPS noise only while its prediction is not much looser than
// the fix.
#pragma once

#include <Eigen/Core>

namespace locaid::fusion {

struct NoiseScaleConfig {
  double prior_samples = 30;
  double window_samples = 300;
  double min_scale = 0.01;
  double max_scale = 100;
  double clip_sigmas = 3.0;
};

class NoiseScaleEstimator {
 public:
  NoiseScaleEstimator(int axes, NoiseScaleConfig config);

  // One innovation component of axis `axis`: residual r, its predicted part
  // (H P H')_ii and the model's variance R0_ii (> 0). Non-finite or
  // non-positive inputs are ignored.
  void Add(int axis, double r, double predicted_var, double model_var);

  // lambda per axis (1 until samples arrive).
  const Eigen::VectorXd& scale() const { return scale_; }
  double scale(int axis) const { return scale_[axis]; }
  // Samples taken per axis so far.
  const Eigen::VectorXd& samples() const { return samples_; }

 private:
  NoiseScaleConfig config_;
  double clip_correction_ = 1;  // E[min(z^2, c^2)] for z ~ N(0, 1)
  Eigen::VectorXd mean_, scale_, samples_;
  Eigen::VectorXd weight_;  // the weight behind mean_: the prior's, then the samples', at most the window
};

}  // namespace locaid::fusion
