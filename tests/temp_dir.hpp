// ScopedTempDir: a folder of the test's own, made by mkdtemp under $TMPDIR
// (/tmp when unset) and removed with everything in it when the object goes.
// Every test that writes files works in one: a run leaves nothing behind, and
// two runs at once (or two tests of one run) never share a name. Shared by
// every test folder; the Python and JavaScript tests use mkdtemp likewise.
#pragma once

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace locaid::test_support {

class ScopedTempDir {
 public:
  // `label` (any text, e.g. a test name) goes into the folder's name to tell
  // a leftover apart; characters other than [A-Za-z0-9_-] become '_'.
  explicit ScopedTempDir(const std::string& label = "test") {
    const char* env = std::getenv("TMPDIR");
    const std::filesystem::path base = env != nullptr && *env != '\0' ? env : "/tmp";
    std::string name = "locaid_";
    for (const char c : label.substr(0, 40)) {
      const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                         c == '-';
      name += plain ? c : '_';
    }
    std::string pattern = (base / (name + "_XXXXXX")).string();
    std::vector<char> buffer(pattern.begin(), pattern.end());
    buffer.push_back('\0');
    if (::mkdtemp(buffer.data()) == nullptr) {
      throw std::system_error(errno, std::generic_category(), "mkdtemp " + pattern);
    }
    path_ = buffer.data();
  }
  ~ScopedTempDir() {
    std::error_code ignored;  // a destructor must not throw; a leftover is visible by its name
    std::filesystem::remove_all(path_, ignored);
  }
  ScopedTempDir(const ScopedTempDir&) = delete;
  ScopedTempDir& operator=(const ScopedTempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  operator const std::filesystem::path&() const { return path_; }  // NOLINT: used where a folder is asked for
  std::filesystem::path operator/(const std::filesystem::path& relative) const { return path_ / relative; }

 private:
  std::filesystem::path path_;
};

}  // namespace locaid::test_support
