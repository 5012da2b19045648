#include "server/camera_fault_request.hpp"

#include "server/status.hpp"

#include <cmath>
#include <sstream>
#include <string>

namespace locaid::server {

namespace v1 = locaid::v1;
using sim::CameraFaultKind;

namespace {

std::string Number(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

bool KindFromProto(v1::CameraFault::Kind kind, CameraFaultKind* out) {
  switch (kind) {
    case v1::CameraFault::DARK: *out = CameraFaultKind::kDark; return true;
    case v1::CameraFault::NOISE: *out = CameraFaultKind::kNoise; return true;
    case v1::CameraFault::BLUR: *out = CameraFaultKind::kBlur; return true;
    case v1::CameraFault::FROZEN: *out = CameraFaultKind::kFrozen; return true;
    case v1::CameraFault::DROP: *out = CameraFaultKind::kDrop; return true;
    case v1::CameraFault::LEFT_ONLY: *out = CameraFaultKind::kLeftOnly; return true;
    case v1::CameraFault::RIGHT_ONLY: *out = CameraFaultKind::kRightOnly; return true;
    default: return false;
  }
}

}  // namespace

grpc::Status CameraFaultFromProto(const v1::CameraFault& f, bool window, sim::CameraFaultWindow* out) {
  sim::CameraFaultWindow w;
  if (!KindFromProto(f.kind(), &w.kind))
    return Invalid("fault.kind: must be DARK, NOISE, BLUR, FROZEN, DROP, LEFT_ONLY or RIGHT_ONLY, got " +
                   std::to_string(static_cast<int>(f.kind())));
  const std::string kind(v1::CameraFault::Kind_Name(f.kind()));
  // Seconds become int64 nanoseconds on the sensor clock (as outages).
  constexpr double kMaxSeconds = 1e6;
  if (!(std::isfinite(f.start_s()) && f.start_s() >= 0 && f.start_s() <= kMaxSeconds))
    return Invalid("fault.start_s: must be in [0, 1e6] s, got " + Number(f.start_s()));
  if (!(std::isfinite(f.duration_s()) && f.duration_s() >= 0 && f.duration_s() <= kMaxSeconds))
    return Invalid("fault.duration_s: must be in [0, 1e6] s, got " + Number(f.duration_s()));
  if (window && f.duration_s() <= 0) return Invalid("fault.duration_s: a WINDOW needs duration_s > 0");
  if (!window && f.start_s() != 0)
    return Invalid("fault.start_s: applies to WINDOW only (START_NOW starts at the next frame), got " +
                   Number(f.start_s()));
  w.start_s = f.start_s();
  w.duration_s = f.duration_s();
  // A parameter for a fault it does not change is a mistake of the caller's.
  const auto only_for = [&](const char* field, double v, bool applies, const char* kinds) -> grpc::Status {
    if (v != 0 && !applies)
      return Invalid(std::string("fault.") + field + ": applies to " + kinds + " only, got " + Number(v) + " for " +
                     kind);
    return grpc::Status::OK;
  };
  const bool dark = w.kind == CameraFaultKind::kDark, noise = w.kind == CameraFaultKind::kNoise;
  if (grpc::Status s = only_for("gain", f.gain(), dark, "DARK"); !s.ok()) return s;
  if (grpc::Status s = only_for("noise_dn", f.noise_dn(), dark || noise, "DARK and NOISE"); !s.ok()) return s;
  if (grpc::Status s = only_for("blur_sigma_px", f.blur_sigma_px(), w.kind == CameraFaultKind::kBlur, "BLUR");
      !s.ok())
    return s;
  // 0 = the default (sim::CameraFaultWindow's; 8 DN for NOISE).
  if (f.gain() != 0) w.gain = f.gain();
  if (noise) w.noise_dn = 8;
  if (f.noise_dn() != 0) w.noise_dn = f.noise_dn();
  if (f.blur_sigma_px() != 0) w.blur_sigma_px = f.blur_sigma_px();
  const std::string problem = sim::CameraFaultParameterProblem(w);
  if (!problem.empty()) return Invalid("fault." + problem);
  *out = w;
  return grpc::Status::OK;
}

grpc::Status CameraFaultCommandFromProto(const v1::InjectCameraFaultRequest& req, Session::Command* out) {
  using pipeline::CameraFaultAction;
  CameraFaultAction action;
  switch (req.action()) {
    case v1::InjectCameraFaultRequest::START_NOW: action = CameraFaultAction::kStartNow; break;
    case v1::InjectCameraFaultRequest::WINDOW: action = CameraFaultAction::kWindow; break;
    case v1::InjectCameraFaultRequest::STOP_NOW:
      *out = [](pipeline::RunLoop& p) { p.InjectCameraFault(pipeline::CameraFaultAction::kStop, {}); };
      return grpc::Status::OK;
    default: return Invalid("action: must be START_NOW, STOP_NOW or WINDOW");
  }
  if (!req.has_fault()) return Invalid("fault: required for START_NOW and WINDOW");
  sim::CameraFaultWindow fault;
  if (grpc::Status s = CameraFaultFromProto(req.fault(), action == CameraFaultAction::kWindow, &fault); !s.ok())
    return s;
  *out = [action, fault](pipeline::RunLoop& p) { p.InjectCameraFault(action, fault); };
  return grpc::Status::OK;
}

}  // namespace locaid::server
