// The ROS 2 message definitions locaid's ROS 2 bags use, as rosbag2 stores
// them in an MCAP Schema record (encoding "ros2msg"): the type's .msg text,
// then each type it depends on, depth first, every one once, after a
// delimiter line of 80 '=' and a line "MSG: pkg/Type" (rosbag2's
// LocalMessageDefinitionSource::get_full_text; the format is documented in
// rosbag2's docs/message_definition_encoding.md).
//
// The .msg texts are the official ROS 2 Jazzy definitions, comments
// included, from common_interfaces (nav_msgs, sensor_msgs, geometry_msgs,
// std_msgs, diagnostic_msgs), geometry2 (tf2_msgs) and rcl_interfaces
// (builtin_interfaces).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace locaid::output {

// Type names as "pkg/msg/Type" or "pkg/Type"; every function throws
// std::invalid_argument for a type it does not hold.

// The .msg file of one type, verbatim.
const std::string& Ros2MsgText(std::string_view type);
// The complete definition of `type` as rosbag2 writes it.
std::string Ros2FullDefinition(std::string_view type);
// The message types that have a .msg text here ("pkg/Type").
std::vector<std::string> Ros2KnownTypes();

}  // namespace locaid::output
