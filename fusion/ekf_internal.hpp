// Shared by the EKF's translation units (ekf*.cpp, *_process_model.cpp):
// the error-state layout and two small helpers. Not part of the public API.
#pragma once

#include <Eigen/Core>

#include <cstdint>

namespace locaid::fusion::detail {

inline constexpr double kNsPerS = 1e9;
// IMU layout: p v theta ba bg, clone p_c theta_c, VO boresight (3) and scale
// (1), the vehicle speed sensor's scale error (1).
inline constexpr int kP = 0, kV = 3, kTh = 6, kBa = 9, kBg = 12, kPc = 15, kThc = 18, kCal = 21, kSpd = 25;
inline constexpr int kSpeedStates = 1;

inline double Seconds(int64_t a_ns, int64_t b_ns) { return static_cast<double>(a_ns - b_ns) / kNsPerS; }
inline void Symmetrize(Eigen::MatrixXd& P) { P = 0.5 * (P + P.transpose()).eval(); }

// One gated measurement update: residual r = z - h(x), H = dh/d(dx), noise R.
// When the normalised innovation squared is finite and below `gate` (gate <=
// 0: no gate), P takes the Joseph-form update and dx is the correction to
// apply; otherwise P is untouched.
struct GatedCorrection {
  double nis = 0;
  bool accepted = false;
  Eigen::VectorXd dx;
};
GatedCorrection GatedKalmanUpdate(Eigen::MatrixXd& P, const Eigen::MatrixXd& H, const Eigen::MatrixXd& R,
                                  const Eigen::VectorXd& r, double gate);

}  // namespace locaid::fusion::detail
