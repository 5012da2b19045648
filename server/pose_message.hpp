// A fused pose as the API's PoseUpdate: the one place that fills it, for the
// server's sessions and for locaid-replay's MCAP recording. Everything except
// session_id, sequence, published_unix_ns and dropped_for_subscriber.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/localizer.hpp"
#include "server/session_pipeline.hpp"

#include <vector>

namespace locaid::server {

void FillPoseUpdate(const StepResult& r, double latency_ms, locaid::v1::PoseUpdate* out);

// The fixes a Localizer call fed to the filter, as a pose reports them.
std::vector<FixSeen> FixesSeen(const pipeline::FrameResult& r);

}  // namespace locaid::server
