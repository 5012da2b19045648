#include "server/live_source_request.hpp"

#include "ros/camera_info_yaml.hpp"
#include "ros/camera_model.hpp"
#include "server/quoted.hpp"

#include <cmath>
#include <sstream>
#include <utility>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;

bool Finite(double x) { return std::isfinite(x); }

std::string Number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string ParseCamera(const v1::LiveSource& l, const Eigen::Isometry3d& default_T, pipeline::LiveCameraSetup* out) {
  for (const auto& [name, v] : {std::pair{"fx", l.fx()}, {"fy", l.fy()}, {"baseline_m", l.baseline_m()}}) {
    if (!Finite(v) || v <= 0) {
      return std::string("live.") + name + ": must be finite and > 0, got " + std::to_string(v);
    }
  }
  for (const auto& [name, v] : {std::pair{"cx", l.cx()}, {"cy", l.cy()}}) {
    if (!Finite(v)) return std::string("live.") + name + ": must be finite";
  }
  if (l.width() < 16 || l.height() < 16 || l.width() > 8192 || l.height() > 8192) {
    return "live.width/height: must be in [16, 8192], got " + std::to_string(l.width()) + "x" +
           std::to_string(l.height());
  }
  out->camera = StereoCamera{l.fx(), l.fy(), l.cx(), l.cy(), l.baseline_m(), l.width(), l.height()};
  if (l.t_cam0_imu_size() == 0) {
    out->T_cam0_imu = default_T;
  } else if (l.t_cam0_imu_size() == 12) {
    Eigen::Matrix<double, 3, 4> m;
    for (int i = 0; i < 12; ++i) {
      if (!Finite(l.t_cam0_imu(i))) return "live.T_cam0_imu[" + std::to_string(i) + "]: not finite";
      m(i / 4, i % 4) = l.t_cam0_imu(i);
    }
    const Eigen::Matrix3d R = m.leftCols<3>();
    if (!((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() <= 1e-6) || R.determinant() < 0) {
      return "live.T_cam0_imu: rotation part is not orthonormal";
    }
    out->T_cam0_imu.linear() = R;
    out->T_cam0_imu.translation() = m.col(3);
  } else {
    return "live.T_cam0_imu: expected 0 or 12 values, got " + std::to_string(l.t_cam0_imu_size());
  }
  const double delay = l.max_gps_delay_s();
  if (!Finite(delay) || delay < 0 || delay > kMaxGpsDelayS) {
    return "live.max_gps_delay_s: must be in [0, 10] (0 = 0.5 s), got " + Number(delay);
  }
  out->max_gps_delay_s = delay == 0 ? kDefaultGpsDelayS : delay;
  return "";
}

// The GPS antenna's lever arm: 0 or 3 finite values within 10 m of the IMU.
std::string ParseLeverArm(const v1::LiveSource& l, Eigen::Vector3d* out) {
  out->setZero();
  if (l.gps_antenna_body_m_size() == 0) return "";
  if (l.gps_antenna_body_m_size() != 3)
    return "live.gps_antenna_body_m: expected 0 or 3 values (x, y, z), got " +
           std::to_string(l.gps_antenna_body_m_size());
  for (int i = 0; i < 3; ++i) {
    const double v = l.gps_antenna_body_m(i);
    if (!Finite(v) || std::abs(v) > 10)
      return "live.gps_antenna_body_m[" + std::to_string(i) + "]: must be finite and within 10 m of the IMU";
    (*out)[i] = v;
  }
  return "";
}

// The noise and scale prior of the car's speed sensor.
std::string ParseSpeedSensor(const v1::LiveSource& l, LiveSourceSetup* out) {
  const v1::SpeedSensor& s = l.speed_sensor();
  const std::pair<const char*, double> fields[] = {
      {"rate_hz", s.rate_hz()}, {"sigma_mps", s.sigma_mps()}, {"scale_factor_sigma", s.scale_factor_sigma()}};
  for (const auto& [name, v] : fields)
    if (!Finite(v) || v < 0) return std::string("live.speed_sensor.") + name + ": must be finite and >= 0";
  if (s.sigma_mps() > 10) return "live.speed_sensor.sigma_mps: must be <= 10 m/s";
  if (s.scale_factor_sigma() > 0.5) return "live.speed_sensor.scale_factor_sigma: must be <= 0.5";
  out->speed_sigma_mps = s.sigma_mps();
  out->speed_scale_sigma = s.scale_factor_sigma();
  return "";
}

// LiveSource.cameras: the pipelines, the two camera_info files (the camera
// model VO sees is theirs, rectified and cropped as a bag's), pairing and
// stall bounds. The pipelines themselves are started by CameraFeeder.
std::string ParseCameras(const v1::LiveSource& l, LiveSourceSetup* out) {
  out->cameras.reset();
  if (!l.has_cameras()) return "";
  const v1::CameraSource& c = l.cameras();
  if (l.fx() != 0 || l.fy() != 0 || l.cx() != 0 || l.cy() != 0 || l.baseline_m() != 0 || l.width() != 0 ||
      l.height() != 0) {
    return "live.cameras: leave live.fx .. height 0: the camera model comes from the camera_info files";
  }
  CameraSetup s;
  const bool two = !c.left_pipeline().empty() || !c.right_pipeline().empty();
  if (two == !c.stereo_pipeline().empty()) {
    return "live.cameras: give left_pipeline and right_pipeline, or stereo_pipeline (two appsinks named left and "
           "right), not both";
  }
  if (two && (c.left_pipeline().empty() || c.right_pipeline().empty())) {
    return std::string("live.cameras.") + (c.left_pipeline().empty() ? "left" : "right") + "_pipeline: missing";
  }
  for (const auto& [name, v] : {std::pair{"left_pipeline", &c.left_pipeline()}, {"right_pipeline", &c.right_pipeline()},
                                {"stereo_pipeline", &c.stereo_pipeline()}}) {
    if (v->size() > 4096) return std::string("live.cameras.") + name + ": longer than 4096 bytes";
  }
  s.left_pipeline = c.left_pipeline();
  s.right_pipeline = c.right_pipeline();
  s.stereo_pipeline = c.stereo_pipeline();
  try {
    s.left_info = ros::ParseCameraInfoYaml(c.left_camera_info(), "live.cameras.left_camera_info");
    s.right_info = ros::ParseCameraInfoYaml(c.right_camera_info(), "live.cameras.right_camera_info");
  } catch (const std::exception& e) {
    return std::string(e.what());  // names the field
  }
  try {
    out->camera.camera = ros::MakeRectifiedStereo(s.left_info, s.right_info).camera;
  } catch (const std::exception& e) {
    return std::string("live.cameras: ") + e.what();
  }
  const double tol = c.pair_tolerance_ms(), stall = c.stall_timeout_s();
  if (!Finite(tol) || tol < 0 || tol > 1000) {
    return "live.cameras.pair_tolerance_ms: must be in [0, 1000] (0 = 10 ms), got " + Number(tol);
  }
  if (!Finite(stall) || (stall != 0 && (stall < 0.1 || stall > 60))) {
    return "live.cameras.stall_timeout_s: must be 0 (1 s) or in [0.1, 60], got " + Number(stall);
  }
  s.pair_tolerance_s = tol == 0 ? 0.010 : tol * 1e-3;
  s.stall_timeout_s = stall == 0 ? 1.0 : stall;
  out->cameras = std::move(s);
  return "";
}

std::string ParseGpsd(const v1::LiveSource& l, std::optional<GpsdEndpoint>* out) {
  out->reset();
  if (!l.has_gps_source() || l.gps_source().kind_case() == v1::GpsSource::KIND_NOT_SET) return "";
  const auto& g = l.gps_source().gpsd();
  GpsdEndpoint e;
  if (!g.host().empty()) {
    if (g.host().size() > 253 || g.host().find_first_of(" \t\r\n/") != std::string::npos)
      return "live.gps_source.gpsd.host " + Quoted(g.host()) + ": not a host name or address";
    e.host = g.host();
  }
  if (g.port() > 65535) return "live.gps_source.gpsd.port: must be in [1, 65535], got " + std::to_string(g.port());
  if (g.port() != 0) e.port = static_cast<uint16_t>(g.port());
  *out = e;
  return "";
}

}  // namespace

