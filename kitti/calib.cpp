#include "kitti/calib.hpp"
#include "core/stereo_camera.hpp"

#include "kitti/parse_number.hpp"

#include <Eigen/SVD>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace locaid::kitti {
namespace {

struct Entry {
  int line = 0;
  std::string value;  // text after "key:"
};

std::string_view Trim(std::string_view s) {
  const char* ws = " \t\r\n";
  const size_t b = s.find_first_not_of(ws);
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(ws) - b + 1);
}

// Splits "key: value" lines. Blank lines are skipped; a non-blank line without
// ':' or a repeated key is an error.
class KeyValues {
 public:
  KeyValues(std::string_view text, std::string where) : where_(std::move(where)) {
    int line_no = 0;
    size_t pos = 0;
    while (pos <= text.size()) {
      size_t end = text.find('\n', pos);
      if (end == std::string_view::npos) end = text.size();
      const std::string_view line = Trim(text.substr(pos, end - pos));
      ++line_no;
      pos = end + 1;
      if (line.empty()) continue;
      const size_t colon = line.find(':');
      if (colon == std::string_view::npos || colon == 0) {
        throw Error(where_ + ":" + std::to_string(line_no) + ": expected 'key: values', got '" +
                    std::string(line) + "'");
      }
      const std::string key(Trim(line.substr(0, colon)));
      if (entries_.count(key)) {
        throw Error(where_ + ":" + std::to_string(line_no) + ": key '" + key +
                    "' repeated (first on line " + std::to_string(entries_[key].line) + ")");
      }
      entries_[key] = Entry{line_no, std::string(Trim(line.substr(colon + 1)))};
    }
  }

  bool Has(const std::string& key) const { return entries_.count(key) != 0; }

  std::string Text(const std::string& key) const {
    auto it = entries_.find(key);
    return it == entries_.end() ? std::string() : it->second.value;
  }

  // Exactly `count` finite numbers under `key`.
  std::vector<double> Numbers(const std::string& key, size_t count) const {
    auto it = entries_.find(key);
    if (it == entries_.end()) throw Error(where_ + ": missing key '" + key + "'");
    const std::string at = where_ + ":" + std::to_string(it->second.line) + ": key '" + key + "': ";
    std::vector<double> out;
    std::istringstream ss(it->second.value);
    std::string tok;
    while (ss >> tok) {
      double v = 0;
      std::string why;
      if (!ParseFiniteDouble(tok, v, why)) {
        throw Error(at + "value " + std::to_string(out.size() + 1) + " " + why + ": '" + tok + "'");
      }
      out.push_back(v);
    }
    if (out.size() != count) {
      throw Error(at + std::to_string(out.size()) + " numbers, expected " + std::to_string(count));
    }
    return out;
  }

  template <int R, int C>
  Eigen::Matrix<double, R, C> Matrix(const std::string& key) const {
    const auto v = Numbers(key, R * C);
    Eigen::Matrix<double, R, C> m;
    for (int r = 0; r < R; ++r)
      for (int c = 0; c < C; ++c) m(r, c) = v[r * C + c];  // row-major in the file
    return m;
  }

  // R (3x3) and T (3) as an isometry; R must be a rotation (|R^T R - I| < 1e-4,
  // det > 0; KITTI prints 7 digits).
  Eigen::Isometry3d Rigid(const std::string& r_key, const std::string& t_key) const {
    const Eigen::Matrix3d R = Matrix<3, 3>(r_key);
    CheckRotation(R, r_key);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = Matrix<3, 1>(t_key);
    return T;
  }

  void CheckRotation(const Eigen::Matrix3d& R, const std::string& key) const {
    constexpr double kOrthoTol = 1e-4;
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (err > kOrthoTol || R.determinant() <= 0) {
      auto it = entries_.find(key);
      throw Error(where_ + ":" + std::to_string(it->second.line) + ": key '" + key +
                  "': not a rotation matrix (|R^T R - I| = " + std::to_string(err) +
                  ", det = " + std::to_string(R.determinant()) + ")");
    }
  }

  const std::string& where() const { return where_; }

 private:
  std::string where_;
  std::map<std::string, Entry> entries_;
};

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot open calibration file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(path.string() + ": cannot open for writing");
  out << text;
  if (!out) throw Error(path.string() + ": write failed");
}

