#include "kitti/parse_number.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace locaid::kitti {

bool ParseFiniteDouble(std::string_view token, double& out, std::string& why) {
  const char* first = token.data();
  const char* last = token.data() + token.size();
  if (first != last && *first == '+' && last - first > 1 && first[1] != '-' && first[1] != '+') {
    ++first;  // from_chars rejects a leading '+'
  }
  double v = 0;
  const auto [ptr, ec] = std::from_chars(first, last, v);
  if (ptr != last || (ec != std::errc() && ec != std::errc::result_out_of_range)) {
    why = "is not a number";
    return false;
  }
  if (ec == std::errc::result_out_of_range) {
    // The token is syntactically a number; strtod tells overflow from underflow.
    const std::string copy(first, last);
    errno = 0;
    v = std::strtod(copy.c_str(), nullptr);
    if (std::isinf(v)) {
      why = "overflows a double";
      return false;
    }
  }
  if (std::isnan(v)) {
    why = "is NaN";
    return false;
  }
  if (std::isinf(v)) {
    why = "is infinite";
    return false;
  }
  out = v;
  return true;
}

}  // namespace locaid::kitti
