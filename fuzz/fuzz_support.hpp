// Helpers shared by the libFuzzer targets in fuzz/.
//
// Contract every target checks: a parser of outside input either returns a
// value that satisfies its documented invariants or throws its documented
// exception type. Anything else (another exception type, a crash, a sanitizer
// report, a broken invariant) aborts, so libFuzzer records the input.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>

namespace locaid::fuzz {

// Prints `what` and aborts: the fuzzer keeps the input as a crash.
[[noreturn]] inline void Fail(const std::string& what) {
  std::fprintf(stderr, "locaid fuzz contract violated: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

#define LOCAID_FUZZ_CHECK(cond, msg)                                             \
  do {                                                                           \
    if (!(cond)) ::locaid::fuzz::Fail(std::string(#cond) + ": " + (msg));        \
  } while (0)

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// An anonymous in-memory file (memfd) reachable through a path, for parsers
// that only read from a path. One per process, rewritten for every input.
class MemFile {
 public:
  MemFile() {
    fd_ = ::memfd_create("locaid-fuzz", 0);
    if (fd_ < 0) Fail("memfd_create failed");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemFile() { ::close(fd_); }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;

  // Replaces the file content with `bytes` and returns its path.
  const std::filesystem::path& Write(std::string_view bytes) {
    if (::ftruncate(fd_, 0) != 0) Fail("ftruncate failed");
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done,
                                 static_cast<off_t>(done));
      if (n <= 0) Fail("pwrite failed");
      done += static_cast<size_t>(n);
    }
    return path_;
  }

 private:
  int fd_ = -1;
  std::filesystem::path path_;
};

// A private scratch folder for writer round trips (removed at exit).
class ScratchDir {
 public:
  ScratchDir() {
    std::error_code ec;
    std::filesystem::path base = std::filesystem::temp_directory_path(ec);
    if (ec) base = "/tmp";
    dir_ = base / ("locaid-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_, ec);
    if (ec) Fail("cannot create " + dir_.string());
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::filesystem::path operator/(const std::string& name) const { return dir_ / name; }

 private:
  std::filesystem::path dir_;
};

}  // namespace locaid::fuzz