std::string Num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.16e", v);
  return buf;
}

template <typename Derived>
std::string Line(const std::string& key, const Eigen::MatrixBase<Derived>& m) {
  std::string s = key + ":";
  for (int r = 0; r < m.rows(); ++r)
    for (int c = 0; c < m.cols(); ++c) {
      s += ' ';
      s += Num(m(r, c));
    }
  return s + "\n";
}

std::string CamSuffix(int i) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%02d", i);
  return buf;
}

std::string PKey(int i) {  // "P0".."P3"
  char buf[16];
  std::snprintf(buf, sizeof buf, "P%d", i);
  return buf;
}

std::string RigidText(const RigidCalib& c, bool velo_to_cam) {
  std::string s;
  s += "calib_time: " + c.calib_time + "\n";
  s += Line("R", Eigen::Matrix3d(c.T_to_from.linear()));
  s += Line("T", Eigen::Vector3d(c.T_to_from.translation()));
  if (velo_to_cam) {
    s += Line("delta_f", Eigen::Vector2d::Zero());
    s += Line("delta_c", Eigen::Vector2d::Zero());
  }
  return s;
}

}  // namespace

CamToCamCalib ParseCamToCam(std::string_view text, const std::string& where) {
  const KeyValues kv(text, where);
  CamToCamCalib c;
  c.calib_time = kv.Text("calib_time");
  if (kv.Has("corner_dist")) c.corner_dist = kv.Numbers("corner_dist", 1)[0];
  for (int i = 0; i < 4; ++i) {
    const std::string s = CamSuffix(i);
    CameraCalib& cam = c.cams[i];
    cam.S = kv.Matrix<2, 1>("S_" + s);
    cam.K = kv.Matrix<3, 3>("K_" + s);
    cam.D = kv.Matrix<5, 1>("D_" + s);
    cam.R = kv.Matrix<3, 3>("R_" + s);
    cam.T = kv.Matrix<3, 1>("T_" + s);
    cam.S_rect = kv.Matrix<2, 1>("S_rect_" + s);
    cam.R_rect = kv.Matrix<3, 3>("R_rect_" + s);
    cam.P_rect = kv.Matrix<3, 4>("P_rect_" + s);
    kv.CheckRotation(cam.R_rect, "R_rect_" + s);
    for (const auto& [key, size] : {std::pair{"S_", cam.S}, std::pair{"S_rect_", cam.S_rect}}) {
      constexpr double kMaxSidePx = 100000;
      if (size(0) < 1 || size(1) < 1 || size(0) > kMaxSidePx || size(1) > kMaxSidePx ||
          size(0) != std::floor(size(0)) || size(1) != std::floor(size(1))) {
        throw Error(where + ": key '" + std::string(key) + s +
                    "': image size must be two integers in [1, 100000]");
      }
    }
  }
  return c;
}

RigidCalib ParseRigidCalib(std::string_view text, const std::string& where) {
  const KeyValues kv(text, where);
  RigidCalib c;
  c.calib_time = kv.Text("calib_time");
  c.T_to_from = kv.Rigid("R", "T");
  return c;
}

OdometryCalib ParseOdometryCalib(std::string_view text, const std::string& where) {
  const KeyValues kv(text, where);
  OdometryCalib c;
  for (int i = 0; i < 4; ++i) c.P[i] = kv.Matrix<3, 4>(PKey(i));
  const Eigen::Matrix<double, 3, 4> Tr = kv.Matrix<3, 4>("Tr");
  kv.CheckRotation(Tr.leftCols<3>(), "Tr");
  c.T_cam0_velo.linear() = Tr.leftCols<3>();
  c.T_cam0_velo.translation() = Tr.col(3);
  return c;
}

CamToCamCalib ReadCamToCam(const std::filesystem::path& path) {
  return ParseCamToCam(ReadText(path), path.string());
}
RigidCalib ReadVeloToCam(const std::filesystem::path& path) {
  return ParseRigidCalib(ReadText(path), path.string());
}
RigidCalib ReadImuToVelo(const std::filesystem::path& path) {
  return ParseRigidCalib(ReadText(path), path.string());
}
OdometryCalib ReadOdometryCalib(const std::filesystem::path& path) {
  return ParseOdometryCalib(ReadText(path), path.string());
}

