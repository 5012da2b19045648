#include "sweep/recording.hpp"

#include "sweep/key_hash.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <system_error>
#include <vector>

namespace fs = std::filesystem;

namespace locaid::sweep {
namespace {

bool HasMcap(const fs::path& dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".mcap") return true;
  return false;
}

// "size:mtime_ns" of a file.
std::string SizeAndTime(const fs::path& file, std::error_code& ec) {
  const auto size = fs::file_size(file, ec);
  if (ec) return {};
  const auto mtime = fs::last_write_time(file, ec);
  if (ec) return {};
  return std::to_string(size) + ":" + std::to_string(mtime.time_since_epoch().count());
}

}  // namespace

std::optional<RecordingKind> ClassifyRecording(const fs::path& path, std::string& why) {
  std::error_code ec;
  if (fs::is_regular_file(path, ec)) {
    if (path.extension() == ".mcap") return RecordingKind::kBag;
    why = "a file that is not a ROS 2 bag (.mcap)";
    return std::nullopt;
  }
  if (!fs::is_directory(path, ec)) {
    why = fs::exists(path, ec) ? "neither a file nor a folder" : "does not exist";
    return std::nullopt;
  }
  // The layouts kitti::OpenDataset and bag::RosBag accept.
  if (fs::is_directory(path / "image_00", ec) ||
      (fs::is_regular_file(path / "calib.txt", ec) && fs::is_regular_file(path / "times.txt", ec)))
    return RecordingKind::kDrive;
  if (fs::is_regular_file(path / "metadata.yaml", ec) || HasMcap(path)) return RecordingKind::kBag;
  why = "not a KITTI drive (no image_00/, nor calib.txt + times.txt) nor a ROS 2 bag (no metadata.yaml or .mcap)";
  return std::nullopt;
}

std::string RecordingKey(const fs::path& path) {
  KeyHasher h;
  h.Add("path", fs::weakly_canonical(path).string());
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    h.Add("file", SizeAndTime(path, ec));
    return h.Hex();
  }
  std::vector<std::pair<std::string, std::string>> files;
  for (auto it = fs::recursive_directory_iterator(path, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    std::error_code fec;
    if (!it->is_regular_file(fec)) continue;
    files.emplace_back(fs::relative(it->path(), path).generic_string(), SizeAndTime(it->path(), fec));
  }
  // A raw drive's calibration sits in the folder above it (2011_09_26/calib_*.txt).
  if (fs::is_directory(path / "image_00", ec)) {
    for (const auto& e : fs::directory_iterator(path.parent_path(), ec)) {
      const std::string name = e.path().filename().string();
      std::error_code fec;
      if (name.rfind("calib", 0) == 0 && e.is_regular_file(fec))
        files.emplace_back("../" + name, SizeAndTime(e.path(), fec));
    }
  }
  std::sort(files.begin(), files.end());  // directory order is not stable across file systems
  for (const auto& [rel, st] : files) h.Add(rel, st);
  return h.Hex();
}

std::string FileFingerprint(const fs::path& path) {
  std::error_code ec;
  const std::string st = SizeAndTime(path, ec);
  if (ec) return "";
  return KeyHasher().Add("path", fs::weakly_canonical(path).string()).Add("file", st).Hex();
}

std::string ReadFileText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace locaid::sweep
