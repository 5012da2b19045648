// NMEA 0183 sentences a GNSS receiver prints (GGA, RMC, GST), for replaying a
// drive's degraded GPS through real tools such as gpsd. Pure formatting: no
// I/O, no threads.
#pragma once

#include <cstdint>
#include <string>

namespace locaid::sensors {

// One epoch of a receiver. Times are UTC nanoseconds since the Unix epoch.
struct NmeaFix {
  int64_t utc_ns = 0;
  bool valid = false;              // false: no fix (GGA quality 0, RMC status V)
  double lat_deg = 0, lon_deg = 0;
  double alt_m = 0;                // written as the altitude with a geoid separation of 0
  double speed_mps = 0;            // over ground
  double course_deg = 0;           // true, clockwise from north, [0, 360)
  int satellites = 10;
  double hdop = 0.9;
  double sigma_lat_m = 0, sigma_lon_m = 0, sigma_alt_m = 0;  // GST 1-sigma errors
};

// "*HH": XOR of the characters between '$' and '*', two upper-case hex digits.
std::string NmeaChecksum(const std::string& body);
// Full sentences, "$...*HH\r\n", talker "GP".
std::string GgaSentence(const NmeaFix& fix);
std::string RmcSentence(const NmeaFix& fix);
std::string GstSentence(const NmeaFix& fix);
// GSA without satellites: the fix mode only (what a receiver without a fix
// still prints every epoch).
std::string GsaSentence(const NmeaFix& fix);

// Parses "YYYY-MM-DDTHH:MM:SS[.fff]Z" (UTC; the Z may be left out) into ns
// since the Unix epoch; throws std::invalid_argument naming what is wrong.
int64_t ParseIso8601Utc(const std::string& text);

}  // namespace locaid::sensors
