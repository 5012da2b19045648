// camera_info YAML files (camera_calibration_parsers' format): KITTI's
// 2011_09_26 calibration written as ROS's camera_calibration tool writes it
// parses to exactly its numbers and rectifies; every malformed file names the
// file, the key and the reason.
#include "error_of.hpp"
#include "ros/camera_info_yaml.hpp"
#include "ros/camera_model.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace locaid::ros {
namespace {

using test_support::ScopedTempDir;

// KITTI raw 2011_09_26, cam0 (K_00, D_00, R_rect_00, P_rect_00 of
// calib_cam_to_cam.txt, raw size S_00), laid out as camera_calibration saves.
const char* const kCam0 = R"(image_width: 1392
image_height: 512
camera_name: kitti_cam0
camera_matrix:
  rows: 3
  cols: 3
  data: [9.842439e+02, 0.000000e+00, 6.900000e+02, 0.000000e+00, 9.808141e+02, 2.331966e+02, 0.000000e+00, 0.000000e+00, 1.000000e+00]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-3.728755e-01, 2.037299e-01, 2.219027e-03, 1.383707e-03, -7.233722e-02]
rectification_matrix:
  rows: 3
  cols: 3
  data: [9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01, -4.278459e-03, 7.402527e-03, 4.351614e-03, 9.999631e-01]
projection_matrix:
  rows: 3
  cols: 4
  data: [7.215377e+02, 0.000000e+00, 6.095593e+02, 0.000000e+00, 0.000000e+00, 7.215377e+02, 1.728540e+02, 0.000000e+00, 0.000000e+00, 0.000000e+00, 1.000000e+00, 0.000000e+00]
)";

// cam1 of the same calibration (K_01, D_01, R_rect_01, P_rect_01), in flow
// style with the extra keys some writers add: both must be read alike.
const char* const kCam1 = R"(image_width: 1392
image_height: 512
camera_name: kitti_cam1
header: {frame_id: cam1}
binning_x: 0
camera_matrix: {rows: 3, cols: 3, data: [9.895267e+02, 0, 7.020000e+02, 0, 9.878386e+02, 2.455590e+02, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-3.644661e-01, 1.790019e-01, 1.148107e-03, -6.298563e-04, -5.314062e-02]}
rectification_matrix: {rows: 3, cols: 3, data: [9.996878e-01, -8.976826e-03, 2.331651e-02, 8.876121e-03, 9.999508e-01, 4.418952e-03, -2.335503e-02, -4.210612e-03, 9.997184e-01]}
projection_matrix: {rows: 3, cols: 4, data: [7.215377e+02, 0, 6.095593e+02, -3.875744e+02, 0, 7.215377e+02, 1.728540e+02, 0, 0, 0, 1, 0]}
)";

// `text` with its first occurrence of `from` replaced by `to` (which must be there).
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("test text has no '" + from + "'");
  return text.replace(at, from.size(), to);
}

// `text` without top-level `key` and its indented lines.
std::string Without(const std::string& text, const std::string& key) {
  std::istringstream in(text);
  std::string out, line;
  bool dropping = false;
  while (std::getline(in, line)) {
    if (line.rfind(key + ":", 0) == 0) dropping = true;
    else if (!line.empty() && line[0] != ' ') dropping = false;
    if (!dropping) out += line + "\n";
  }
  return out;
}

std::string ErrorOf(const std::string& text) {
  return test_support::ErrorOf<std::invalid_argument>([&] { ParseCameraInfoYaml(text, "left.yaml"); });
}

// Cam0 with `data` as the distortion coefficients (`model` empty: no distortion_model key).
std::string WithDistortion(const std::string& model, const std::string& data, int count) {
  std::string text = Replace(kCam0, "  cols: 5\n  data: [-3.728755e-01, 2.037299e-01, 2.219027e-03, "
                                    "1.383707e-03, -7.233722e-02]",
                             "  cols: " + std::to_string(count) + "\n  data: [" + data + "]");
  return model.empty() ? Without(text, "distortion_model") : Replace(text, "model: plumb_bob", "model: " + model);
}

