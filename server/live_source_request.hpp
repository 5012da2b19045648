// A live source as a client describes it (StartSessionRequest.live, the
// `start` of a PushSensorData stream): camera, extrinsic, GPS delay bound,
// antenna lever arm, speed sensor and an optional gpsd receiver, every field
// checked here: the one place for it. Free of gRPC, so fuzz_push_requests
// starts its streams from fuzzed sources.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/live_frame_source.hpp"
#include "ros/messages.hpp"
#include "server/gpsd_feeder.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>

namespace locaid::server {

// LiveSource.max_gps_delay_s: default (for 0) and upper bound, seconds.
inline constexpr double kDefaultGpsDelayS = 0.5, kMaxGpsDelayS = 10.0;

// LiveSource.cameras, checked: what CameraFeeder opens.
struct CameraSetup {
  std::string left_pipeline, right_pipeline, stereo_pipeline;  // two cameras, or one stereo pipeline
  ros::CameraInfo left_info, right_info;
  double pair_tolerance_s = 0.010;
  double stall_timeout_s = 1.0;
};

struct LiveSourceSetup {
  pipeline::LiveCameraSetup camera;  // intrinsics, T_cam0_imu, max GPS delay
  Eigen::Vector3d gps_antenna_body_m = Eigen::Vector3d::Zero();
  double speed_sigma_mps = 0, speed_scale_sigma = 0;  // 0: the filter's defaults
  std::optional<GpsdEndpoint> gpsd;
  std::optional<CameraSetup> cameras;  // the server reads the cameras (camera model from their camera_info)
};

// "" with *out filled, or why the source is refused, naming the field (the
// RPC answers INVALID_ARGUMENT with it). `default_T_cam0_imu` is the extrinsic
// of a source that gives none.
std::string LiveSourceFromProto(const locaid::v1::LiveSource& in, const Eigen::Isometry3d& default_T_cam0_imu,
                                LiveSourceSetup* out);

}  // namespace locaid::server
