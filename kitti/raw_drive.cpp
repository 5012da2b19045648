#include "kitti/dataset.hpp"
#include "kitti/raw_drive.hpp"

#include "kitti/image_io.hpp"
#include "kitti/oxts.hpp"
#include "kitti/timestamps.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <map>
#include <system_error>

namespace locaid::kitti {
namespace fs = std::filesystem;

namespace {

std::string FrameName(size_t i, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%010zu.%s", i, ext);
  return buf;
}

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

// Index from a KITTI data file name ("0000000017.txt" -> 17); -1 if not all digits.
long ParseIndex(const fs::path& p) {
  std::string stem = p.stem().string();
  if (stem.size() == 10 && stem[0] == '0') stem.erase(0, 1);
  if (stem.empty() || stem.size() > 9) return -1;  // KITTI uses 10 digits, values < 1e9
  long v = 0;
  for (char c : stem) {
    if (c < '0' || c > '9') return -1;
    v = v * 10 + (c - '0');
  }
  return v;
}

cv::Size SizeOf(const Eigen::Vector2d& s) {
  return {static_cast<int>(s(0)), static_cast<int>(s(1))};
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

RawDrive::RawDrive(const fs::path& drive_dir, const RawDriveOptions& options) : dir_(NormalizeDir(drive_dir)) {
  if (!fs::is_directory(dir_ / "image_00")) {
    throw Error(dir_.string() + ": not a KITTI raw drive (no image_00/ folder)");
  }
  calib_ = ReadRawCalib(dir_.parent_path());

  t_ns_ = ReadTimestampsFile(dir_ / "image_00" / "timestamps.txt");
  if (t_ns_.empty()) throw Error((dir_ / "image_00" / "timestamps.txt").string() + ": no frames");
  for (size_t i = 1; i < t_ns_.size(); ++i) {
    if (t_ns_[i] <= t_ns_[i - 1]) {
      report_.notes.push_back("image_00/timestamps.txt: time of frame " + std::to_string(i) +
                              " does not increase");
    }
  }
  const fs::path ts1 = dir_ / "image_01" / "timestamps.txt";
  if (IsFile(ts1)) {
    const auto t1 = ReadTimestampsFile(ts1);
    if (t1.size() != t_ns_.size()) {
      report_.notes.push_back("image_01/timestamps.txt has " + std::to_string(t1.size()) +
                              " lines, image_00 has " + std::to_string(t_ns_.size()));
    }
  } else {
    report_.notes.push_back("image_01/timestamps.txt absent");
  }

  // Images present per frame.
  has_left_.resize(t_ns_.size());
  has_right_.resize(t_ns_.size());
  for (size_t i = 0; i < t_ns_.size(); ++i) {
    has_left_[i] = IsFile(left_path(i));
    has_right_[i] = IsFile(right_path(i));
    if (!has_left_[i]) report_.missing_left.push_back(static_cast<int>(i));
    if (!has_right_[i]) report_.missing_right.push_back(static_cast<int>(i));
  }
  if (!report_.missing_left.empty() || !report_.missing_right.empty()) {
    report_.notes.push_back(std::to_string(report_.missing_left.size()) + " left and " +
                            std::to_string(report_.missing_right.size()) +
                            " right images missing of " + std::to_string(t_ns_.size()) +
                            " frames (has_stereo() false for those frames)");
  }

  // Layout.
  const std::string name = dir_.filename().string();
  const CameraCalib& c0 = calib_.cam_to_cam.cams[0];
  if (options.layout != RawLayout::kAuto) {
    extract_ = options.layout == RawLayout::kExtract;
  } else if (EndsWith(name, "_extract")) {
    extract_ = true;
  } else if (EndsWith(name, "_sync")) {
    extract_ = false;
  } else {
    const auto first = std::find(has_left_.begin(), has_left_.end(), 1);
    if (first == has_left_.end()) {
      throw Error(dir_.string() + ": cannot tell sync from extract: folder name has neither "
                  "suffix and no left image exists");
    }
    const fs::path p = left_path(static_cast<size_t>(first - has_left_.begin()));
    const cv::Size s = ReadGrayImage(p).size();
    if (s == SizeOf(c0.S)) {
      extract_ = true;
    } else if (s == SizeOf(c0.S_rect)) {
      extract_ = false;
    } else {
      throw Error(p.string() + ": image size " + std::to_string(s.width) + "x" +
                  std::to_string(s.height) + " matches neither S_00 nor S_rect_00");
    }
    report_.notes.push_back(std::string("layout detected from the image size: ") +
                            (extract_ ? "extract" : "sync"));
  }

  if (extract_) {
    for (int cam = 0; cam < 2; ++cam) {
      const CameraCalib& c = calib_.cam_to_cam.cams[cam];
      cv::Mat K, D, R, P;
      cv::eigen2cv(c.K, K);
      cv::eigen2cv(Eigen::Matrix<double, 1, 5>(c.D.transpose()), D);
      cv::eigen2cv(c.R_rect, R);
      cv::eigen2cv(Eigen::Matrix3d(c.P_rect.leftCols<3>()), P);
      cv::initUndistortRectifyMap(K, D, R, P, SizeOf(c.S_rect), CV_16SC2, map1_[cam], map2_[cam]);
    }
    if (SizeOf(calib_.cam_to_cam.cams[1].S_rect) != SizeOf(c0.S_rect)) {
      throw Error((dir_.parent_path() / "calib_cam_to_cam.txt").string() +
                  ": S_rect_00 and S_rect_01 differ");
    }
  }

  ReadOxts(options);
  gt_ = ComputeOxtsGroundTruth(oxts_, t_ns_, calib_.T_cam0_imu, options.max_gt_gap_s);
  size_t with_gt = 0;
  for (const auto& g : gt_.T_world_cam) with_gt += g.has_value();
  report_.notes.push_back("ground truth for " + std::to_string(with_gt) + " of " +
                          std::to_string(t_ns_.size()) + " frames" +
                          (gt_.anchor_frame >= 0
                               ? "; world = cam0 at frame " + std::to_string(gt_.anchor_frame)
                               : std::string()));
}

void RawDrive::ReadOxts(const RawDriveOptions& options) {
  const fs::path data = dir_ / "oxts" / "data";
  if (!fs::is_directory(data)) {
    report_.notes.push_back("oxts/data absent: no OXTS records, no ground truth");
    return;
  }
  std::map<long, OxtsRecord> records;  // sorted by index
  for (const auto& entry : fs::directory_iterator(data)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".txt") continue;
    const long index = ParseIndex(entry.path());
    if (index < 0) {
      report_.notes.push_back(entry.path().string() + ": ignored (not a KITTI index name)");
      continue;
    }
    try {
      records[index] = ReadOxtsFile(entry.path());
    } catch (const Error& e) {
      if (!options.skip_bad_oxts) throw;
      report_.oxts_skipped.push_back(std::string("skipped bad OXTS file: ") + e.what());
      report_.notes.push_back(report_.oxts_skipped.back());
    }
  }
  report_.oxts_records = static_cast<int>(records.size());
  if (records.empty()) {
    report_.notes.push_back("oxts/data holds no readable record");
    return;
  }

  const fs::path ts = dir_ / "oxts" / "timestamps.txt";
  std::vector<int64_t> oxts_t;
  const bool have_ts = IsFile(ts);
  if (have_ts) {
    oxts_t = ReadTimestampsFile(ts);
    report_.oxts_expected = static_cast<int>(oxts_t.size());
  } else {
    report_.oxts_timestamps_estimated = true;
    if (extract_) {
      report_.oxts_expected = static_cast<int>(records.rbegin()->first - records.begin()->first + 1);
      report_.notes.push_back(
          "oxts/timestamps.txt absent: OXTS times estimated as t(image_00 frame 0) + " +
          std::to_string(options.extract_oxts_offset_ns / 1e9) + " s + index * " +
          std::to_string(options.extract_oxts_period_ns / 1e9) + " s");
    } else {
      report_.oxts_expected = static_cast<int>(t_ns_.size());
      report_.notes.push_back(
          "oxts/timestamps.txt absent: OXTS record i placed at the image_00 time of frame i");
    }
  }

  for (const auto& [index, record] : records) {
    const fs::path file = data / FrameName(static_cast<size_t>(index), "txt");
    int64_t t = 0;
    if (have_ts || !extract_) {
      const auto& times = have_ts ? oxts_t : t_ns_;
      if (static_cast<size_t>(index) >= times.size()) {
        const std::string msg = file.string() + ": record index " + std::to_string(index) +
                                " has no time (" + std::to_string(times.size()) + " lines in " +
                                (have_ts ? "oxts" : "image_00") + "/timestamps.txt)";
        if (!options.skip_bad_oxts) throw Error(msg);
        report_.oxts_skipped.push_back("skipped OXTS record: " + msg);
        report_.notes.push_back(report_.oxts_skipped.back());
        continue;
      }
      t = times[static_cast<size_t>(index)];
    } else {
      t = t_ns_.front() + options.extract_oxts_offset_ns + index * options.extract_oxts_period_ns;
    }
    oxts_.push_back(OxtsSample{t, static_cast<int>(index), record});
  }
  std::stable_sort(oxts_.begin(), oxts_.end(),
                   [](const OxtsSample& a, const OxtsSample& b) { return a.t_ns < b.t_ns; });
  report_.oxts_records = static_cast<int>(oxts_.size());
  if (report_.oxts_records != report_.oxts_expected) {
    report_.notes.push_back(std::to_string(report_.oxts_records) + " of " +
                            std::to_string(report_.oxts_expected) + " OXTS records present");
  }
}

int64_t RawDrive::time_ns(size_t i) const { return t_ns_.at(i); }

double RawDrive::tum_time_s(size_t i) const {
  return static_cast<double>(t_ns_.at(i) - t_ns_.front()) * 1e-9;
}

bool RawDrive::has_stereo(size_t i) const { return has_left_.at(i) && has_right_.at(i); }

fs::path RawDrive::left_path(size_t i) const {
  return dir_ / "image_00" / "data" / FrameName(i, "png");
}
fs::path RawDrive::right_path(size_t i) const {
  return dir_ / "image_01" / "data" / FrameName(i, "png");
}

cv::Mat RawDrive::LoadOne(const fs::path& path, int cam, bool missing, size_t i,
                          const char* side) const {
  if (missing) {
    throw Error(path.string() + ": " + side + " image of frame " + std::to_string(i) + " missing");
  }
  cv::Mat img = ReadGrayImage(path);
  const CameraCalib& c = calib_.cam_to_cam.cams[cam];
  const cv::Size expected = SizeOf(extract_ ? c.S : c.S_rect);
  if (img.size() != expected) {
    throw Error(path.string() + ": image size " + std::to_string(img.cols) + "x" +
                std::to_string(img.rows) + ", expected " + std::to_string(expected.width) + "x" +
                std::to_string(expected.height) + (extract_ ? " (S_0x)" : " (S_rect_0x)"));
  }
  return Rectify(cam, img);
}

cv::Mat RawDrive::Rectify(int cam, const cv::Mat& raw) const {
  if (!extract_) return raw;
  cv::Mat rect;
  cv::remap(raw, rect, map1_[cam & 1], map2_[cam & 1], cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return rect;
}

StereoImages RawDrive::Load(size_t i, const PairRunner& run) const {
  if (i >= size()) {
    throw Error(dir_.string() + ": frame " + std::to_string(i) + " out of range (" +
                std::to_string(size()) + " frames)");
  }
  StereoImages out;
  run.Run([&] { out.left = LoadOne(left_path(i), 0, !has_left_[i], i, "left"); },
          [&] { out.right = LoadOne(right_path(i), 1, !has_right_[i], i, "right"); });
  return out;
}

std::optional<Eigen::Isometry3d> RawDrive::ground_truth(size_t i) const {
  return gt_.T_world_cam.at(i);
}

}  // namespace locaid::kitti
