#include "server/synthetic_drive.hpp"

#include "synth/synth.hpp"

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <unistd.h>

namespace locaid::server {

Eigen::Isometry3d KittiRigTcam0Imu() {
  Eigen::Matrix<double, 3, 4> m;
  m << 0.000998747, -0.999990382, 0.004259378, -0.314076870,  //
      0.008416902, -0.004250821, -0.999955570, 0.719452036,   //
      0.999964049, 0.001034553, 0.008412575, -1.089082940;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(Eigen::Matrix3d(m.leftCols<3>())).normalized().toRotationMatrix();
  T.translation() = m.col(3);
  return T;
}

namespace {

synth::SynthConfig ParseOptions(const std::string& yaml, uint64_t seed, size_t frames) {
  synth::SynthConfig config;
  config.seed = seed;
  config.frames = static_cast<int>(frames);
  if (yaml.empty()) return config;
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& e) {
    throw SyntheticError(std::string("synthetic.options_yaml: ") + e.what());
  }
  if (root.IsNull()) return config;
  if (!root.IsMap()) throw SyntheticError("synthetic.options_yaml: expected a map");
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    try {
      if (key == "width") config.width = kv.second.as<int>();
      else if (key == "height") config.height = kv.second.as<int>();
      else if (key == "frame_rate_hz") config.frame_rate_hz = kv.second.as<double>();
      else if (key == "length_m") config.length_m = kv.second.as<double>();
      else if (key == "noise_sigma_dn") config.noise_sigma_dn = kv.second.as<double>();
      else throw SyntheticError("synthetic.options_yaml: unknown key '" + key +
                                "' (known: width, height, frame_rate_hz, length_m, noise_sigma_dn)");
    } catch (const YAML::Exception& e) {
      throw SyntheticError("synthetic.options_yaml: key '" + key + "': " + e.msg);
    }
  }
  return config;
}

// One lock per drive folder: two sessions never render the same folder at
// once, different folders render in parallel. Entries are never erased (one
// per distinct drive key, a few dozen bytes each).
std::mutex& FolderLock(const std::string& key) {
  static std::mutex map_mu;
  static std::map<std::string, std::unique_ptr<std::mutex>> locks;
  std::lock_guard lock(map_mu);
  auto& m = locks[key];
  if (!m) m = std::make_unique<std::mutex>();
  return *m;
}

}  // namespace

SyntheticRig ValidateSyntheticRequest(uint64_t seed, size_t frames, const std::string& options_yaml,
                                      size_t max_frames) {
  const synth::SynthConfig config = ParseOptions(options_yaml, seed, frames);
  try {
    synth::ValidateSynthConfig(config);
  } catch (const kitti::Error& e) {
    throw SyntheticError(std::string("synthetic.options_yaml: ") + e.what());
  }
  // A length_m drive lasts at most length / slowest speed (+ 5 s of margin).
  const double frames_needed =
      config.length_m > 0 ? (config.length_m / config.speed_min_mps + 5) * config.frame_rate_hz
                          : static_cast<double>(config.frames);
  if (frames_needed > static_cast<double>(max_frames)) {
    throw SyntheticError("synthetic: the drive needs up to " + std::to_string(static_cast<long long>(frames_needed)) +
                         " frames, more than the server's max_synthetic_frames (" + std::to_string(max_frames) + ")");
  }
  const synth::SynthCalib calib = synth::MakeSynthCalib(config.width, config.height);
  return {calib.stereo, calib.T_cam0_imu};
}

std::filesystem::path SyntheticRoot(const std::string& work_dir) {
  const std::filesystem::path root =
      work_dir.empty() ? std::filesystem::temp_directory_path() / ("locaid-server-" + std::to_string(::getuid()))
                       : std::filesystem::path(work_dir);
  return root / "synthetic";
}

size_t RemoveStaleSyntheticDrives(const std::string& work_dir) {
  std::error_code ec;
  const auto root = SyntheticRoot(work_dir);
  size_t removed = 0;
  for (const auto& e : std::filesystem::directory_iterator(root, ec)) {
    std::error_code rm;
    std::filesystem::remove_all(e.path(), rm);
    removed += rm ? 0 : 1;
  }
  return removed;
}

std::unique_ptr<kitti::StereoDataset> MakeSyntheticDrive(const std::filesystem::path& dir, uint64_t seed,
                                                         size_t frames, const std::string& options_yaml,
                                                         const std::atomic<bool>* cancel) {
  const synth::SynthConfig config = ParseOptions(options_yaml, seed, frames);
  std::lock_guard lock(FolderLock(dir.string()));
  try {
    const auto marker = dir / "complete";
    if (!std::filesystem::exists(marker)) {
      std::filesystem::remove_all(dir);
      std::filesystem::create_directories(dir);
      const auto stop_if_cancelled = [cancel](int, int) {
        if (cancel && cancel->load()) throw SyntheticCancelled();
      };
      synth::SynthSummary summary;
      try {
        summary = synth::GenerateDrive(config, dir, stop_if_cancelled);
      } catch (const SyntheticCancelled&) {
        std::error_code ec;
        std::filesystem::remove_all(dir, ec);
        throw;
      }
      std::ofstream(marker) << summary.drive_dir.filename().string() << "\n";
    }
    std::string drive;
    std::ifstream(marker) >> drive;
    return kitti::OpenDataset(dir / drive);
  } catch (const kitti::Error& e) {
    throw SyntheticError(e.what());
  } catch (const std::filesystem::filesystem_error& e) {
    throw SyntheticError(std::string("work_dir: ") + e.what());
  }
}

}  // namespace locaid::server
