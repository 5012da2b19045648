// A camera's calibration from a ROS camera_info YAML file: the format
// camera_calibration_parsers reads and writes (and ROS's camera_calibration
// tool saves), so a live camera is rectified exactly like a bag's images
// (Rectifier, StereoFromCameraInfo in ros/camera_model.hpp):
//
//   image_width: 1392
//   image_height: 512
//   camera_name: left                       # optional, not kept
//   camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
//   distortion_model: plumb_bob             # or rational_polynomial, equidistant
//   distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, t1, t2, k3]}
//   rectification_matrix: {rows: 3, cols: 3, data: [9 numbers]}
//   projection_matrix: {rows: 3, cols: 4, data: [12 numbers]}
//
// Matrices are row-major, as in the message. distortion_coefficients takes 5
// numbers for plumb_bob, 8 for rational_polynomial, 4 for equidistant, or
// none (no distortion); distortion_model may be left out only when every
// coefficient is zero (it then stays empty, which the Rectifier reads as "no
// distortion"). Other keys are ignored: real files carry more. The header,
// binning and ROI stay at their defaults (none, full image).
#pragma once

#include "ros/messages.hpp"

#include <string>

namespace locaid::ros {

// Parses the text of a camera_info YAML file; `where` names it in errors (a
// path or "left camera_info"). Throws std::invalid_argument as
// "<where>: <key>: <reason>", e.g. "left.yaml: camera_matrix: expected 9
// numbers (rows 3 x cols 3), got 8"; YAML syntax errors give the line and
// column.
CameraInfo ParseCameraInfoYaml(const std::string& text, const std::string& where);

// Reads the file at `path` and parses it; errors name the path (a file that
// cannot be read: with the system's reason).
CameraInfo ReadCameraInfoYaml(const std::string& path);

}  // namespace locaid::ros
