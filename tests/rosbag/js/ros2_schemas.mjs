// ROS 2 message definitions (.msg text, ROS 2 Humble field sets) and the
// "ros2msg" schema text rosbag2 stores for a type: the type's own .msg text,
// then each dependency (recursively, each once) after a line of 80 '=' and a
// line "MSG: <type>" (see schemaText). Comments are shortened from the
// official files, but comments, inline comments, constants and defaults are
// kept so readers meet them.

const MSG = {
  "builtin_interfaces/msg/Time": `# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 10e9).
uint32 nanosec
`,
  "std_msgs/msg/Header": `# Standard metadata for higher-level stamped data types.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
`,
  "geometry_msgs/msg/Quaternion": `# This represents an orientation in free space in quaternion form.

float64 x 0
float64 y 0
float64 z 0
float64 w 1
`,
  "geometry_msgs/msg/Vector3": `# This represents a vector in free space.

float64 x
float64 y
float64 z
`,
  "geometry_msgs/msg/Transform": `# This represents the transform between two coordinate frames in free space.

Vector3 translation
Quaternion rotation
`,
  "geometry_msgs/msg/TransformStamped": `# This expresses a transform from coordinate frame header.frame_id
# to the coordinate frame child_frame_id at the time of header.stamp

std_msgs/Header header

# The frame id of the child frame to which this transform points.
string child_frame_id

# Translation and rotation in 3-dimensions of child_frame_id from header.frame_id.
Transform transform
`,
  "tf2_msgs/msg/TFMessage": `geometry_msgs/TransformStamped[] transforms
`,
  "geometry_msgs/msg/Twist": `# This expresses velocity in free space broken into its linear and angular parts.

Vector3  linear
Vector3  angular
`,
  "geometry_msgs/msg/TwistStamped": `# A twist with reference coordinate frame and timestamp

std_msgs/Header header
Twist twist
`,
  "sensor_msgs/msg/Image": `# This message contains an uncompressed image
# (0, 0) is at top-left corner of image

std_msgs/Header header # Header timestamp should be acquisition time of image

uint32 height                # image height, that is, number of rows
uint32 width                 # image width, that is, number of columns

string encoding       # Encoding of pixels -- channel meaning, ordering, size
                      # taken from the list of strings in include/sensor_msgs/image_encodings.hpp

uint8 is_bigendian    # is this data bigendian?
uint32 step           # Full row length in bytes
uint8[] data          # actual matrix data, size is (step * rows)
`,
  "sensor_msgs/msg/CompressedImage": `# This message contains a compressed image.

std_msgs/Header header # Header timestamp should be acquisition time of image

string format                # Specifies the format of the data
                             #   Acceptable values differ by the image transport used:
                             #   - compressed_image_transport:
                             #       ORIG_PIXFMT; CODEC compressed [COMPRESSED_PIXFMT]

uint8[] data                 # Compressed image buffer
`,
  "sensor_msgs/msg/RegionOfInterest": `# This message is used to specify a region of interest within an image.

uint32 x_offset  # Leftmost pixel of the ROI
                 # (0 if the ROI includes the left edge of the image)
uint32 y_offset  # Topmost pixel of the ROI
                 # (0 if the ROI includes the top edge of the image)
uint32 height    # Height of ROI
uint32 width     # Width of ROI

# True if a distinct rectified ROI should be calculated from the "raw"
# ROI in this message.
bool do_rectify
`,
  "sensor_msgs/msg/CameraInfo": `# This message defines meta information for a camera.

std_msgs/Header header

uint32 height
uint32 width

# The distortion model used. Supported models are listed in
# sensor_msgs/distortion_models.hpp.
string distortion_model

# For "plumb_bob", the 5 parameters are: (k1, k2, t1, t2, k3).
float64[] d

# Intrinsic camera matrix for the raw (distorted) images.
float64[9]  k # 3x3 row-major matrix

# Rectification matrix (stereo cameras only)
float64[9]  r # 3x3 row-major matrix

# Projection/camera matrix
float64[12] p # 3x4 row-major matrix

uint32 binning_x
uint32 binning_y

RegionOfInterest roi
`,
  "sensor_msgs/msg/Imu": `# This is a message to hold data from an IMU (Inertial Measurement Unit)
#
# If the covariance of the measurement is known, it should be filled in (if all you know is the
# variance of each measurement, e.g. from the datasheet, just put those along the diagonal)
# A covariance matrix of all zeros will be interpreted as "covariance unknown", and to use the
# data a covariance will have to be assumed or gotten from some other source
#
# If you have no estimate for one of the data elements (e.g. your IMU doesn't produce an
# orientation estimate), please set element 0 of the associated covariance matrix to -1

std_msgs/Header header

geometry_msgs/Quaternion orientation
float64[9] orientation_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance # Row major x, y z
`,
  "sensor_msgs/msg/NavSatStatus": `# Navigation Satellite fix status for any Global Navigation Satellite System.

# Whether to output an augmented fix is determined by both the fix
# type and the last time differential corrections were received.  A
# fix is valid when status >= STATUS_FIX.

int8 STATUS_NO_FIX =  -1        # unable to fix position
int8 STATUS_FIX =      0        # unaugmented fix
int8 STATUS_SBAS_FIX = 1        # with satellite-based augmentation
int8 STATUS_GBAS_FIX = 2        # with ground-based augmentation

int8 status

# Bits defining which Global Navigation Satellite System signals were
# used by the receiver.

uint16 SERVICE_GPS =     1
uint16 SERVICE_GLONASS = 2
uint16 SERVICE_COMPASS = 4      # includes BeiDou.
uint16 SERVICE_GALILEO = 8

uint16 service
`,
  "sensor_msgs/msg/NavSatFix": `# Navigation Satellite fix for any Global Navigation Satellite System
#
# Specified using the WGS 84 reference ellipsoid

# header.stamp specifies the ROS time for this measurement (the
#        corresponding satellite time may be reported using the
#        sensor_msgs/TimeReference message).
#
# header.frame_id is the frame of reference reported by the satellite
#        receiver, usually the location of the antenna.  This is a
#        Euclidean frame relative to the vehicle, not a reference
#        ellipsoid.
std_msgs/Header header

# Satellite fix status information.
NavSatStatus status

# Latitude [degrees]. Positive is north of equator; negative is south.
float64 latitude

# Longitude [degrees]. Positive is east of prime meridian; negative is west.
float64 longitude

# Altitude [m]. Positive is above the WGS 84 ellipsoid
# (quiet NaN if no altitude is available).
float64 altitude

# Position covariance [m^2] defined relative to a tangential plane
# through the reported position. The components are East, North, and
# Up (ENU), in row-major order.
float64[9] position_covariance

# If the covariance of the fix is known, fill it in completely. If the
# GPS receiver provides the variance of each measurement, put them
# along the diagonal. If only Dilution of Precision is available,
# estimate an approximate covariance from that.

uint8 COVARIANCE_TYPE_UNKNOWN = 0
uint8 COVARIANCE_TYPE_APPROXIMATED = 1
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2
uint8 COVARIANCE_TYPE_KNOWN = 3

uint8 position_covariance_type
`,
};

