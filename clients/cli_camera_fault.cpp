#include "clients/cli_camera_fault.hpp"

#include <algorithm>
#include <vector>

namespace locaid::clients {
namespace v1 = locaid::v1;
namespace {

// The --kind names, as in scenario YAML, in the order of CameraFault.Kind.
std::vector<std::string> CameraFaultKindNames() {
  return {"dark", "noise", "blur", "frozen", "drop", "left_only", "right_only"};
}

}  // namespace

CameraFaultCommand AddCameraFaultCommand(CLI::App& app, std::string& session_id) {
  CameraFaultCommand c;
  c.args = std::make_shared<CameraFaultArgs>();
  CameraFaultArgs& a = *c.args;
  c.command = app.add_subcommand("camera-fault", "inject camera faults (dark, frozen, dropped images ...)");
  c.command->require_subcommand(1);
  c.start = c.command->add_subcommand("start", "the fault from the next frame on");
  c.stop = c.command->add_subcommand("stop", "end every injected camera fault now (the scenario's stay)");
  c.window = c.command->add_subcommand("window", "the fault in [start, start+duration) since the first frame");
  for (auto* cmd : {c.start, c.stop, c.window}) cmd->add_option("id", session_id)->required();
  for (auto* cmd : {c.start, c.window}) {
    cmd->add_option("--kind", a.kind, "dark|noise|blur|frozen|drop|left_only|right_only")
        ->required()
        ->check(CLI::IsMember(CameraFaultKindNames()));
    cmd->add_option("--gain", a.gain, "dark: image gain in (0, 1] (0 = 0.06)");
    cmd->add_option("--noise-dn", a.noise_dn, "dark, noise: 1-sigma noise, DN (0 = 3 dark, 8 noise)");
    cmd->add_option("--blur-px", a.blur_sigma_px, "blur: Gaussian sigma, px (0 = 3)");
  }
  c.start->add_option("--duration", a.duration_s, "seconds of sensor time (0 = until 'camera-fault stop')");
  c.window->add_option("--start", a.start_s, "seconds since the first frame")->required();
  c.window->add_option("--duration", a.duration_s, "seconds")->required();
  return c;
}

v1::CameraFault CameraFaultMessage(const CameraFaultArgs& a) {
  v1::CameraFault f;
  const std::vector<std::string> names = CameraFaultKindNames();
  const auto it = std::find(names.begin(), names.end(), a.kind);  // checked by the parser
  f.set_kind(static_cast<v1::CameraFault::Kind>(v1::CameraFault::DARK + (it - names.begin())));
  f.set_start_s(a.start_s);
  f.set_duration_s(a.duration_s);
  f.set_gain(a.gain);
  f.set_noise_dn(a.noise_dn);
  f.set_blur_sigma_px(a.blur_sigma_px);
  return f;
}

}  // namespace locaid::clients
