// OXTS RT3003 record I/O (KITTI raw oxts/data/NNNNNNNNNN.txt: one line of 30
// space-separated numbers, field order of oxts/dataformat.txt).
#pragma once

#include "kitti/types.hpp"

#include <array>
#include <filesystem>
#include <string>
#include <string_view>

namespace locaid::kitti {

inline constexpr int kOxtsFieldCount = 30;

// Field names in file order ("lat", "lon", ..., "orimode"), as in dataformat.txt.
const std::array<std::string_view, kOxtsFieldCount>& OxtsFieldNames();

// Parses one OXTS line. `where` prefixes every error ("oxts/data/17.txt:1").
// Checks: exactly 30 fields; each a finite number (NaN/inf rejected, naming the
// field); lat in [-90, 90]; lon in [-180, 180]; navstat..orimode integral.
// Throws kitti::Error "WHERE: reason".
OxtsRecord ParseOxtsLine(std::string_view line, const std::string& where);

// Reads a KITTI oxts file: exactly one non-empty line (trailing blank lines
// allowed). Throws kitti::Error "PATH:LINE: reason" (also if unreadable/empty).
OxtsRecord ReadOxtsFile(const std::filesystem::path& path);

// One line, 30 space-separated fields, doubles with 17 significant digits so
// ParseOxtsLine(WriteOxtsLine(r)) == r exactly; integers as integers. No '\n'.
std::string WriteOxtsLine(const OxtsRecord& r);

}  // namespace locaid::kitti
