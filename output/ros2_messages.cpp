#include "output/ros2_messages.hpp"

#include "output/enum_names.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace locaid::output {
namespace {

// sensor_msgs/msg/NavSatStatus and NavSatFix constants.
constexpr int8_t kStatusFix = 0;
constexpr uint16_t kServiceGps = 1;
constexpr uint8_t kCovarianceDiagonalKnown = 2;
constexpr uint8_t kCovarianceKnown = 3;

void PutTime(CdrWriter& w, int64_t t_ns) {  // builtin_interfaces/msg/Time
  const int64_t t = std::max<int64_t>(t_ns, 0);
  w.Int32(static_cast<int32_t>(t / 1'000'000'000));
  w.Uint32(static_cast<uint32_t>(t % 1'000'000'000));
}

void PutHeader(CdrWriter& w, int64_t t_ns, const std::string& frame_id) {  // std_msgs/msg/Header
  PutTime(w, t_ns);
  w.String(frame_id);
}

void PutXyz(CdrWriter& w, double x, double y, double z) {  // Point or Vector3
  w.Float64(x);
  w.Float64(y);
  w.Float64(z);
}

void PutQuaternion(CdrWriter& w, const Eigen::Quaterniond& q) {  // x, y, z, w
  w.Float64(q.x());
  w.Float64(q.y());
  w.Float64(q.z());
  w.Float64(q.w());
}

void PutMatrix(CdrWriter& w, const double* row_major, int n) {
  for (int i = 0; i < n; ++i) w.Float64(row_major[i]);
}

// The pose's orientation, normalised (identity when it is not a rotation).
Eigen::Quaterniond Orientation(const v1::PoseUpdate& p) {
  Eigen::Quaterniond q(p.orientation_enu_body().w(), p.orientation_enu_body().x(), p.orientation_enu_body().y(),
                       p.orientation_enu_body().z());
  if (!(q.norm() > 1e-9) || !q.coeffs().allFinite()) return Eigen::Quaterniond::Identity();
  return q.normalized();
}

Eigen::Vector3d Position(const v1::PoseUpdate& p) {
  return {p.position_enu_m().x(), p.position_enu_m().y(), p.position_enu_m().z()};
}

Matrix6d FilterCovariance(const v1::PoseUpdate& p) {
  if (p.covariance_size() != 36) return Matrix6d::Identity() * kRos2UnknownVariance;
  Matrix6d P;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) P(r, c) = p.covariance(r * 6 + c);
  }
  return P.allFinite() ? P : Matrix6d::Identity() * kRos2UnknownVariance;
}

// A TFMessage of one geometry_msgs/msg/TransformStamped.
void PutTfMessage(CdrWriter& w, int64_t t_ns, const std::string& parent, const std::string& child,
                  const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
  w.Reset();
  w.SequenceLength(1);
  PutHeader(w, t_ns, parent);
  w.String(child);
  PutXyz(w, t.x(), t.y(), t.z());
  PutQuaternion(w, q);
}

void PutNavSatFix(CdrWriter& w, int64_t t_ns, const std::string& frame, double lat, double lon, double alt,
                  const Eigen::Matrix3d& cov, uint8_t covariance_type) {
  w.Reset();
  PutHeader(w, t_ns, frame);
  w.Int8(kStatusFix);
  w.Uint16(kServiceGps);
  w.Float64(lat);
  w.Float64(lon);
  w.Float64(alt);
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> row_major = cov;
  PutMatrix(w, row_major.data(), 9);
  w.Uint8(covariance_type);
}

std::string Number(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", v);
  return text;
}

uint8_t Level(v1::Mode mode) {
  switch (mode) {
    case v1::MODE_GPS_FUSED: return DiagnosticStatus::kOk;
    case v1::MODE_GPS_DEGRADED:
    case v1::MODE_VO_ONLY:
    case v1::MODE_DEAD_RECKONING: return DiagnosticStatus::kWarn;
    default: return DiagnosticStatus::kError;  // LOST, UNSPECIFIED
  }
}

// What the gate did with one fix: "fused", "fused, vertical refused", "refused".
std::string GateResult(const v1::GpsFixSeen& f) {
  if (!f.used()) return "refused";
  return f.rejected_vertical() ? "fused, vertical refused" : "fused";
}

}  // namespace

Matrix6d NearestSymmetricPsd(const Matrix6d& m) {
  const Matrix6d symmetric = 0.5 * (m + m.transpose());
  Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(symmetric);
  if (eigen.info() != Eigen::Success || eigen.eigenvalues().minCoeff() >= 0) return symmetric;
  const Eigen::Matrix<double, 6, 1> clipped = eigen.eigenvalues().cwiseMax(0.0);
  const Matrix6d psd = eigen.eigenvectors() * clipped.asDiagonal() * eigen.eigenvectors().transpose();
  return 0.5 * (psd + psd.transpose());
}

Eigen::Matrix3d RpyFromEnuAttitudeJacobian(const Eigen::Matrix3d& R) {
  // R = Rz(yaw) Ry(pitch) Rx(roll); a change of the angles rotates by
  // dtheta = E (d roll, d pitch, d yaw) in ENU axes with the columns of E
  // Rz Ry e_x, Rz e_y, e_z. Its inverse in closed form:
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double cy = std::cos(yaw), sy = std::sin(yaw), cp = std::cos(pitch), sp = std::sin(pitch);
  if (std::abs(cp) < 1e-6) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d J;
  J << cy / cp, sy / cp, 0,  //
      -sy, cy, 0,            //
      sp * cy / cp, sp * sy / cp, 1;
  return J;
}

Matrix6d RosPoseCovariance(const Matrix6d& P_filter, const Eigen::Quaterniond& q_enu_body) {
  Matrix6d J = Matrix6d::Identity();
  J.block<3, 3>(3, 3) = RpyFromEnuAttitudeJacobian(q_enu_body.normalized().toRotationMatrix());
  return NearestSymmetricPsd(J * P_filter * J.transpose());
}

void EncodeOdometry(const v1::PoseUpdate& p, const Ros2Frames& frames, CdrWriter& w) {
  const Eigen::Quaterniond q = Orientation(p);
  const Eigen::Vector3d position = Position(p);
  w.Reset();
  PutHeader(w, p.t_ns(), frames.map);
  w.String(frames.body);
  PutXyz(w, position.x(), position.y(), position.z());
  PutQuaternion(w, q);
  const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> pose_cov = RosPoseCovariance(FilterCovariance(p), q);
  PutMatrix(w, pose_cov.data(), 36);
  const Eigen::Vector3d v_body =
      q.conjugate() * Eigen::Vector3d(p.velocity_enu_mps().x(), p.velocity_enu_mps().y(), p.velocity_enu_mps().z());
  PutXyz(w, v_body.x(), v_body.y(), v_body.z());
  PutXyz(w, 0, 0, 0);  // angular velocity: not in the API
  const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> twist_cov = Matrix6d::Identity() * kRos2UnknownVariance;
  PutMatrix(w, twist_cov.data(), 36);
}

bool EncodeFusedFix(const v1::PoseUpdate& p, const Ros2Frames& frames, CdrWriter& w) {
  // None while LOST (before initialisation, or coasting).
  if (p.mode() == v1::MODE_LOST || p.mode() == v1::MODE_UNSPECIFIED) return false;
  PutNavSatFix(w, p.t_ns(), frames.body, p.latitude_deg(), p.longitude_deg(), p.altitude_m(),
               NearestSymmetricPsd(FilterCovariance(p)).block<3, 3>(0, 0), kCovarianceKnown);
  return true;
}

void EncodeTf(const v1::PoseUpdate& p, const Ros2Frames& frames, CdrWriter& w) {
  PutTfMessage(w, p.t_ns(), frames.map, frames.body, Position(p), Orientation(p));
}

void EncodeCameraTf(int64_t t_ns, const Eigen::Isometry3d& T_body_cam0, const Ros2Frames& frames, CdrWriter& w) {
  PutTfMessage(w, t_ns, frames.body, frames.camera, T_body_cam0.translation(),
               Eigen::Quaterniond(T_body_cam0.rotation()));
}

void EncodeGpsFixSeen(const v1::GpsFixSeen& f, const Ros2Frames& frames, CdrWriter& w) {
  const double h2 = f.sigma_horizontal_m() * f.sigma_horizontal_m();
  const double v2 = f.sigma_vertical_m() * f.sigma_vertical_m();
  PutNavSatFix(w, f.t_ns(), frames.gps, f.latitude_deg(), f.longitude_deg(), f.altitude_m(),
               Eigen::Vector3d(h2, h2, v2).asDiagonal(), kCovarianceDiagonalKnown);
}

void EncodeDiagnosticArray(int64_t t_ns, const std::vector<DiagnosticStatus>& statuses, CdrWriter& w) {
  w.Reset();
  PutHeader(w, t_ns, "");
  w.SequenceLength(statuses.size());
  for (const DiagnosticStatus& s : statuses) {
    w.Uint8(s.level);
    w.String(s.name);
    w.String(s.message);
    w.String(s.hardware_id);
    w.SequenceLength(s.values.size());
    for (const auto& [key, value] : s.values) {
      w.String(key);
      w.String(value);
    }
  }
}

DiagnosticStatus PoseStatus(const v1::PoseUpdate& p) {
  DiagnosticStatus s;
  s.level = Level(p.mode());
  s.name = "locaid";
  s.message = ModeName(p.mode());
  s.hardware_id = p.session_id();
  int fused = 0;
  for (const auto& f : p.gps_fixes()) fused += f.used() ? 1 : 0;
  s.values = {
      {"mode", ModeName(p.mode())},
      {"session_id", p.session_id()},
      {"sequence", std::to_string(p.sequence())},
      {"frame_index", std::to_string(p.frame_index())},
      {"vo_status", VoStatusName(p.vo_status())},
      {"vo_health", VoHealthName(p.vo_health())},
      {"vo_inliers", std::to_string(p.vo_inliers())},
      {"gps_outage_active", p.gps_outage_active() ? "true" : "false"},
      {"seconds_since_gps", Number(p.seconds_since_gps())},
      {"gps_used", std::to_string(p.gps_used())},
      {"gps_rejected", std::to_string(p.gps_rejected())},
      {"gps_resets", std::to_string(p.gps_resets())},
      {"gps_fixes_seen", std::to_string(p.gps_fixes_size())},
      {"gps_fixes_fused", std::to_string(fused)},
      {"gps_fixes_refused", std::to_string(p.gps_fixes_size() - fused)},
  };
  if (p.gps_fixes_size() > 0) {
    const v1::GpsFixSeen& last = p.gps_fixes(p.gps_fixes_size() - 1);
    s.values.insert(s.values.end(), {{"gps_last_fix_t_ns", std::to_string(last.t_ns())},
                                     {"gps_last_fix_gate", GateResult(last)},
                                     {"gps_last_fix_nis", Number(last.nis())},
                                     {"gps_last_fix_gate_threshold", Number(last.gate())}});
  }
  std::string vo_scale;
  for (double v : p.noise().vo_scale()) vo_scale += (vo_scale.empty() ? "" : " ") + Number(v);
  s.values.insert(s.values.end(), {{"vo_noise_scale", vo_scale},
                                   {"gps_noise_scale_horizontal", Number(p.noise().gps_horizontal_scale())},
                                   {"gps_noise_scale_vertical", Number(p.noise().gps_vertical_scale())},
                                   {"vo_noise_learning", p.noise().vo_learning() ? "true" : "false"}});
  s.values.insert(s.values.end(), {{"speed_scale_error", Number(p.speed_scale_error())},
                                   {"speed_samples_used", std::to_string(p.speed_samples_used())},
                                   {"processing_latency_ms", Number(p.processing_latency_ms())},
                                   {"behind_real_time_s", Number(p.behind_real_time_s())},
                                   {"falling_behind", p.falling_behind() ? "true" : "false"}});
  if (p.has_truth()) s.values.emplace_back("horizontal_error_m", Number(p.horizontal_error_m()));
  return s;
}

}  // namespace locaid::output
