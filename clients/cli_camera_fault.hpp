// `locaid camera-fault start|stop|window`: its options and the CameraFault
// message they make (0 = the server's default for each parameter).
#pragma once

#include "locaid/v1/localization.pb.h"

#include <CLI/CLI.hpp>

#include <memory>
#include <string>

namespace locaid::clients {

struct CameraFaultArgs {
  std::string kind;
  double start_s = 0, duration_s = 0, gain = 0, noise_dn = 0, blur_sigma_px = 0;
};

struct CameraFaultCommand {
  CLI::App* command = nullptr;
  CLI::App *start = nullptr, *stop = nullptr, *window = nullptr;
  std::shared_ptr<CameraFaultArgs> args;  // filled by the parser
};

// Adds the subcommand to `app`; the session id goes to `session_id`.
CameraFaultCommand AddCameraFaultCommand(CLI::App& app, std::string& session_id);
locaid::v1::CameraFault CameraFaultMessage(const CameraFaultArgs& args);

}  // namespace locaid::clients
