#include "server/synthetic_drive.hpp"

#include "kitti/synth/synth.hpp"

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <functional>
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

kitti::synth::SynthConfig ParseOptions(const std::string& yaml, uint64_t seed, size_t frames) {
  kitti::synth::SynthConfig config;
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

std::mutex g_render_mutex;  // two sessions never render the same folder at once

}  // namespace

std::unique_ptr<kitti::StereoDataset> MakeSyntheticDrive(const std::string& work_dir, uint64_t seed, size_t frames,
                                                         const std::string& options_yaml) {
  const kitti::synth::SynthConfig config = ParseOptions(options_yaml, seed, frames);
  const std::filesystem::path root =
      work_dir.empty() ? std::filesystem::temp_directory_path() / ("locaid-server-" + std::to_string(::getuid()))
                       : std::filesystem::path(work_dir);
  const std::string key = "seed" + std::to_string(seed) + "_f" + std::to_string(frames) + "_" +
                          std::to_string(std::hash<std::string>{}(options_yaml) % 100000);
  const std::filesystem::path dir = root / "synthetic" / key;
  std::lock_guard lock(g_render_mutex);
  try {
    const auto marker = dir / "complete";
    if (!std::filesystem::exists(marker)) {
      std::filesystem::remove_all(dir);
      std::filesystem::create_directories(dir);
      const auto summary = kitti::synth::GenerateDrive(config, dir);
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
