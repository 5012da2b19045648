// Strict number parsing shared by the kitti/ text parsers.
#pragma once

#include <string>
#include <string_view>

namespace locaid::kitti {

// Parses the whole token as a finite double (optional leading '+'; decimal or
// exponent form; values below the smallest subnormal read as +-0 or the
// subnormal). On failure returns false and sets `why` to one of
// "is not a number", "is NaN", "is infinite", "overflows a double".
bool ParseFiniteDouble(std::string_view token, double& out, std::string& why);

}  // namespace locaid::kitti
