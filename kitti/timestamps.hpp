// KITTI time files: raw image_0x/timestamps.txt and oxts/timestamps.txt lines
// "2011-09-26 14:05:35.500923136", and odometry times.txt (seconds per line).
//
// Raw timestamps are local wall-clock labels of the recording PC; locaid treats
// them as UTC so t_ns = nanoseconds since 1970-01-01T00:00:00 of that label.
// Only differences between them carry meaning.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::kitti {

// Parses "YYYY-MM-DD HH:MM:SS.fffffffff" (fraction of 1 to 9 digits, padded to
// ns; surrounding whitespace ignored) to ns since the Unix epoch, exact.
// Throws kitti::Error "WHERE: reason" for anything else (bad field, out-of-range
// month/day/hour/minute/second, trailing text).
int64_t ParseTimestamp(std::string_view line, const std::string& where);

// Inverse of ParseTimestamp, always with a 9-digit fraction.
std::string FormatTimestamp(int64_t t_ns);

// One timestamp per line; line k (0-based) is frame/record k. Trailing blank
// lines are allowed, a blank line in the middle is an error. Throws
// kitti::Error "PATH:LINE: reason".
std::vector<int64_t> ReadTimestampsFile(const std::filesystem::path& path);
void WriteTimestampsFile(const std::filesystem::path& path, const std::vector<int64_t>& t_ns);

// Odometry times.txt: one finite, non-negative, non-decreasing number of
// seconds per line. Throws kitti::Error "PATH:LINE: reason".
std::vector<double> ReadOdometryTimes(const std::filesystem::path& path);

}  // namespace locaid::kitti
