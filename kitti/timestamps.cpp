#include "kitti/timestamps.hpp"

#include "kitti/parse_number.hpp"
#include "kitti/types.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::kitti {
namespace {

std::string_view Trim(std::string_view s) {
  const char* ws = " \t\r\n";
  const size_t b = s.find_first_not_of(ws);
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(ws) - b + 1);
}

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm).
int64_t DaysFromCivil(int64_t y, int m, int d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

void CivilFromDays(int64_t z, int64_t& y, int& m, int& d) {
  z += 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const int64_t doe = z - era * 146097;
  const int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  y = yoe + era * 400;
  const int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const int64_t mp = (5 * doy + 2) / 153;
  d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  y += m <= 2;
}

int DaysInMonth(int64_t y, int m) {
  static const int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  return m == 2 && leap ? 29 : kDays[m - 1];
}

// Reads exactly `n` digits at s[pos..].
bool Digits(std::string_view s, size_t pos, size_t n, int64_t& out) {
  if (pos + n > s.size()) return false;
  out = 0;
  for (size_t i = pos; i < pos + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
    out = out * 10 + (s[i] - '0');
  }
  return true;
}

// Calls parse(line, "path:N") for each line of a file whose line k belongs
// to frame k (trimmed; trailing blank lines allowed, a blank line before a
// non-blank one is an error: it would shift every later frame).
template <typename Parse>
void ForEachFrameLine(const std::filesystem::path& path, const char* what, Parse parse) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open " + what + " file");
  std::string line;
  int line_no = 0, first_blank = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string_view tok = Trim(line);
    if (tok.empty()) {
      if (first_blank == 0) first_blank = line_no;
      continue;
    }
    if (first_blank != 0) {
      throw Error(path.string() + ":" + std::to_string(first_blank) + ": blank line inside a " + what +
                  " file (line k must be frame k)");
    }
    parse(tok, path.string() + ":" + std::to_string(line_no));
  }
}

}  // namespace

int64_t ParseTimestamp(std::string_view line_in, const std::string& where) {
  const std::string_view s = Trim(line_in);
  const auto fail = [&](const std::string& why) {
    return Error(where + ": " + why + " in timestamp '" + std::string(s) +
                 "' (expected 'YYYY-MM-DD HH:MM:SS.fffffffff')");
  };
  // Fixed part: "YYYY-MM-DD HH:MM:SS" = 19 characters.
  int64_t y, mo, d, h, mi, sec;
  if (s.size() < 19 || !Digits(s, 0, 4, y) || s[4] != '-' || !Digits(s, 5, 2, mo) ||
      s[7] != '-' || !Digits(s, 8, 2, d) || s[10] != ' ' || !Digits(s, 11, 2, h) ||
      s[13] != ':' || !Digits(s, 14, 2, mi) || s[16] != ':' || !Digits(s, 17, 2, sec)) {
    throw fail("malformed date/time");
  }
  if (mo < 1 || mo > 12) throw fail("month " + std::to_string(mo) + " out of range");
  if (d < 1 || d > DaysInMonth(y, static_cast<int>(mo)))
    throw fail("day " + std::to_string(d) + " out of range");
  if (h > 23) throw fail("hour " + std::to_string(h) + " out of range");
  if (mi > 59) throw fail("minute " + std::to_string(mi) + " out of range");
  if (sec > 59) throw fail("second " + std::to_string(sec) + " out of range");
  // t_ns is int64 ns since 1970: only years 1678..2261 fit (found by fuzz_timestamps).
  constexpr int64_t kMinYear = 1678, kMaxYear = 2261;
  if (y < kMinYear || y > kMaxYear) {
    throw fail("year " + std::to_string(y) + " outside [1678, 2261] (int64 nanoseconds since 1970)");
  }
  int64_t frac_ns = 0;
  if (s.size() > 19) {
    if (s[19] != '.') throw fail("unexpected text after the seconds");
    const size_t n = s.size() - 20;
    if (n < 1 || n > 9) throw fail(std::to_string(n) + " fraction digits, expected 1 to 9");
    if (!Digits(s, 20, n, frac_ns)) throw fail("fraction is not all digits");
    for (size_t k = n; k < 9; ++k) frac_ns *= 10;
  }
  const int64_t days = DaysFromCivil(y, static_cast<int>(mo), static_cast<int>(d));
  return ((days * 24 + h) * 60 + mi) * 60 * 1'000'000'000LL + sec * 1'000'000'000LL + frac_ns;
}

std::string FormatTimestamp(int64_t t_ns) {
  constexpr int64_t kNsPerDay = 86'400LL * 1'000'000'000LL;
  int64_t days = t_ns / kNsPerDay;
  int64_t rem = t_ns % kNsPerDay;
  if (rem < 0) {
    rem += kNsPerDay;
    --days;
  }
  int64_t y;
  int m, d;
  CivilFromDays(days, y, m, d);
  const int64_t sec_of_day = rem / 1'000'000'000LL;
  const int64_t ns = rem % 1'000'000'000LL;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04lld-%02d-%02d %02lld:%02lld:%02lld.%09lld",
                static_cast<long long>(y), m, d, static_cast<long long>(sec_of_day / 3600),
                static_cast<long long>(sec_of_day / 60 % 60),
                static_cast<long long>(sec_of_day % 60), static_cast<long long>(ns));
  return buf;
}

std::vector<int64_t> ReadTimestampsFile(const std::filesystem::path& path) {
  std::vector<int64_t> out;
  ForEachFrameLine(path, "timestamps", [&](std::string_view line, const std::string& where) {
    out.push_back(ParseTimestamp(std::string(line), where));
  });
  return out;
}

void WriteTimestampsFile(const std::filesystem::path& path, const std::vector<int64_t>& t_ns) {
  std::ofstream out(path);
  if (!out) throw Error(path.string() + ": cannot open for writing");
  for (int64_t t : t_ns) out << FormatTimestamp(t) << '\n';
  if (!out) throw Error(path.string() + ": write failed");
}

std::vector<double> ReadOdometryTimes(const std::filesystem::path& path) {
  std::vector<double> out;
  ForEachFrameLine(path, "times", [&](std::string_view tok, const std::string& where) {
    const std::string at = where + ": ";
    double v = 0;
    std::string why;
    if (!ParseFiniteDouble(tok, v, why)) throw Error(at + "time " + why + ": '" + std::string(tok) + "'");
    if (v < 0) throw Error(at + "negative time " + std::string(tok));
    constexpr double kMaxTimeS = 1e9;  // keeps llround(t * 1e9) inside int64
    if (v > kMaxTimeS) throw Error(at + "time " + std::string(tok) + " s exceeds 1e9 s");
    if (!out.empty() && v < out.back())
      throw Error(at + "time " + std::string(tok) + " s goes back (previous line " +
                  std::to_string(out.back()) + " s)");
    out.push_back(v);
  });
  return out;
}

}  // namespace locaid::kitti
