// A recording of a sweep: a KITTI drive folder (raw sync/extract or odometry
// sequence, including synthetic drives) or a ROS 2 bag (one .mcap file, or a
// rosbag2 folder). What kind a path is, told from its layout without reading
// it, and the key of its content.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace locaid::sweep {

enum class RecordingKind { kDrive, kBag };

// nullopt with `why` set when `path` is neither: names what was looked for.
std::optional<RecordingKind> ClassifyRecording(const std::filesystem::path& path, std::string& why);

// The key of a recording's content: its canonical path (a VO cache names
// the drive it was made from) and, for every file under it (or the one
// file), its relative path, size and modification time. Hashing the bytes of
// gigabytes of images each time a sweep is planned would take minutes per
// recording; a changed file gets a new size or mtime in practice (a copy that
// keeps both, e.g. `cp -p` of other bytes over it, is not noticed).
std::string RecordingKey(const std::filesystem::path& path);

// The key of a regular file by the same rule (a --bag-topics file, the
// locaid-replay binary); "" when it does not exist.
std::string FileFingerprint(const std::filesystem::path& path);

// A small file's bytes (a scenario or --bag-topics file, a run's JSON
// output); "" when it cannot be read.
std::string ReadFileText(const std::filesystem::path& path);

}  // namespace locaid::sweep
