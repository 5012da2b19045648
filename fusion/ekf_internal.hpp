// Shared by the EKF's translation units (ekf*.cpp, *_process_model.cpp):
// the error-state layout and two small helpers. Not part of the public API.
#pragma once

#include <Eigen/Core>

#include <cstdint>

namespace locaid::fusion::detail {

inline constexpr double kNsPerS = 1e9;
// IMU layout: p v theta ba bg, clone p_c theta_c, VO boresight (3) and scale (1).
inline constexpr int kP = 0, kV = 3, kTh = 6, kBa = 9, kBg = 12, kPc = 15, kThc = 18, kCal = 21;

inline double Seconds(int64_t a_ns, int64_t b_ns) { return static_cast<double>(a_ns - b_ns) / kNsPerS; }
inline void Symmetrize(Eigen::MatrixXd& P) { P = 0.5 * (P + P.transpose()).eval(); }

}  // namespace locaid::fusion::detail