std::string LiveSourceFromProto(const v1::LiveSource& in, const Eigen::Isometry3d& default_T_cam0_imu,
                                LiveSourceSetup* out) {
  if (in.has_cameras()) {
    if (std::string e = ParseCameras(in, out); !e.empty()) return e;
    v1::LiveSource rest = in;  // the rest of the camera setup (extrinsic, GPS delay) as for pushed frames
    rest.set_fx(out->camera.camera.fx);
    rest.set_fy(out->camera.camera.fy);
    rest.set_cx(out->camera.camera.cx);
    rest.set_cy(out->camera.camera.cy);
    rest.set_baseline_m(out->camera.camera.baseline_m);
    rest.set_width(out->camera.camera.width);
    rest.set_height(out->camera.camera.height);
    if (std::string e = ParseCamera(rest, default_T_cam0_imu, &out->camera); !e.empty()) return e;
    // A given T_cam0_imu is of the left camera's raw optical frame (as a ROS
    // tf gives it); VO works in its rectified frame: rotated by camera_info's
    // R, as a bag's extrinsic is. The default rig is KITTI's rectified cam0
    // already.
    if (in.t_cam0_imu_size() > 0) {
      Eigen::Isometry3d T_rect_cam = Eigen::Isometry3d::Identity();
      T_rect_cam.linear() = ros::RectificationRotation(out->cameras->left_info);
      out->camera.T_cam0_imu = T_rect_cam * out->camera.T_cam0_imu;
    }
  } else if (std::string e = ParseCamera(in, default_T_cam0_imu, &out->camera); !e.empty()) {
    return e;
  }
  out->camera.expects_imu = !in.no_imu();
  if (std::string e = ParseLeverArm(in, &out->gps_antenna_body_m); !e.empty()) return e;
  if (std::string e = ParseGpsd(in, &out->gpsd); !e.empty()) return e;
  return ParseSpeedSensor(in, out);
}

}  // namespace locaid::server
