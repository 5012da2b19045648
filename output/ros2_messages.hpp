// The ROS 2 messages of a session's poses, one CDR encoder per message: what
// a ROS 2 bag of the poses holds (ros2_recording.*) and what locaid-ros2
// publishes live over DDS (ros2/), byte for byte the same. docs/api.md "ROS 2
// output" maps every field; frames follow REP-103/105 and their names are
// the caller's (Ros2Frames). Each Encode* resets the writer and writes one
// message; stamps are the sensor time they describe (negative: 0).
#pragma once

#include "locaid/v1/localization.pb.h"
#include "output/cdr_writer.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace locaid::output {

// Variance written where locaid has no estimate (the twist: the API carries
// no velocity covariance and no angular velocity), and for a pose without
// a 36-value covariance: "unknown", as the filter itself reports before it
// is initialised (1e6 on the diagonal).
inline constexpr double kRos2UnknownVariance = 1e6;

struct Ros2Frames {
  std::string map = "map";              // the filter's ENU frame (origin: the first accepted GPS fix)
  std::string body = "base_link";       // the body / IMU frame: x forward, y left, z up
  std::string camera = "camera_left";   // the left rectified camera, optical (x right, y down, z forward)
  std::string gps = "gps";              // the GPS antenna
};

// nav_msgs/msg/Odometry: map -> body, pose with covariance (RosPoseCovariance),
// twist in body axes (linear from velocity_enu_mps; angular 0 and the twist
// covariance kRos2UnknownVariance: the API carries neither).
void EncodeOdometry(const v1::PoseUpdate& pose, const Ros2Frames& frames, CdrWriter& w);
// sensor_msgs/msg/NavSatFix of the fused position (covariance KNOWN: the
// ENU block). False, and nothing written, while the pose is LOST.
bool EncodeFusedFix(const v1::PoseUpdate& pose, const Ros2Frames& frames, CdrWriter& w);
// tf2_msgs/msg/TFMessage: map -> body, the pose.
void EncodeTf(const v1::PoseUpdate& pose, const Ros2Frames& frames, CdrWriter& w);
// tf2_msgs/msg/TFMessage: body -> camera (the rig), stamped t_ns.
void EncodeCameraTf(int64_t t_ns, const Eigen::Isometry3d& T_body_cam0, const Ros2Frames& frames, CdrWriter& w);
// sensor_msgs/msg/NavSatFix of one GPS fix the filter saw, stamped with its
// own time; diag(sigma_h^2, sigma_h^2, sigma_v^2) (DIAGONAL_KNOWN).
void EncodeGpsFixSeen(const v1::GpsFixSeen& fix, const Ros2Frames& frames, CdrWriter& w);

// diagnostic_msgs/msg/DiagnosticStatus.
struct DiagnosticStatus {
  static constexpr uint8_t kOk = 0, kWarn = 1, kError = 2;
  uint8_t level = kOk;
  std::string name, message, hardware_id;
  std::vector<std::pair<std::string, std::string>> values;
};
// diagnostic_msgs/msg/DiagnosticArray of `statuses`, header frame "".
void EncodeDiagnosticArray(int64_t t_ns, const std::vector<DiagnosticStatus>& statuses, CdrWriter& w);
// The "locaid" status of a pose (docs/api.md "ROS 2 output"): level by
// mode, message = mode, hardware_id = session id, the PoseUpdate's fields.
DiagnosticStatus PoseStatus(const v1::PoseUpdate& pose);

// The conversions, free functions for the tests.
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// The symmetric positive semi-definite matrix nearest to `m` (Frobenius
// norm): symmetrised, negative eigenvalues raised to 0.
Matrix6d NearestSymmetricPsd(const Matrix6d& m);

// The filter's covariance of [position E, N, U; attitude error about E, N,
// U] (a left perturbation R = Exp(dtheta) R_hat in ENU axes) as ROS
// PoseWithCovariance wants it in the `map` frame: (x, y, z, rotation about
// X, Y, Z) in the fixed-axis (roll, pitch, yaw) representation of
// R_enu_body = Rz(yaw) Ry(pitch) Rx(roll). J P J^T with J = diag(I, E^-1),
// where E maps (d roll, d pitch, d yaw) to dtheta. Within 1e-6 of pitch
// +-90 deg (gimbal lock, where E is singular) J = I.
Matrix6d RosPoseCovariance(const Matrix6d& P_filter, const Eigen::Quaterniond& q_enu_body);
// The 3x3 Jacobian d(roll, pitch, yaw) / d(dtheta in ENU axes) of the above.
Eigen::Matrix3d RpyFromEnuAttitudeJacobian(const Eigen::Matrix3d& R_enu_body);

}  // namespace locaid::output
