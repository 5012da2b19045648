#include "kitti/dataset.hpp"

#include "kitti/odometry_sequence.hpp"
#include "kitti/raw_drive.hpp"

#include <system_error>

namespace locaid::kitti {
namespace fs = std::filesystem;

std::unique_ptr<StereoDataset> OpenDataset(const fs::path& path, const RawDriveOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) throw Error(path.string() + ": not a directory");
  if (fs::is_directory(path / "image_00", ec)) return std::make_unique<RawDrive>(path, options);
  if (fs::is_regular_file(path / "calib.txt", ec) && fs::is_regular_file(path / "times.txt", ec)) {
    return std::make_unique<OdometrySequence>(path);
  }
  throw Error(path.string() +
              ": not a KITTI dataset: neither a raw drive (image_00/ with calibration in the "
              "parent folder) nor an odometry sequence (calib.txt and times.txt)");
}

fs::path NormalizeDir(const fs::path& path) {
  fs::path dir = fs::absolute(path).lexically_normal();
  if (!dir.has_filename() && dir.has_parent_path() && dir != dir.root_path()) dir = dir.parent_path();
  return dir;
}

std::unique_ptr<StereoDataset> OpenDataset(const fs::path& path) {
  return OpenDataset(path, RawDriveOptions{});
}

}  // namespace locaid::kitti
