// libFuzzer target: locaid-sweep manifests (sweep/manifest.hpp). The
// manifest is written into a scratch folder holding a drive folder, a bag
// file and a scenario file it may name by relative path.
// Contract: LoadManifest returns a manifest or throws ManifestError (no
// yaml-cpp or other exception escapes); an accepted one has recordings,
// scenarios, seeds and IMU settings, each recording once and existing, and
// no reserved replay argument. Inputs with glob patterns across folders
// ("/*", "*/", "..") are skipped: they would walk the machine's files.
#include "fuzz/fuzz_support.hpp"
#include "sweep/manifest.hpp"

#include <exception>
#include <fstream>
#include <set>
#include <typeinfo>

namespace {

const std::filesystem::path& Scratch() {
  static locaid::fuzz::ScratchDir scratch;
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = scratch / "sweep";
    std::filesystem::create_directories(d / "drive_sync" / "image_00");
    std::ofstream(d / "drive.mcap") << "\x89MCAP0\r\n";
    std::ofstream(d / "outage.yaml") << "base: open-sky\noutages: [{start_s: 5, duration_s: 10}]\n";
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  for (const char* walk : {"/*", "*/", "..", "**"})
    if (text.find(walk) != std::string::npos) return 0;
  const std::filesystem::path file = Scratch() / "sweep.yaml";
  std::ofstream(file, std::ios::binary | std::ios::trunc) << text;
  locaid::sweep::Manifest m;
  try {
    m = locaid::sweep::LoadManifest(file);
  } catch (const locaid::sweep::ManifestError&) {
    return 0;
  } catch (const std::exception& e) {
    locaid::fuzz::Fail(std::string("LoadManifest threw ") + typeid(e).name() + ": " + e.what());
  }
  LOCAID_FUZZ_CHECK(!m.recordings.empty() && !m.scenarios.empty() && !m.seeds.empty() && !m.imu.empty(),
                    "an accepted manifest without runs");
  std::set<std::filesystem::path> seen;
  for (const auto& r : m.recordings) {
    LOCAID_FUZZ_CHECK(seen.insert(r.path).second, "a recording listed twice");
    LOCAID_FUZZ_CHECK(std::filesystem::exists(r.path), "a recording that does not exist");
  }
  for (const auto& a : m.replay_args) LOCAID_FUZZ_CHECK(!locaid::sweep::IsReservedReplayArg(a), "a reserved replay arg");
  return 0;
}
