#include "sensors/nmea.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <regex>
#include <stdexcept>

namespace locaid::sensors {
namespace {

constexpr int64_t kNsPerS = 1'000'000'000;

std::tm UtcTm(int64_t utc_ns) {
  const std::time_t s = static_cast<std::time_t>(utc_ns >= 0 ? utc_ns / kNsPerS : (utc_ns - kNsPerS + 1) / kNsPerS);
  std::tm tm{};
  gmtime_r(&s, &tm);
  return tm;
}

// hhmmss.ss
std::string TimeField(int64_t utc_ns) {
  const std::tm tm = UtcTm(utc_ns);
  const int64_t centis = ((utc_ns % kNsPerS) + kNsPerS) % kNsPerS / 10'000'000;
  char buf[16];
  std::snprintf(buf, sizeof buf, "%02d%02d%02d.%02lld", tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<long long>(centis));
  return buf;
}

// ddmm.mmmmmm,N or dddmm.mmmmmm,E
std::string Angle(double deg, bool latitude) {
  const char hemi = latitude ? (deg >= 0 ? 'N' : 'S') : (deg >= 0 ? 'E' : 'W');
  const double a = std::abs(deg);
  int d = static_cast<int>(a);
  double m = (a - d) * 60.0;
  if (m >= 59.9999995) { ++d; m = 0; }  // would print as 60.000000
  char buf[32];
  std::snprintf(buf, sizeof buf, latitude ? "%02d%09.6f,%c" : "%03d%09.6f,%c", d, m, hemi);
  return buf;
}

std::string Sentence(const std::string& body) { return "$" + body + NmeaChecksum(body) + "\r\n"; }

}  // namespace

std::string NmeaChecksum(const std::string& body) {
  unsigned char x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char buf[4];
  std::snprintf(buf, sizeof buf, "*%02X", x);
  return buf;
}

std::string GgaSentence(const NmeaFix& f) {
  char buf[160];
  if (!f.valid) {
    std::snprintf(buf, sizeof buf, "GPGGA,%s,,,,,0,00,,,M,,M,,", TimeField(f.utc_ns).c_str());
    return Sentence(buf);
  }
  std::snprintf(buf, sizeof buf, "GPGGA,%s,%s,%s,1,%02d,%.1f,%.3f,M,0.000,M,,", TimeField(f.utc_ns).c_str(),
                Angle(f.lat_deg, true).c_str(), Angle(f.lon_deg, false).c_str(), f.satellites, f.hdop, f.alt_m);
  return Sentence(buf);
}

std::string RmcSentence(const NmeaFix& f) {
  const std::tm tm = UtcTm(f.utc_ns);
  char date[16];
  std::snprintf(date, sizeof date, "%02d%02d%02d", tm.tm_mday, tm.tm_mon + 1, (tm.tm_year % 100 + 100) % 100);
  char buf[160];
  if (!f.valid) {
    std::snprintf(buf, sizeof buf, "GPRMC,%s,V,,,,,,,%s,,,N", TimeField(f.utc_ns).c_str(), date);
    return Sentence(buf);
  }
  const double knots = f.speed_mps * 3600.0 / 1852.0;
  std::snprintf(buf, sizeof buf, "GPRMC,%s,A,%s,%s,%.3f,%.2f,%s,,,A", TimeField(f.utc_ns).c_str(),
                Angle(f.lat_deg, true).c_str(), Angle(f.lon_deg, false).c_str(), knots, f.course_deg, date);
  return Sentence(buf);
}

std::string GstSentence(const NmeaFix& f) {
  const double rms = std::sqrt(f.sigma_lat_m * f.sigma_lat_m + f.sigma_lon_m * f.sigma_lon_m);
  char buf[160];
  std::snprintf(buf, sizeof buf, "GPGST,%s,%.2f,%.2f,%.2f,0.0,%.2f,%.2f,%.2f", TimeField(f.utc_ns).c_str(), rms,
                std::max(f.sigma_lat_m, f.sigma_lon_m), std::min(f.sigma_lat_m, f.sigma_lon_m), f.sigma_lat_m,
                f.sigma_lon_m, f.sigma_alt_m);
  return Sentence(buf);
}

std::string GsaSentence(const NmeaFix& f) {
  // Auto 2-D/3-D selection; mode 1 (no fix) or 3 (3-D), no satellite list.
  return Sentence(std::string("GPGSA,A,") + (f.valid ? "3" : "1") + ",,,,,,,,,,,,,,,");
}

int64_t ParseIso8601Utc(const std::string& text) {
  static const std::regex re(R"((\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2}):(\d{2})(\.\d{1,9})?Z?)");
  std::smatch m;
  if (!std::regex_match(text, m, re))
    throw std::invalid_argument("'" + text + "': expected YYYY-MM-DDTHH:MM:SS[.fff]Z (UTC)");
  std::tm tm{};
  tm.tm_year = std::stoi(m[1]) - 1900;
  tm.tm_mon = std::stoi(m[2]) - 1;
  tm.tm_mday = std::stoi(m[3]);
  tm.tm_hour = std::stoi(m[4]);
  tm.tm_min = std::stoi(m[5]);
  tm.tm_sec = std::stoi(m[6]);
  if (tm.tm_mon > 11 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 || tm.tm_min > 59 || tm.tm_sec > 60)
    throw std::invalid_argument("'" + text + "': a field is out of range");
  const int64_t s = static_cast<int64_t>(timegm(&tm));
  int64_t frac = 0;
  if (m[7].matched) {
    std::string digits = m[7].str().substr(1);
    digits.resize(9, '0');
    frac = std::stoll(digits);
  }
  return s * kNsPerS + frac;
}

}  // namespace locaid::sensors
