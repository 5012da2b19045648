#include "server/outage_request.hpp"

#include "server/status.hpp"

#include <cmath>

namespace locaid::server {

namespace v1 = locaid::v1;

grpc::Status OutageCommandFromProto(const v1::InjectOutageRequest& req, Session::Command* out) {
  const double start_s = req.start_s(), duration_s = req.duration_s();
  // Seconds become int64 nanoseconds on the sensor clock: bounded so they
  // cannot overflow (1e6 s is 11.6 days).
  constexpr double kMaxOutageSeconds = 1e6;
  if (!std::isfinite(start_s) || !std::isfinite(duration_s) || duration_s < 0 || duration_s > kMaxOutageSeconds ||
      std::abs(start_s) > kMaxOutageSeconds) {
    return Invalid("start_s/duration_s: must be finite, duration_s in [0, 1e6] s, |start_s| <= 1e6 s");
  }
  switch (req.action()) {
    case v1::InjectOutageRequest::START_NOW:
      *out = [duration_s](pipeline::RunLoop& p) { p.StartOutageNow(duration_s); };
      return grpc::Status::OK;
    case v1::InjectOutageRequest::STOP_NOW:
      *out = [](pipeline::RunLoop& p) { p.StopOutage(); };
      return grpc::Status::OK;
    case v1::InjectOutageRequest::WINDOW:
      if (start_s < 0 || duration_s <= 0) return Invalid("WINDOW: start_s must be >= 0 and duration_s > 0");
      *out = [start_s, duration_s](pipeline::RunLoop& p) { p.AddOutageWindow(start_s, duration_s); };
      return grpc::Status::OK;
    default:
      return Invalid("action: must be START_NOW, STOP_NOW or WINDOW");
  }
}

}  // namespace locaid::server