RawCalib ReadRawCalib(const std::filesystem::path& date_dir) {
  RawCalib c;
  c.cam_to_cam = ReadCamToCam(date_dir / "calib_cam_to_cam.txt");
  c.velo_to_cam = ReadVeloToCam(date_dir / "calib_velo_to_cam.txt");
  c.imu_to_velo = ReadImuToVelo(date_dir / "calib_imu_to_velo.txt");
  c.stereo = RectifiedStereo(c.cam_to_cam);
  c.T_cam0_imu = ComputeT_cam0_imu(c.cam_to_cam, c.velo_to_cam.T_to_from, c.imu_to_velo.T_to_from);
  return c;
}

void WriteCamToCam(const std::filesystem::path& path, const CamToCamCalib& c) {
  std::string s = "calib_time: " + c.calib_time + "\n";
  s += "corner_dist: " + Num(c.corner_dist) + "\n";
  for (int i = 0; i < 4; ++i) {
    const std::string x = CamSuffix(i);
    const CameraCalib& cam = c.cams[i];
    s += Line("S_" + x, cam.S.transpose());
    s += Line("K_" + x, cam.K);
    s += Line("D_" + x, cam.D.transpose());
    s += Line("R_" + x, cam.R);
    s += Line("T_" + x, cam.T.transpose());
    s += Line("S_rect_" + x, cam.S_rect.transpose());
    s += Line("R_rect_" + x, cam.R_rect);
    s += Line("P_rect_" + x, cam.P_rect);
  }
  WriteText(path, s);
}

void WriteVeloToCam(const std::filesystem::path& path, const RigidCalib& c) {
  WriteText(path, RigidText(c, true));
}
void WriteImuToVelo(const std::filesystem::path& path, const RigidCalib& c) {
  WriteText(path, RigidText(c, false));
}

void WriteOdometryCalib(const std::filesystem::path& path, const OdometryCalib& c) {
  std::string s;
  for (int i = 0; i < 4; ++i) s += Line(PKey(i), c.P[i]);
  Eigen::Matrix<double, 3, 4> Tr;
  Tr << c.T_cam0_velo.linear(), c.T_cam0_velo.translation();
  s += Line("Tr", Tr);
  WriteText(path, s);
}

StereoCamera RectifiedStereo(const CamToCamCalib& c) {
  const auto& P0 = c.cams[0].P_rect;
  const auto& P1 = c.cams[1].P_rect;
  StereoCamera cam;
  cam.fx = P0(0, 0);
  cam.fy = P0(1, 1);
  cam.cx = P0(0, 2);
  cam.cy = P0(1, 2);
  cam.baseline_m = P1(0, 0) != 0 ? -P1(0, 3) / P1(0, 0) : 0;
  cam.width = static_cast<int>(c.cams[0].S_rect(0));
  cam.height = static_cast<int>(c.cams[0].S_rect(1));
  return cam;
}

StereoCamera OdometryStereo(const OdometryCalib& c, int width, int height) {
  StereoCamera cam;
  cam.fx = c.P[0](0, 0);
  cam.fy = c.P[0](1, 1);
  cam.cx = c.P[0](0, 2);
  cam.cy = c.P[0](1, 2);
  cam.baseline_m = c.P[1](0, 0) != 0 ? -c.P[1](0, 3) / c.P[1](0, 0) : 0;
  cam.width = width;
  cam.height = height;
  return cam;
}

Eigen::Isometry3d ComputeT_cam0_imu(const CamToCamCalib& cam_to_cam,
                                    const Eigen::Isometry3d& T_cam0_velo,
                                    const Eigen::Isometry3d& T_velo_imu) {
  Eigen::Isometry3d T_rect0 = Eigen::Isometry3d::Identity();
  T_rect0.linear() = cam_to_cam.cams[0].R_rect;
  Eigen::Isometry3d T = T_rect0 * T_cam0_velo * T_velo_imu;
  // KITTI prints rotations with 7 digits (|R^T R - I| ~ 1e-7); project onto
  // SO(3) so Isometry3d::inverse() (which transposes) is exact.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(T.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  return T;
}

}  // namespace locaid::kitti
