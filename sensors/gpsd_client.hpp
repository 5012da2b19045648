// A client of a gpsd daemon (https://gpsd.io) through Debian's libgps: it
// watches the JSON stream and turns TPV reports into fixes the filter takes.
// No threads of its own: the caller polls Read() (the server runs it on the
// session's receiver thread, server/gps_receiver.cpp).
#pragma once

#include "fusion/types.hpp"

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace locaid::sensors {

// One TPV report, in gpsd's terms (NaN where gpsd did not say).
struct GpsdReport {
  int mode = 0;    // 0 not seen, 1 no fix, 2 2-D, 3 3-D
  int status = 0;  // gpsd STATUS_*: 2 DGPS, 3 RTK fixed, 4 RTK float, ...
  int64_t t_ns = 0;  // UTC of the fix, Unix epoch; 0 when the report had no time
  double lat_deg = 0, lon_deg = 0, alt_hae_m = 0;
  double epx_m = 0, epy_m = 0, epv_m = 0, eph_m = 0;  // gpsd's error estimates
  double speed_mps = 0, track_deg = 0, climb_mps = 0, eps_mps = 0;
};

// The filter's view of a report. nullopt for a report without time or
// position (mode < 2): the receiver has no fix. gpsd states its error
// estimates at 95 % confidence; they are turned into 1-sigma (/ 2.45 for the
// 2-D horizontal, / 1.96 vertical). Missing estimates: 5 m / 10 m 1-sigma.
// A 2-D fix does not measure altitude. Speed/track/climb give the velocity.
std::optional<fusion::GpsFix> FixFromGpsd(const GpsdReport& report);

class GpsdClient {
 public:
  // Connects and enables the JSON watch. Throws std::runtime_error naming
  // host:port and the reason.
  GpsdClient(const std::string& host, uint16_t port);
  ~GpsdClient();
  GpsdClient(const GpsdClient&) = delete;
  GpsdClient& operator=(const GpsdClient&) = delete;

  // Waits up to `timeout` for data and returns the TPV reports read (none on
  // timeout). Throws std::runtime_error when the connection is lost.
  std::vector<GpsdReport> Read(std::chrono::milliseconds timeout);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace locaid::sensors
