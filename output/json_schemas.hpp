// JSON Schemas of the foxglove message types locaid publishes as JSON, and of
// its own status message. Field names and types follow the foxglove schemas
// (https://docs.foxglove.dev/docs/visualization/message-schemas); only the
// fields locaid fills are required. They stay within what Foxglove's and
// Lichtblick's JSON Schema reader accepts: one "type" per field (boolean,
// string, number, integer, object, array of those), enums as "oneOf" numeric
// constants.
#pragma once

#include <string>

namespace locaid::output::schemas {

std::string PoseInFrame();      // foxglove.PoseInFrame
std::string PosesInFrame();     // foxglove.PosesInFrame
std::string FrameTransforms();  // foxglove.FrameTransforms
std::string LocationFix();      // foxglove.LocationFix (with color and metadata)
std::string Status();           // locaid.Status

}  // namespace locaid::output::schemas
