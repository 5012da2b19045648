#include "ros/camera_info_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace locaid::ros {
namespace {

constexpr long long kMaxImageSide = 20000;

struct Ctx {
  std::string where;
  [[noreturn]] void Fail(const std::string& key, const std::string& why) const {
    throw std::invalid_argument(where + ": " + key + ": " + why);
  }
};

// Scalars are quoted back as written, so the message shows the typo itself.
std::string Quoted(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  return n.IsNull() ? "nothing" : n.IsSequence() ? "a list" : "a mapping";
}

double Number(const Ctx& c, const YAML::Node& n, const std::string& key) {
  double v = 0;
  // yaml-cpp refuses trailing junk ("1.5x") and booleans, but reads ".nan" and ".inf".
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v)) c.Fail(key, "expected a number, got " + Quoted(n));
  if (!std::isfinite(v)) c.Fail(key, "expected a finite number, got " + Quoted(n));
  return v;
}

// An integer in [lo, hi]; "640.0" is not one (camera_calibration_parsers reads ints).
long long Integer(const Ctx& c, const YAML::Node& n, const std::string& key, long long lo, long long hi) {
  const std::string range = "an integer in " + std::to_string(lo) + ".." + std::to_string(hi);
  long long v = 0;
  if (!n.IsScalar() || !YAML::convert<long long>::decode(n, v) || v < lo || v > hi)
    c.Fail(key, "expected " + range + ", got " + Quoted(n));
  return v;
}

YAML::Node Required(const Ctx& c, const YAML::Node& map, const std::string& name, const std::string& key) {
  const YAML::Node n = map[name];
  if (!n.IsDefined()) c.Fail(key, "missing");
  return n;
}

uint32_t ImageSide(const Ctx& c, const YAML::Node& root, const std::string& key) {
  return static_cast<uint32_t>(Integer(c, Required(c, root, key, key), key, 1, kMaxImageSide));
}

std::string Text(const Ctx& c, const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) c.Fail(key, "expected a string");
  return n.Scalar();
}

// {rows, cols, data}: the data, checked against rows x cols. `want_rows` /
// `want_cols` < 0: any shape (distortion_coefficients is 1 x N).
std::vector<double> Matrix(const Ctx& c, const YAML::Node& root, const std::string& key, int want_rows,
                           int want_cols) {
  const YAML::Node m = Required(c, root, key, key);
  if (!m.IsMap()) c.Fail(key, "expected a mapping {rows, cols, data}");
  const long long rows = Integer(c, Required(c, m, "rows", key + ".rows"), key + ".rows", 0, 1000);
  const long long cols = Integer(c, Required(c, m, "cols", key + ".cols"), key + ".cols", 0, 1000);
  if (want_rows >= 0 && (rows != want_rows || cols != want_cols))
    c.Fail(key, "expected rows " + std::to_string(want_rows) + " x cols " + std::to_string(want_cols) + ", got rows " +
                    std::to_string(rows) + " x cols " + std::to_string(cols));
  const YAML::Node data = Required(c, m, "data", key + ".data");
  // `data: []` for no distortion; a bare `data:` (null) means the same.
  const size_t count = data.IsNull() ? 0 : data.size();
  if (!data.IsNull() && !data.IsSequence()) c.Fail(key + ".data", "expected a list of numbers");
  if (count != static_cast<size_t>(rows * cols))
    c.Fail(key, "expected " + std::to_string(rows * cols) + " numbers (rows " + std::to_string(rows) + " x cols " +
                    std::to_string(cols) + "), got " + std::to_string(count));
  std::vector<double> out;
  for (size_t i = 0; i < count; ++i) out.push_back(Number(c, data[i], key + ".data[" + std::to_string(i) + "]"));
  return out;
}

bool AllZero(const std::vector<double>& v) {
  for (const double x : v)
    if (x != 0) return false;
  return true;
}

