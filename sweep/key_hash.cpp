#include "sweep/key_hash.hpp"

#include <cstdio>

namespace locaid::sweep {

void KeyHasher::Bytes(std::string_view s) {
  for (const unsigned char c : s) {
    h_ ^= c;
    h_ *= 0x100000001b3ULL;
  }
}

KeyHasher& KeyHasher::Add(std::string_view name, std::string_view value) {
  Bytes(std::to_string(name.size()) + ":");
  Bytes(name);
  Bytes(std::to_string(value.size()) + ":");
  Bytes(value);
  return *this;
}

std::string KeyHasher::Hex() const {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h_));
  return buf;
}

std::string HashHex(std::string_view text) { return KeyHasher().Add("", text).Hex(); }

}  // namespace locaid::sweep
