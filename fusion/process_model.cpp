// Choosing the process model, and the VO noise both models share.
#include "fusion/process_model.hpp"

#include "fusion/ekf.hpp"

#include <algorithm>
#include <cmath>

namespace locaid::fusion {

std::unique_ptr<ProcessModel> MakeProcessModel(const EkfConfig& config) {
  return config.imu.enabled ? MakeImuProcessModel(config) : MakeOdometryProcessModel(config);
}

Mat6 ScaledVoNoise(const EkfConfig& config, const Mat6& reported, const Vec3& sigma_rel) {
  Mat6 Rvo = reported * config.vo.cov_scale;
  for (int i = 0; i < 3; ++i) {
    Rvo(i, i) += sigma_rel[i] * sigma_rel[i];
    Rvo(i, i) = std::max(Rvo(i, i), std::pow(config.vo.min_sigma_t_m, 2));
    Rvo(i + 3, i + 3) = std::max(Rvo(i + 3, i + 3), std::pow(config.vo.min_sigma_rot_rad, 2));
  }
  return Rvo;
}

}  // namespace locaid::fusion
