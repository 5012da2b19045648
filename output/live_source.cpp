#include "output/live_source.hpp"

namespace locaid::output {

v1::LiveSource LiveSourceOf(const StereoCamera& c, const Eigen::Isometry3d& T_cam0_imu) {
  v1::LiveSource l;
  l.set_fx(c.fx);
  l.set_fy(c.fy);
  l.set_cx(c.cx);
  l.set_cy(c.cy);
  l.set_baseline_m(c.baseline_m);
  l.set_width(c.width);
  l.set_height(c.height);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) l.add_t_cam0_imu(T_cam0_imu.matrix()(r, k));
  return l;
}

}  // namespace locaid::output
