// ErrorOf<E>(f): the message of the E that f throws, or "(no error)" when it
// throws nothing; the tests then check which file, line, field and reason the
// message names. Shared by the test folders that check error messages.
#pragma once

#include <string>

namespace locaid::test_support {

template <typename E, typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace locaid::test_support