TEST(CameraInfoYaml, KittiCam0FileParsesToItsCalibrationAndRectifies) {
  const ScopedTempDir dir("camera_info_yaml");
  const std::string path = (dir / "left.yaml").string();
  std::ofstream(path) << kCam0;

  const CameraInfo info = ReadCameraInfoYaml(path);
  EXPECT_EQ(info.width, 1392u);
  EXPECT_EQ(info.height, 512u);
  EXPECT_EQ(info.distortion_model, "plumb_bob");
  // Exactly the numbers: the decimal text and the C++ literal round alike.
  EXPECT_EQ(info.k, (std::array<double, 9>{9.842439e+02, 0, 6.900000e+02, 0, 9.808141e+02, 2.331966e+02, 0, 0, 1}));
  EXPECT_EQ(info.d, (std::vector<double>{-3.728755e-01, 2.037299e-01, 2.219027e-03, 1.383707e-03, -7.233722e-02}));
  EXPECT_EQ(info.r, (std::array<double, 9>{9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01,
                                           -4.278459e-03, 7.402527e-03, 4.351614e-03, 9.999631e-01}));
  EXPECT_EQ(info.p, (std::array<double, 12>{7.215377e+02, 0, 6.095593e+02, 0, 0, 7.215377e+02, 1.728540e+02, 0, 0,
                                            0, 1, 0}));
  EXPECT_EQ(info.binning_x, 0u);  // not in the file: none
  EXPECT_EQ(info.roi_width, 0u);  // not in the file: the full image

  const Rectifier rectifier(info);
  EXPECT_FALSE(rectifier.passthrough());
  const cv::Mat rectified = rectifier.Rectify(cv::Mat(512, 1392, CV_8UC1, cv::Scalar(128)));
  EXPECT_EQ(rectified.size(), cv::Size(1392, 512));
}

TEST(CameraInfoYaml, KittiStereoPairInFlowStyleGivesItsBaseline) {
  const CameraInfo left = ParseCameraInfoYaml(kCam0, "left camera_info");
  const CameraInfo right = ParseCameraInfoYaml(kCam1, "right camera_info");
  EXPECT_EQ(right.k[0], 9.895267e+02);
  EXPECT_EQ(right.p[3], -3.875744e+02);
  EXPECT_TRUE(right.header.frame_id.empty());  // extra keys are ignored, not read
  const StereoCamera cam = StereoFromCameraInfo(left, right);
  EXPECT_EQ(cam.fx, 7.215377e+02);
  EXPECT_EQ(cam.cy, 1.728540e+02);
  EXPECT_DOUBLE_EQ(cam.baseline_m, 3.875744e+02 / 7.215377e+02);
  EXPECT_NO_THROW(Rectifier{right});
}

TEST(CameraInfoYaml, NoDistortionNeedsNoModel) {
  // An already rectified camera: no coefficients, identity R.
  std::string text = WithDistortion("", "", 0);
  text = Replace(text, "9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01, -4.278459e-03, "
                       "7.402527e-03, 4.351614e-03, 9.999631e-01",
                 "1, 0, 0, 0, 1, 0, 0, 0, 1");
  const CameraInfo info = ParseCameraInfoYaml(text, "left.yaml");
  EXPECT_TRUE(info.d.empty());
  EXPECT_TRUE(info.distortion_model.empty());
  EXPECT_TRUE(Rectifier(info).passthrough());
  // Five zeros without a model, and no coefficients with a model: also no distortion.
  EXPECT_EQ(ParseCameraInfoYaml(WithDistortion("", "0, 0, 0, 0, 0", 5), "x").d, std::vector<double>(5, 0.0));
  EXPECT_TRUE(ParseCameraInfoYaml(WithDistortion("equidistant", "", 0), "x").d.empty());
}

TEST(CameraInfoYaml, RationalPolynomialAndEquidistantTakeTheirCounts) {
  const CameraInfo rational =
      ParseCameraInfoYaml(WithDistortion("rational_polynomial", "-0.37, 0.2, 0.002, 0.001, -0.07, 0, 0, 0", 8), "x");
  EXPECT_EQ(rational.d.size(), 8u);
  EXPECT_NO_THROW(Rectifier{rational});
  const CameraInfo fisheye = ParseCameraInfoYaml(WithDistortion("equidistant", "0.01, 0, 0, 0", 4), "x");
  EXPECT_EQ(fisheye.distortion_model, "equidistant");
  EXPECT_NO_THROW(Rectifier{fisheye});
}