// What rosbag2_cpp's LocalMessageDefinitionSource does (get_full_text): a
// dependency is each non-primitive field type as written in the .msg text
// ("std_msgs/Header"; a bare "Vector3" gets the package: "geometry_msgs/Vector3"),
// sorted (a std::set) and appended depth-first, each once, after "\n", 80 '='
// and "MSG: <that name>". So rosbag2 writes "MSG: std_msgs/Header", while its
// docs/message_definition_encoding.md shows "MSG: pkg/msg/Type"; msgNames
// "long" writes the latter (readers should take both).
const PRIMITIVES = new Set([
  "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
  "int32", "uint32", "int64", "uint64", "string",
]);
const FIELD_TYPE = /(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+/g;  // rosbag2's MSG_FIELD_TYPE_REGEX

function dependencies(text, pkg) {
  const deps = new Set();
  for (const m of text.matchAll(FIELD_TYPE)) {
    if (PRIMITIVES.has(m[1])) continue;
    deps.add(m[1].includes("/") ? m[1] : `${pkg}/${m[1]}`);
  }
  return [...deps].sort();
}

const withMsg = (name) => {  // "pkg/Type" or "pkg/msg/Type" -> "pkg/msg/Type"
  const p = name.split("/");
  return p.length === 2 ? `${p[0]}/msg/${p[1]}` : name;
};

// The complete "ros2msg" schema text of `type` ("sensor_msgs/msg/Imu").
export function schemaText(type, { msgNames = "short" } = {}) {
  if (!MSG[type]) throw new Error(`no message definition for ${type}`);
  const seen = new Set();
  const append = (t) => {
    const full = withMsg(t);
    if (!MSG[full]) throw new Error(`no message definition for ${full}`);
    let text = MSG[full];
    for (const dep of dependencies(text, full.split("/")[0])) {
      if (seen.has(withMsg(dep))) continue;
      seen.add(withMsg(dep));
      text += `\n${"=".repeat(80)}\nMSG: ${msgNames === "long" ? withMsg(dep) : dep}\n${append(dep)}`;
    }
    return text;
  };
  return append(type);
}

export const knownTypes = () => Object.keys(MSG);

// offered_qos_profiles as rosbag2 (Humble) writes it in MCAP channel metadata
// and metadata.yaml: a YAML list with one profile of the publisher. Numeric
// rmw enums: history 3 = unknown, reliability 1 = reliable, durability
// 1 = transient_local, 2 = volatile, liveliness 1 = automatic.
export function qosYaml({ transientLocal = false } = {}) {
  const inf = "    sec: 9223372036\n    nsec: 854775807\n";
  return (
    "- history: 3\n  depth: 0\n  reliability: 1\n" +
    `  durability: ${transientLocal ? 1 : 2}\n` +
    `  deadline:\n${inf}  lifespan:\n${inf}  liveliness: 1\n` +
    `  liveliness_lease_duration:\n${inf}  avoid_ros_namespace_conventions: false`
  );
}
