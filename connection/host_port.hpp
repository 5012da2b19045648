// "HOST:PORT" or "HOST" as a program names a service it or the server
// reaches (`--gpsd 127.0.0.1:2947`, the server YAML's `live_cameras.gpsd`):
// one parse for every place that takes one.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace locaid::connection {

struct HostPort {
  std::string host;
  uint32_t port = 0;  // 0: not given (the service's default)
};

// Throws std::invalid_argument naming `what` and the value when the port is
// not 1-5 digits.
inline HostPort SplitHostPort(const std::string& value, const std::string& what) {
  HostPort out;
  const auto colon = value.rfind(':');
  out.host = value.substr(0, colon);
  if (colon == std::string::npos) return out;
  const std::string port = value.substr(colon + 1);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos) {
    throw std::invalid_argument(what + " '" + value + "': expected HOST:PORT");
  }
  out.port = static_cast<uint32_t>(std::stoul(port));
  return out;
}

}  // namespace locaid::connection