TEST(CameraInfoYaml, MissingKeysAreNamed) {
  for (const std::string key : {"image_width", "image_height", "camera_matrix", "distortion_coefficients",
                                "rectification_matrix", "projection_matrix"}) {
    EXPECT_EQ(ErrorOf(Without(kCam0, key)), "left.yaml: " + key + ": missing") << key;
  }
  EXPECT_NO_THROW(ParseCameraInfoYaml(Without(kCam0, "camera_name"), "x"));  // optional
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  rows: 3\n  cols: 4\n", "  cols: 4\n")), "left.yaml: projection_matrix.rows: missing");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  cols: 4\n", "")), "left.yaml: projection_matrix.cols: missing");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  data: [7.215377e+02", "  values: [7.215377e+02")),
            "left.yaml: projection_matrix.data: missing");
}

TEST(CameraInfoYaml, WrongNumberOfValuesIsNamed) {
  EXPECT_EQ(ErrorOf(Replace(kCam0, "0.000000e+00, 0.000000e+00, 1.000000e+00]", "0.000000e+00, 1.000000e+00]")),
            "left.yaml: camera_matrix: expected 9 numbers (rows 3 x cols 3), got 8");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  rows: 3\n  cols: 3\n", "  rows: 3\n  cols: 4\n")),
            "left.yaml: camera_matrix: expected rows 3 x cols 3, got rows 3 x cols 4");
  EXPECT_EQ(ErrorOf(Replace(kCam0, ", -7.233722e-02]", "]")),
            "left.yaml: distortion_coefficients: expected 5 numbers (rows 1 x cols 5), got 4");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  data: [7.215377e+02", "  data: {a: 7.215377e+02}\n  x: [7.215377e+02")),
            "left.yaml: projection_matrix.data: expected a list of numbers");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "camera_matrix:\n  rows: 3", "camera_matrix: 3\nx:\n  rows: 3")),
            "left.yaml: camera_matrix: expected a mapping {rows, cols, data}");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "  rows: 1\n", "  rows: one\n")),
            "left.yaml: distortion_coefficients.rows: expected an integer in 0..1000, got 'one'");
}

TEST(CameraInfoYaml, NonNumericAndNonFiniteValuesAreNamed) {
  const std::string k3 = "6.900000e+02";
  EXPECT_EQ(ErrorOf(Replace(kCam0, k3, "6.9e+02x")),
            "left.yaml: camera_matrix.data[2]: expected a number, got '6.9e+02x'");
  EXPECT_EQ(ErrorOf(Replace(kCam0, k3, "true")), "left.yaml: camera_matrix.data[2]: expected a number, got 'true'");
  EXPECT_EQ(ErrorOf(Replace(kCam0, k3, "[1, 2]")), "left.yaml: camera_matrix.data[2]: expected a number, got a list");
  EXPECT_EQ(ErrorOf(Replace(kCam0, k3, "~")), "left.yaml: camera_matrix.data[2]: expected a number, got nothing");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "1.383707e-03", ".nan")),
            "left.yaml: distortion_coefficients.data[3]: expected a finite number, got '.nan'");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "1.728540e+02", "-.inf")),
            "left.yaml: projection_matrix.data[6]: expected a finite number, got '-.inf'");
}

TEST(CameraInfoYaml, ImageSizeIsAPositiveIntegerUpTo20000) {
  for (const std::string bad : {"0", "-640", "1392.5", "20001", "wide", "99999999999999999999999"}) {
    EXPECT_EQ(ErrorOf(Replace(kCam0, "image_width: 1392", "image_width: " + bad)),
              "left.yaml: image_width: expected an integer in 1..20000, got '" + bad + "'")
        << bad;
  }
  EXPECT_EQ(ErrorOf(Replace(kCam0, "image_height: 512", "image_height: [512]")),
            "left.yaml: image_height: expected an integer in 1..20000, got a list");
  EXPECT_EQ(ParseCameraInfoYaml(Replace(kCam0, "image_width: 1392", "image_width: 20000"), "x").width, 20000u);
}

