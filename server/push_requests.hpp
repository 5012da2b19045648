// What a PushSensorData stream carries (PushRequest.frame / .oxts / .imu /
// .gps) translated into the items a live session queues, with every value
// checked here: the one place for it. Defaults for what a client may leave
// out are documented in docs/api.md ("Typed sensor input").
#pragma once

#include "core/stereo_camera.hpp"
#include "locaid/v1/localization.pb.h"
#include "pipeline/live_frame_source.hpp"

#include <string>

namespace locaid::server {

// Both return "" and fill `out`, or the reason the message is refused (the
// stream answers it with PushRejected and goes on).
std::string ImuItemFromProto(const locaid::v1::ImuSample& in, pipeline::LiveItem* out);
std::string SpeedItemFromProto(const locaid::v1::SpeedSample& in, pipeline::LiveItem* out);
std::string GpsItemFromProto(const locaid::v1::GpsFix& in, pipeline::LiveItem* out);

// A pushed frame (its images are moved out of `in`). `rejected`: the message
// is refused and the stream goes on; `fatal`: a PNG declares another size
// than the session's camera (never decoded: a small file can declare
// 30000x30000 px), the stream must end with INVALID_ARGUMENT.
struct FrameTranslation {
  pipeline::LiveItem item;
  std::string rejected, fatal;
};
FrameTranslation FrameItemFromProto(locaid::v1::StereoFrame* in, const StereoCamera& camera);
// A pushed OXTS line: parsed (and counted bad if it does not parse) on the
// session thread.
pipeline::LiveItem OxtsItemFromProto(const locaid::v1::OxtsRecord& in);

}  // namespace locaid::server
