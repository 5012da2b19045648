// A fused pose as the API's PoseUpdate: the one place that fills it, for the
// server's sessions and for locaid-replay's MCAP recording. Everything except
// session_id, sequence, published_unix_ns and dropped_for_subscriber.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/frame_loop.hpp"

namespace locaid::output {

void FillPoseUpdate(const pipeline::StepResult& r, double latency_ms, locaid::v1::PoseUpdate* out);

}  // namespace locaid::output
