// LOCAID_NEEDS_TOOL(present, what): for a test that runs a program the test
// dependencies provide (deploy/install-deps.sh installs every one: node, npm,
// openssl, gpsfake, promtool, python3-grpcio). Without it the test skips on a
// developer's machine, and fails when the environment variable CI is set, so
// a CI run cannot pass with such tests unrun. Skips for hardware or
// privileges (a tmpfs mount) and for the optional shared KITTI data do not
// use it. Shared by every test folder.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace locaid::test_support {

// CI set to anything but "", "0" or "false".
inline bool InCi() {
  const char* ci = std::getenv("CI");
  if (ci == nullptr) return false;
  const std::string v = ci;
  return !v.empty() && v != "0" && v != "false";
}

// `name` is a program on PATH.
inline bool HaveCommand(const std::string& name) {
  return std::system(("command -v '" + name + "' >/dev/null 2>&1").c_str()) == 0;
}

}  // namespace locaid::test_support

#define LOCAID_NEEDS_TOOL(present, what)                                                              \
  do {                                                                                                \
    if (!(present)) {                                                                                 \
      if (::locaid::test_support::InCi()) {                                                           \
        FAIL() << what << " (CI is set: a missing test dependency fails; deploy/install-deps.sh installs it)"; \
      }                                                                                               \
      GTEST_SKIP() << what;                                                                           \
    }                                                                                                 \
  } while (false)
