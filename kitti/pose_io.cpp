#include "kitti/pose_io.hpp"

#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

namespace locaid::kitti {
namespace {

constexpr size_t kKittiColumns = 12;
constexpr size_t kTumColumns = 8;
// A quaternion shorter than this cannot be normalised meaningfully.
constexpr double kMinQuaternionNorm = 1e-9;

std::string Where(const std::filesystem::path& path, size_t line_number) {
  return path.string() + ":" + std::to_string(line_number);
}

std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

bool IsBlank(std::string_view line) { return SplitWhitespace(line).empty(); }

bool IsComment(std::string_view line) {
  size_t i = line.find_first_not_of(" \t\r");
  return i != std::string_view::npos && line[i] == '#';
}

// Parses all tokens of one line as finite doubles, checking the count first.
std::vector<double> ParseNumbers(std::string_view line, size_t expected, const std::string& where,
                                 const char* layout) {
  std::vector<std::string_view> tokens = SplitWhitespace(line);
  if (tokens.size() != expected) {
    throw Error(where + ": " + std::to_string(tokens.size()) + " numbers, expected " +
                std::to_string(expected) + " (" + layout + ")");
  }
  std::vector<double> values(tokens.size());
  for (size_t k = 0; k < tokens.size(); ++k) {
    std::string_view tok = tokens[k];
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    double v = 0;
    auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (ec == std::errc::result_out_of_range) {
      throw Error(where + ": number " + std::to_string(k + 1) + " '" + std::string(tokens[k]) +
                  "' is out of range for a double");
    }
    if (ec != std::errc() || ptr != tok.data() + tok.size()) {
      throw Error(where + ": number " + std::to_string(k + 1) + " '" + std::string(tokens[k]) +
                  "' is not a number");
    }
    if (!std::isfinite(v)) {
      throw Error(where + ": number " + std::to_string(k + 1) + " '" + std::string(tokens[k]) +
                  "' is not finite");
    }
    values[k] = v;
  }
  return values;
}

std::ifstream OpenForReading(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    throw Error(path.string() + ": cannot open for reading: " + std::strerror(errno));
  }
  return in;
}

Eigen::Isometry3d KittiPoseFromLine(std::string_view line, const std::string& where,
                                    const PoseReadConfig& config) {
  std::vector<double> v = ParseNumbers(line, kKittiColumns, where, "KITTI 3x4 row-major");
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) M(r, c) = v[static_cast<size_t>(r * 4 + c)];
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double orth_err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double det = R.determinant();
  if (orth_err > config.rotation_tolerance || std::abs(det - 1.0) > config.rotation_tolerance) {
    throw Error(where + ": 3x3 block is not a rotation (max |R^T R - I| = " +
                std::to_string(orth_err) + ", det = " + std::to_string(det) + ", tolerance " +
                std::to_string(config.rotation_tolerance) + ")");
  }
  Eigen::Isometry3d T;
  T.matrix() = M;  // kept exactly as read
  return T;
}

StampedPose TumPoseFromLine(std::string_view line, const std::string& where) {
  std::vector<double> v = ParseNumbers(line, kTumColumns, where, "TUM: t tx ty tz qx qy qz qw");
  Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // w, x, y, z
  const double norm = q.norm();
  if (norm < kMinQuaternionNorm) {
    throw Error(where + ": quaternion has zero norm (" + std::to_string(norm) + ")");
  }
  q.coeffs() /= norm;
  StampedPose p;
  p.t_s = v[0];
  p.T_world_cam = Eigen::Isometry3d::Identity();
  p.T_world_cam.linear() = q.toRotationMatrix();
  p.T_world_cam.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
  return p;
}

void AppendNumber(std::string& out, double v) {
  char buf[64];
  auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip
  if (ec != std::errc()) throw Error("cannot format number");
  out.append(buf, ptr);
}

void WriteAtomically(const std::filesystem::path& path, const std::string& content) {
  static std::atomic<unsigned> counter{0};
  std::filesystem::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      throw Error(path.string() + ": cannot create temporary file " + tmp.string() + ": " +
                  std::strerror(errno));
    }
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out) {
      std::error_code ignore;
      std::filesystem::remove(tmp, ignore);
      throw Error(path.string() + ": write to " + tmp.string() + " failed: " + std::strerror(errno));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignore;
    std::filesystem::remove(tmp, ignore);
    throw Error(path.string() + ": cannot rename " + tmp.string() + " into place: " + ec.message());
  }
}

}  // namespace

std::vector<Eigen::Isometry3d> ReadKittiPoses(const std::filesystem::path& path,
                                              const PoseReadConfig& config) {
  std::ifstream in = OpenForReading(path);
  std::vector<Eigen::Isometry3d> poses;
  std::string line;
  size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (IsBlank(line)) continue;
    poses.push_back(KittiPoseFromLine(line, Where(path, line_number), config));
  }
  if (in.bad()) throw Error(path.string() + ": read error after line " + std::to_string(line_number));
  return poses;
}

std::vector<StampedPose> ReadTumPoses(const std::filesystem::path& path) {
  std::ifstream in = OpenForReading(path);
  std::vector<StampedPose> poses;
  std::string line;
  size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (IsBlank(line) || IsComment(line)) continue;
    poses.push_back(TumPoseFromLine(line, Where(path, line_number)));
  }
  if (in.bad()) throw Error(path.string() + ": read error after line " + std::to_string(line_number));
  return poses;
}

PoseFile ReadPoses(const std::filesystem::path& path, const PoseReadConfig& config) {
  std::ifstream in = OpenForReading(path);
  std::string line;
  size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (IsBlank(line) || IsComment(line)) continue;
    const size_t columns = SplitWhitespace(line).size();
    in.close();
    PoseFile file;
    if (columns == kKittiColumns) {
      file.format = PoseFormat::kKitti;
      std::vector<Eigen::Isometry3d> kitti = ReadKittiPoses(path, config);
      file.poses.resize(kitti.size());
      for (size_t i = 0; i < kitti.size(); ++i) {
        file.poses[i].t_s = static_cast<double>(i);
        file.poses[i].T_world_cam = kitti[i];
      }
    } else if (columns == kTumColumns) {
      file.format = PoseFormat::kTum;
      file.poses = ReadTumPoses(path);
    } else {
      throw Error(Where(path, line_number) + ": " + std::to_string(columns) +
                  " columns: neither KITTI (12) nor TUM (8) pose format");
    }
    return file;
  }
  throw Error(path.string() + ": no pose line (file is empty or only comments)");
}

void WriteKittiPoses(const std::filesystem::path& path,
                     const std::vector<Eigen::Isometry3d>& poses_T_world_cam) {
  std::string content;
  content.reserve(poses_T_world_cam.size() * 12 * 24);
  for (const Eigen::Isometry3d& T : poses_T_world_cam) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (r != 0 || c != 0) content += ' ';
        AppendNumber(content, T.matrix()(r, c));
      }
    }
    content += '\n';
  }
  WriteAtomically(path, content);
}

void WriteTumPoses(const std::filesystem::path& path, const std::vector<StampedPose>& poses) {
  std::string content;
  content.reserve(poses.size() * 8 * 24);
  for (const StampedPose& p : poses) {
    const Eigen::Quaterniond q(p.T_world_cam.rotation());
    const Eigen::Vector3d t = p.T_world_cam.translation();
    const double values[kTumColumns] = {p.t_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
    for (size_t k = 0; k < kTumColumns; ++k) {
      if (k != 0) content += ' ';
      AppendNumber(content, values[k]);
    }
    content += '\n';
  }
  WriteAtomically(path, content);
}

}  // namespace locaid::kitti
