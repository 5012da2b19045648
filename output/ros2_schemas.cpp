#include "output/ros2_schemas.hpp"

#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace locaid::output {
namespace {

// "pkg/Type" -> the .msg file's text (each ends with a newline).
const std::map<std::string, std::string, std::less<>>& MsgFiles() {
  static const std::map<std::string, std::string, std::less<>> files = {
    {"builtin_interfaces/Time", R"msg(# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9).
uint32 nanosec
)msg"},
    {"diagnostic_msgs/DiagnosticArray", R"msg(# This message is used to send diagnostic information about the state of the robot.
std_msgs/Header header # for timestamp
DiagnosticStatus[] status # an array of components being reported on
)msg"},
    {"diagnostic_msgs/DiagnosticStatus", R"msg(# This message holds the status of an individual component of the robot.

# Possible levels of operations.
byte OK=0
byte WARN=1
byte ERROR=2
byte STALE=3

# Level of operation enumerated above.
byte level
# A description of the test/component reporting.
string name
# A description of the status.
string message
# A hardware unique string.
string hardware_id
# An array of values associated with the status.
KeyValue[] values

)msg"},
    {"diagnostic_msgs/KeyValue", R"msg(# What to label this value when viewing.
string key
# A value to track over time.
string value
)msg"},
    {"geometry_msgs/Point", R"msg(# This contains the position of a point in free space
float64 x
float64 y
float64 z
)msg"},
    {"geometry_msgs/Pose", R"msg(# A representation of pose in free space, composed of position and orientation.

Point position
Quaternion orientation
)msg"},
    {"geometry_msgs/PoseWithCovariance", R"msg(# This represents a pose in free space with uncertainty.

Pose pose

# Row-major representation of the 6x6 covariance matrix
# The orientation parameters use a fixed-axis representation.
# In order, the parameters are:
# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)
float64[36] covariance
)msg"},
    {"geometry_msgs/Quaternion", R"msg(# This represents an orientation in free space in quaternion form.

float64 x 0
float64 y 0
float64 z 0
float64 w 1
)msg"},
    {"geometry_msgs/Transform", R"msg(# This represents the transform between two coordinate frames in free space.

Vector3 translation
Quaternion rotation
)msg"},
    {"geometry_msgs/TransformStamped", R"msg(# This expresses a transform from coordinate frame header.frame_id
# to the coordinate frame child_frame_id at the time of header.stamp
#
# This message is mostly used by the
# <a href="https://docs.ros.org/en/rolling/p/tf2/">tf2</a> package.
# See its documentation for more information.
#
# The child_frame_id is necessary in addition to the frame_id
# in the Header to communicate the full reference for the transform
# in a self contained message.

# The frame id in the header is used as the reference frame of this transform.
std_msgs/Header header

# The frame id of the child frame to which this transform points.
string child_frame_id

# Translation and rotation in 3-dimensions of child_frame_id from header.frame_id.
Transform transform
)msg"},
    {"geometry_msgs/Twist", R"msg(# This expresses velocity in free space broken into its linear and angular parts.

Vector3  linear
Vector3  angular
)msg"},
    {"geometry_msgs/TwistWithCovariance", R"msg(# This expresses velocity in free space with uncertainty.

Twist twist

# Row-major representation of the 6x6 covariance matrix
# The orientation parameters use a fixed-axis representation.
# In order, the parameters are:
# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)
float64[36] covariance
)msg"},
    {"geometry_msgs/Vector3", R"msg(# This represents a vector in free space.

# This is semantically different than a point.
# A vector is always anchored at the origin.
# When a transform is applied to a vector, only the rotational component is applied.

float64 x
float64 y
float64 z
)msg"},
    {"nav_msgs/Odometry", R"msg(# This represents an estimate of a position and velocity in free space.
# The pose in this message should be specified in the coordinate frame given by header.frame_id
# The twist in this message should be specified in the coordinate frame given by the child_frame_id

# Includes the frame id of the pose parent.
std_msgs/Header header

# Frame id the pose points to. The twist is in this coordinate frame.
string child_frame_id

# Estimated pose that is typically relative to a fixed world frame.
geometry_msgs/PoseWithCovariance pose

# Estimated linear and angular velocity relative to child_frame_id.
geometry_msgs/TwistWithCovariance twist
)msg"},
    {"sensor_msgs/NavSatFix", R"msg(# Navigation Satellite fix for any Global Navigation Satellite System
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
#
# Beware: this coordinate system exhibits singularities at the poles.
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
)msg"},
    {"sensor_msgs/NavSatStatus", R"msg(# Navigation Satellite fix status for any Global Navigation Satellite System.
#
# Whether to output an augmented fix is determined by both the fix
# type and the last time differential corrections were received.  A
# fix is valid when status >= STATUS_FIX.

int8 STATUS_UNKNOWN = -2        # status is not yet set
int8 STATUS_NO_FIX =  -1        # unable to fix position
int8 STATUS_FIX =      0        # unaugmented fix
int8 STATUS_SBAS_FIX = 1        # with satellite-based augmentation
int8 STATUS_GBAS_FIX = 2        # with ground-based augmentation

int8 status -2 # STATUS_UNKNOWN

# Bits defining which Global Navigation Satellite System signals were
# used by the receiver.

uint16 SERVICE_UNKNOWN = 0  # Remember service is a bitfield, so checking (service & SERVICE_UNKNOWN) will not work. Use == instead.
uint16 SERVICE_GPS =     1
uint16 SERVICE_GLONASS = 2
uint16 SERVICE_COMPASS = 4      # includes BeiDou.
uint16 SERVICE_GALILEO = 8

uint16 service
)msg"},
    {"std_msgs/Header", R"msg(# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
)msg"},
    {"tf2_msgs/TFMessage", R"msg(geometry_msgs/TransformStamped[] transforms
)msg"},
  };
  return files;
}

// "pkg/msg/Type" -> "pkg/Type"; "pkg/Type" unchanged.
std::string ShortName(std::string_view type) {
  const size_t first = type.find('/');
  const size_t last = type.rfind('/');
  if (first == std::string_view::npos) throw std::invalid_argument("ROS 2 type '" + std::string(type) + "': expected pkg/Type");
  if (first == last) return std::string(type);
  return std::string(type.substr(0, first)) + std::string(type.substr(last));
}

bool IsPrimitive(const std::string& type) {
  static const std::set<std::string> primitives = {"bool",   "byte",   "char",  "float32", "float64",
                                                   "int8",   "uint8",  "int16", "uint16",  "int32",
                                                   "uint32", "int64",  "uint64", "string"};
  return primitives.count(type) > 0;
}

// The field types a .msg text names, as rosbag2 finds them: the first word
// of each line (array suffix dropped), primitives left out, a bare name
// taken from the message's own package; sorted, each once.
std::set<std::string> Dependencies(const std::string& text, const std::string& package) {
  std::set<std::string> deps;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string type;
    if (!(words >> type) || type[0] == '#') continue;
    type = type.substr(0, type.find('['));
    if (type.empty() || IsPrimitive(type)) continue;
    deps.insert(type.find('/') == std::string::npos ? package + "/" + type : type);
  }
  return deps;
}

}  // namespace

const std::string& Ros2MsgText(std::string_view type) {
  const auto it = MsgFiles().find(ShortName(type));
  if (it == MsgFiles().end()) throw std::invalid_argument("no .msg definition for ROS 2 type '" + std::string(type) + "'");
  return it->second;
}

std::string Ros2FullDefinition(std::string_view type) {
  const std::string delimiter(80, '=');
  std::set<std::string> seen;
  std::function<std::string(const std::string&)> append = [&](const std::string& name) {
    const std::string& text = Ros2MsgText(name);
    std::string result = text;
    for (const std::string& dep : Dependencies(text, name.substr(0, name.find('/')))) {
      if (!seen.insert(dep).second) continue;
      result += "\n" + delimiter + "\nMSG: " + dep + "\n" + append(dep);
    }
    return result;
  };
  return append(ShortName(type));
}

std::vector<std::string> Ros2KnownTypes() {
  std::vector<std::string> types;
  for (const auto& [name, text] : MsgFiles()) types.push_back(name);
  return types;
}

}  // namespace locaid::output
