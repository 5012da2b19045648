#include "kitti/dataset.hpp"
#include "kitti/odometry_sequence.hpp"

#include "kitti/image_io.hpp"
#include "kitti/pose_io.hpp"
#include "kitti/timestamps.hpp"

#include <cmath>
#include <cstdio>
#include <system_error>

namespace locaid::kitti {
namespace fs = std::filesystem;

namespace {

std::string FrameName(size_t i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06zu.png", i);
  return buf;
}

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

}  // namespace

OdometrySequence::OdometrySequence(const fs::path& sequence_dir) : dir_(NormalizeDir(sequence_dir)) {
  calib_ = ReadOdometryCalib(dir_ / "calib.txt");
  times_s_ = ReadOdometryTimes(dir_ / "times.txt");
  if (times_s_.empty()) throw Error((dir_ / "times.txt").string() + ": no frames");

  has_left_.resize(times_s_.size());
  has_right_.resize(times_s_.size());
  for (const char* folder : {"image_0", "image_1"}) {
    if (!fs::is_directory(dir_ / folder)) {
      report_.notes.push_back(std::string(folder) + "/ absent: no images for any of the " +
                              std::to_string(times_s_.size()) + " frames");
    }
  }
  int first_left = -1;
  for (size_t i = 0; i < times_s_.size(); ++i) {
    has_left_[i] = IsFile(left_path(i));
    has_right_[i] = IsFile(right_path(i));
    if (!has_left_[i]) report_.missing_left.push_back(static_cast<int>(i));
    if (!has_right_[i]) report_.missing_right.push_back(static_cast<int>(i));
    if (has_left_[i] && first_left < 0) first_left = static_cast<int>(i);
  }
  if (!report_.missing_left.empty() || !report_.missing_right.empty()) {
    report_.notes.push_back(std::to_string(report_.missing_left.size()) + " left and " +
                            std::to_string(report_.missing_right.size()) +
                            " right images missing of " + std::to_string(times_s_.size()) +
                            " frames");
  }
  int width = 0, height = 0;
  if (first_left >= 0) {
    const cv::Mat img = ReadGrayImage(left_path(static_cast<size_t>(first_left)));
    width = img.cols;
    height = img.rows;
  } else {
    report_.notes.push_back("no left image: camera().width/height are 0");
  }
  camera_ = OdometryStereo(calib_, width, height);

  const fs::path poses = dir_.parent_path().parent_path() / "poses" /
                         (dir_.filename().string() + ".txt");
  if (IsFile(poses)) {
    poses_ = ReadKittiPoses(poses);
    if (poses_.size() != times_s_.size()) {
      report_.notes.push_back(poses.string() + ": " + std::to_string(poses_.size()) +
                              " poses for " + std::to_string(times_s_.size()) +
                              " frames (ground truth only where both exist)");
    }
  } else {
    report_.notes.push_back(poses.string() + " absent: no ground truth");
  }
}

int64_t OdometrySequence::time_ns(size_t i) const {
  return static_cast<int64_t>(std::llround(times_s_.at(i) * 1e9));
}

bool OdometrySequence::has_stereo(size_t i) const { return has_left_.at(i) && has_right_.at(i); }

fs::path OdometrySequence::left_path(size_t i) const { return dir_ / "image_0" / FrameName(i); }
fs::path OdometrySequence::right_path(size_t i) const { return dir_ / "image_1" / FrameName(i); }

StereoImages OdometrySequence::Load(size_t i, const PairRunner& run) const {
  if (i >= size()) {
    throw Error(dir_.string() + ": frame " + std::to_string(i) + " out of range (" +
                std::to_string(size()) + " frames)");
  }
  const auto load = [&](const char* side, const fs::path& path, bool present) {
    if (!present) {
      throw Error(path.string() + ": " + side + " image of frame " + std::to_string(i) + " missing");
    }
    cv::Mat img = ReadGrayImage(path);
    if (img.cols != camera_.width || img.rows != camera_.height) {
      throw Error(path.string() + ": image size " + std::to_string(img.cols) + "x" +
                  std::to_string(img.rows) + ", expected " + std::to_string(camera_.width) +
                  "x" + std::to_string(camera_.height) + " (first left image)");
    }
    return img;
  };
  StereoImages out;
  run.Run([&] { out.left = load("left", left_path(i), has_left_[i]); },
          [&] { out.right = load("right", right_path(i), has_right_[i]); });
  return out;
}

std::optional<Eigen::Isometry3d> OdometrySequence::ground_truth(size_t i) const {
  if (i >= size()) throw Error(dir_.string() + ": frame " + std::to_string(i) + " out of range");
  if (i >= poses_.size()) return std::nullopt;
  return poses_[i];
}

}  // namespace locaid::kitti
