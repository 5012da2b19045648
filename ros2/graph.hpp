// How a DDS participant shows up in ROS 2's graph: ROS 2 nodes announce
// themselves on the DDS topic "ros_discovery_info" (no "rt/" prefix), type
// rmw_dds_common/msg/ParticipantEntitiesInfo: the participant's gid and, per
// node, its namespace, name and the gids of its readers and writers. `ros2
// node list` reads that topic; `ros2 topic list` reads DDS discovery alone.
//
// A gid is the entity's DDS GUID (16 bytes), padded with zeros to the size
// of rmw_dds_common/msg/Gid: 24 bytes up to ROS 2 Humble, 16 from Iron on
// (rmw_dds_common 2.0). Plain CDR carries no sizes for fixed arrays, so the
// two layouts do not read each other: the distribution is an option.
//
// Node: a participant with one ROS 2 node on it, whose publishers and
// subscriptions are announced as they are made (transient local, so a late
// `ros2 node list` still sees them).
#pragma once

#include "ros2/dds.hpp"

#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::ros2 {

enum class RosDistro { kHumble, kIronOrLater };
// "humble" -> kHumble; "iron", "jazzy", "kilted", "rolling" -> kIronOrLater;
// throws std::invalid_argument for others.
RosDistro ParseRosDistro(std::string_view name);
size_t GidBytes(RosDistro distro);  // 24 or 16

struct NodeEntities {
  std::string ns = "/", name;
  std::vector<Guid> readers, writers;
};
struct ParticipantEntities {
  Guid gid{};
  std::vector<NodeEntities> nodes;
};

// rmw_dds_common/msg/ParticipantEntitiesInfo as CDR (header included).
std::string EncodeParticipantEntitiesInfo(const ParticipantEntities& info, RosDistro distro);
// The inverse; throws ros::CdrError for a truncated or lying message. The
// gid bytes beyond 16 are dropped.
ParticipantEntities DecodeParticipantEntitiesInfo(std::string_view cdr, RosDistro distro);

// "name" must be a ROS node name ([A-Za-z_][A-Za-z0-9_]*), "ns" an absolute
// namespace ("/" or "/a/b"); throws std::invalid_argument otherwise.
void CheckNodeName(const std::string& ns, const std::string& name);

struct NodeOptions {
  ParticipantOptions participant;
  std::string ns = "/", name = "locaid_ros2";
  RosDistro distro = RosDistro::kIronOrLater;
};

class Node {
 public:
  explicit Node(const NodeOptions& options);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  // Made and announced on ros_discovery_info. Any thread.
  std::unique_ptr<Writer> CreatePublisher(const std::string& topic, const std::string& type, const Qos& qos);
  std::unique_ptr<Reader> CreateSubscription(const std::string& topic, const std::string& type, const Qos& qos);

  Participant& participant() { return *participant_; }
  const NodeOptions& options() const { return options_; }

 private:
  void Add(std::vector<Guid> NodeEntities::*list, const Guid& gid);  // a reader or writer, announced
  void Announce();  // mu_ held

  NodeOptions options_;
  std::unique_ptr<Participant> participant_;
  std::unique_ptr<Writer> graph_;
  std::mutex mu_;
  ParticipantEntities entities_;
};

}  // namespace locaid::ros2