// An all-zero K or P (what an uncalibrated driver publishes) cannot rectify;
// saying so here names the file, where the Rectifier could not.
template <size_t N>
void CopyCalibrated(const Ctx& c, const std::vector<double>& data, const std::string& key,
                    std::array<double, N>& out) {
  if (AllZero(data)) c.Fail(key, "all zero (an uncalibrated camera): cannot rectify");
  std::copy(data.begin(), data.end(), out.begin());
}

size_t CoefficientsOf(const std::string& model) {
  if (model == "plumb_bob") return 5;
  if (model == "rational_polynomial") return 8;
  if (model == "equidistant") return 4;
  return 0;
}

// distortion_model against distortion_coefficients (already in info.d).
void ReadDistortionModel(const Ctx& c, const YAML::Node& root, CameraInfo& info) {
  const YAML::Node n = root["distortion_model"];
  if (!n.IsDefined() || n.IsNull()) {
    // camera_calibration_parsers would assume plumb_bob; refusing makes a
    // forgotten rational_polynomial or equidistant visible instead.
    if (!AllZero(info.d))
      c.Fail("distortion_model", "missing (required when distortion_coefficients has nonzero values: plumb_bob, "
                                 "rational_polynomial or equidistant)");
    return;
  }
  info.distortion_model = Text(c, n, "distortion_model");
  const size_t want = CoefficientsOf(info.distortion_model);
  if (want == 0)
    c.Fail("distortion_model", "expected plumb_bob, rational_polynomial or equidistant, got '" +
                                   info.distortion_model + "'");
  if (!info.d.empty() && info.d.size() != want)
    c.Fail("distortion_coefficients", std::to_string(info.d.size()) + " numbers, but distortion_model " +
                                          info.distortion_model + " takes " + std::to_string(want) +
                                          " (or none for no distortion)");
}

YAML::Node Load(const std::string& text, const std::string& where) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw std::invalid_argument(where + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) +
                                ", column " + std::to_string(e.mark.column + 1) + ": " + e.msg);
  }
  if (!root.IsDefined() || root.IsNull()) throw std::invalid_argument(where + ": empty camera_info file");
  if (!root.IsMap())
    throw std::invalid_argument(where + ": expected a mapping of camera_info keys (image_width, camera_matrix, ...)");
  return root;
}

}  // namespace

CameraInfo ParseCameraInfoYaml(const std::string& text, const std::string& where) {
  const Ctx c{where};
  const YAML::Node root = Load(text, where);
  CameraInfo info;
  info.width = ImageSide(c, root, "image_width");
  info.height = ImageSide(c, root, "image_height");
  if (root["camera_name"]) Text(c, root["camera_name"], "camera_name");  // checked only: CameraInfo has no name
  CopyCalibrated(c, Matrix(c, root, "camera_matrix", 3, 3), "camera_matrix", info.k);
  info.d = Matrix(c, root, "distortion_coefficients", -1, -1);
  ReadDistortionModel(c, root, info);
  // An all-zero R is allowed: some drivers write it for "no rotation", and
  // RectificationRotation reads it so.
  const std::vector<double> r = Matrix(c, root, "rectification_matrix", 3, 3);
  std::copy(r.begin(), r.end(), info.r.begin());
  CopyCalibrated(c, Matrix(c, root, "projection_matrix", 3, 4), "projection_matrix", info.p);
  return info;
}

CameraInfo ReadCameraInfoYaml(const std::string& path) {
  // stdio rather than ifstream: fopen and fread set errno, so the message can
  // say why (no such file, permission denied, is a directory).
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) throw std::invalid_argument(path + ": cannot open: " + std::strerror(errno));
  std::string text;
  char buffer[4096];
  size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
  const int err = std::ferror(f) ? errno : 0;
  std::fclose(f);
  if (err != 0) throw std::invalid_argument(path + ": cannot read: " + std::strerror(err));
  return ParseCameraInfoYaml(text, path);
}

}  // namespace locaid::ros