TEST(CameraInfoYaml, DistortionModelMustFitTheCoefficients) {
  const std::string five = "-0.37, 0.2, 0.002, 0.001, -0.07";
  EXPECT_EQ(ErrorOf(WithDistortion("plumb_bob", five + ", 0, 0, 0", 8)),
            "left.yaml: distortion_coefficients: 8 numbers, but distortion_model plumb_bob takes 5 "
            "(or none for no distortion)");
  EXPECT_EQ(ErrorOf(WithDistortion("equidistant", five, 5)),
            "left.yaml: distortion_coefficients: 5 numbers, but distortion_model equidistant takes 4 "
            "(or none for no distortion)");
  EXPECT_EQ(ErrorOf(WithDistortion("rational_polynomial", five, 5)),
            "left.yaml: distortion_coefficients: 5 numbers, but distortion_model rational_polynomial takes 8 "
            "(or none for no distortion)");
  EXPECT_EQ(ErrorOf(WithDistortion("fisheye", "0.01, 0, 0, 0", 4)),
            "left.yaml: distortion_model: expected plumb_bob, rational_polynomial or equidistant, got 'fisheye'");
  EXPECT_EQ(ErrorOf(WithDistortion("", five, 5)),
            "left.yaml: distortion_model: missing (required when distortion_coefficients has nonzero values: "
            "plumb_bob, rational_polynomial or equidistant)");
  EXPECT_EQ(ErrorOf(Replace(kCam0, "model: plumb_bob", "model: [plumb_bob]")),
            "left.yaml: distortion_model: expected a string");
}

TEST(CameraInfoYaml, AllZeroCameraOrProjectionMatrixIsAnError) {
  const std::string zeros9 = "0, 0, 0, 0, 0, 0, 0, 0, 0";
  EXPECT_EQ(ErrorOf(Replace(kCam0,
                            "9.842439e+02, 0.000000e+00, 6.900000e+02, 0.000000e+00, 9.808141e+02, 2.331966e+02, "
                            "0.000000e+00, 0.000000e+00, 1.000000e+00",
                            zeros9)),
            "left.yaml: camera_matrix: all zero (an uncalibrated camera): cannot rectify");
  std::string text = kCam0;
  const size_t p = text.find("projection_matrix:");
  text = text.substr(0, text.find("data: [", p)) + "data: [" + zeros9 + ", 0, 0, 0]\n";
  EXPECT_EQ(ErrorOf(text), "left.yaml: projection_matrix: all zero (an uncalibrated camera): cannot rectify");
  // An all-zero R is how some drivers say "no rotation": accepted.
  EXPECT_NO_THROW(ParseCameraInfoYaml(
      Replace(kCam0, "9.999239e-01, 9.837760e-03, -7.445048e-03, -9.869795e-03, 9.999421e-01, -4.278459e-03, "
                     "7.402527e-03, 4.351614e-03, 9.999631e-01",
              zeros9),
      "x"));
}

TEST(CameraInfoYaml, YamlSyntaxErrorGivesLineAndColumn) {
  const std::string error = ErrorOf(Replace(kCam0, "  cols: 4\n", "  cols: [4\n"));
  EXPECT_EQ(error.rfind("left.yaml: YAML syntax error at line ", 0), 0u) << error;
  EXPECT_NE(error.find(", column "), std::string::npos) << error;
  const std::string indent = ErrorOf("image_width: 1\n  image_height: 2\n");
  EXPECT_NE(indent.find("left.yaml: YAML syntax error at line 2, column "), std::string::npos) << indent;
  EXPECT_EQ(ErrorOf(""), "left.yaml: empty camera_info file");
  EXPECT_EQ(ErrorOf("- 1\n- 2\n"),
            "left.yaml: expected a mapping of camera_info keys (image_width, camera_matrix, ...)");
}

TEST(CameraInfoYaml, UnreadableFileGivesTheSystemReason) {
  const ScopedTempDir dir("camera_info_yaml");
  const std::string missing = (dir / "none.yaml").string();
  EXPECT_EQ(test_support::ErrorOf<std::invalid_argument>([&] { ReadCameraInfoYaml(missing); }),
            missing + ": cannot open: No such file or directory");
  const std::string folder = dir.path().string();
  EXPECT_EQ(test_support::ErrorOf<std::invalid_argument>([&] { ReadCameraInfoYaml(folder); }),
            folder + ": cannot read: Is a directory");
  // A file's parse errors name its path.
  const std::string bad = (dir / "bad.yaml").string();
  std::ofstream(bad) << Without(kCam0, "image_height");
  EXPECT_EQ(test_support::ErrorOf<std::invalid_argument>([&] { ReadCameraInfoYaml(bad); }),
            bad + ": image_height: missing");
}

}  // namespace
}  // namespace locaid::ros
