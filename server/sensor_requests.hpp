// Typed live input (PushRequest.imu / .gps) translated into the items a live
// session queues, with every value checked here. Defaults for what a client
// may leave out are documented in docs/api.md ("Typed sensor input").
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/live_frame_source.hpp"

#include <string>

namespace locaid::server {

// Both return "" and fill `out`, or the reason the message is refused (the
// stream answers it with PushRejected and goes on).
std::string ImuItemFromProto(const locaid::v1::ImuSample& in, pipeline::LiveItem* out);
std::string GpsItemFromProto(const locaid::v1::GpsFix& in, pipeline::LiveItem* out);

}  // namespace locaid::server
