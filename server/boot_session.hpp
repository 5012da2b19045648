// The live camera session a server starts itself (ServerConfig::live_cameras,
// a car that boots into localisation): built as `locaid session start --live`
// builds it, started once the server listens and retried every 5 s on a
// thread of its own while it cannot start (cameras that come up after the
// server), each new reason logged once.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "server/config.hpp"

#include <grpcpp/support/status.h>

#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace locaid::server {

// The StartSessionRequest of `boot`; throws std::runtime_error naming a
// camera_info file that cannot be read or a gpsd that is not HOST[:PORT].
locaid::v1::StartSessionRequest BootCamerasRequest(const BootCameras& boot);

class BootSession {
 public:
  static constexpr double kRetryS = 5.0;
  using Starter = std::function<grpc::Status(const locaid::v1::StartSessionRequest&, std::string*)>;
  // `log` gets one line per event (started, or a new reason it cannot start).
  BootSession(BootCameras boot, Starter start, std::function<void(const std::string&)> log);
  ~BootSession();  // stops retrying (joins the thread); a started session goes on
  BootSession(const BootSession&) = delete;
  BootSession& operator=(const BootSession&) = delete;

 private:
  void Run();

  BootCameras boot_;
  Starter start_;
  std::function<void(const std::string&)> log_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace locaid::server
