// A fused pose as the API's PoseUpdate: the one place that fills it, for the
// server's sessions and for locaid-replay's MCAP recording. Everything except
// session_id, sequence, published_unix_ns and dropped_for_subscriber.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/frame_loop.hpp"

namespace locaid::output {

void FillPoseUpdate(const pipeline::StepResult& r, double latency_ms, locaid::v1::PoseUpdate* out);
// The learned noise of a pose (PoseUpdate.noise, SessionStats.noise).
void FillNoiseLearning(const fusion::FusedPose& p, locaid::v1::NoiseLearning* out);

}  // namespace locaid::output
