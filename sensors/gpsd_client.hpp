// A client of a gpsd daemon (https://gpsd.io) through Debian's libgps: it
// watches the JSON stream and turns TPV reports into fixes the filter takes.
// No threads of its own: the caller polls Read() (the server runs it on the
// session's feeder thread, server/gpsd_feeder.cpp).
#pragma once

#include "fusion/types.hpp"

#include <chrono>
#include <cmath>
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
  // 1-sigma errors from the receiver's newest GST report (NMEA $--GST) of
  // the last 5 s, NaN without one: what the receiver says of itself.
  double gst_lat_m = NAN, gst_lon_m = NAN, gst_alt_m = NAN;
};

// The filter's view of a report; nullopt when it has no position (mode < 2:
// the receiver has no fix). Sigma: the receiver's own GST figures when it
// sends them; else gpsd's estimates, which are 95 % figures (gpsd's error
// model), turned into 1-sigma (/ 1.96 per axis, / 2.45 for the horizontal
// radius eph); else 5 m / 10 m. A 2-D fix does not measure altitude. The
// velocity is not taken: gpsd derives climb from successive altitudes of an
// NMEA receiver, which is noise, not a measurement.
std::optional<fusion::GpsFix> FixFromGpsd(const GpsdReport& report);

class GpsdClient {
 public:
  // Connects and enables the JSON watch. Throws std::runtime_error naming
  // host:port and the reason.
  GpsdClient(const std::string& host, uint16_t port);
  ~GpsdClient();
  GpsdClient(const GpsdClient&) = delete;
  GpsdClient& operator=(const GpsdClient&) = delete;

  // Waits up to `timeout` for data and returns the time-stamped TPV reports
  // read (none on timeout). Throws std::runtime_error when the connection is
  // lost.
  std::vector<GpsdReport> Read(std::chrono::milliseconds timeout);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace locaid::sensors
