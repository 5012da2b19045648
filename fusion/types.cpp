#include "fusion/types.hpp"

namespace locaid::fusion {

const char* ToString(Mode mode) {
  switch (mode) {
    case Mode::kGpsFused: return "GPS_FUSED";
    case Mode::kGpsDegraded: return "GPS_DEGRADED";
    case Mode::kVoOnly: return "VO_ONLY";
    case Mode::kLost: return "LOST";
    case Mode::kDeadReckoning: return "DEAD_RECKONING";
  }
  return "UNKNOWN";
}

}  // namespace locaid::fusion
