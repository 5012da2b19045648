// The names every output writes for the API's enums: the proto's value name
// without its prefix (MODE_GPS_FUSED -> GPS_FUSED), so a new value of the
// proto is named everywhere without a table to keep; the number for a value
// this build's proto does not know.
#pragma once

#include "locaid/v1/localization.pb.h"

#include <string>

namespace locaid::output {

inline std::string EnumName(const std::string& name, const std::string& prefix, int value) {
  if (name.empty()) return std::to_string(value);
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

inline std::string ModeName(v1::Mode m) { return EnumName(v1::Mode_Name(m), "MODE_", m); }
inline std::string VoStatusName(v1::VoStatus s) { return EnumName(v1::VoStatus_Name(s), "VO_STATUS_", s); }
inline std::string VoHealthName(v1::VoHealth h) { return EnumName(v1::VoHealth_Name(h), "VO_HEALTH_", h); }

}  // namespace locaid::output
