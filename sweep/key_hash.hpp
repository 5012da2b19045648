// KeyHasher: the key of a run's inputs, a 64-bit FNV-1a hash of named fields
// printed as 16 hex digits. It detects change (a re-rendered drive, another
// seed, a rebuilt locaid-replay); it is not a defence against anyone
// forging a collision, and nothing here needs one.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace locaid::sweep {

class KeyHasher {
 public:
  // Each field is hashed with its name and both lengths, so ("ab","c") and
  // ("a","bc") differ.
  KeyHasher& Add(std::string_view name, std::string_view value);
  std::string Hex() const;

 private:
  void Bytes(std::string_view s);
  uint64_t h_ = 0xcbf29ce484222325ULL;
};

// The hash of one string, as 16 hex digits (file names of runs).
std::string HashHex(std::string_view text);

}  // namespace locaid::sweep
