// How a request's input is echoed in an error message: quoted and cut, so a
// huge or hostile input cannot blow up a status. Free of gRPC (the request
// translations fuzz targets reach use it too).
#pragma once

#include <cstddef>
#include <string>

namespace locaid::server {

// `input` between single quotes, cut to 200 bytes (then its size is said).
inline std::string Quoted(const std::string& input) {
  constexpr size_t kMax = 200;
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on
  // "'" + std::string&&.
  std::string out = "'";
  out.append(input, 0, kMax);
  out += input.size() <= kMax ? "'" : "...' (" + std::to_string(input.size()) + " bytes)";
  return out;
}

}  // namespace locaid::server
