// The stereo camera model every module shares (vo/, the datasets of kitti/,
// the synthetic renderer, the server's sessions). Names: core/README.md.
#pragma once

namespace locaid {

// Rectified stereo pinhole pair: both cameras share fx, fy, cx, cy (pixels);
// the right camera sits baseline_m along +x of the left one (cam0).
struct StereoCamera {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double baseline_m = 0;
  int width = 0, height = 0;
};

}  // namespace locaid
