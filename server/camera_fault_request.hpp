// InjectCameraFaultRequest translated into the command a session runs on its
// thread, with every value checked here.
#pragma once

#include "sim/scenario.hpp"
#include "locaid/v1/localization.pb.h"
#include "pipeline/camera_faults.hpp"
#include "server/session.hpp"

#include <grpcpp/grpcpp.h>

namespace locaid::server {

// OK and `out` set to the fault (proto defaults filled in: gain 0.06,
// noise_dn 3 for DARK and 8 for NOISE, blur_sigma_px 3), or INVALID_ARGUMENT
// naming the field and the rule: a known kind; parameters finite and in range
// (gain (0, 1], noise_dn [0, 255], blur_sigma_px (0, 50]) and only for the
// kinds they change; times finite, start_s in [0, 1e6] (WINDOW only),
// duration_s in [0, 1e6] (WINDOW: > 0).
grpc::Status CameraFaultFromProto(const locaid::v1::CameraFault& fault, bool window, sim::CameraFaultWindow* out);
// The whole request: OK and `out` set, or INVALID_ARGUMENT (a known action;
// STOP_NOW needs no fault).
grpc::Status CameraFaultCommandFromProto(const locaid::v1::InjectCameraFaultRequest& req, Session::Command* out);

}  // namespace locaid::server
