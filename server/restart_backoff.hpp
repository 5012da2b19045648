// How long a live session's reader waits before it tries its device again:
// the gpsd connection (GpsdFeeder) and the cameras' pipelines
// (CameraFeeder). 0.5 s after a failure, doubling with every failure in a
// row up to 5 s; 0.5 s again once the device delivered.
#pragma once

#include <algorithm>

namespace locaid::server {

class RestartBackoff {
 public:
  static constexpr double kFirstS = 0.5, kMaxS = 5.0;

  double wait_s() const { return wait_s_; }
  void Failed() { wait_s_ = std::min(kMaxS, 2 * wait_s_); }  // the next wait doubles
  void Delivered() { wait_s_ = kFirstS; }                    // back to the first wait

 private:
  double wait_s_ = kFirstS;
};

}  // namespace locaid::server
