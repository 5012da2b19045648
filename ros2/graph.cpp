#include "ros2/graph.hpp"

#include "output/cdr_writer.hpp"
#include "ros/cdr.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace locaid::ros2 {
namespace {

constexpr const char* kGraphTopic = "ros_discovery_info";
constexpr const char* kGraphType = "rmw_dds_common/msg/ParticipantEntitiesInfo";

void PutGid(output::CdrWriter& w, const Guid& gid, size_t bytes) {
  for (size_t i = 0; i < bytes; ++i) w.Uint8(i < gid.size() ? gid[i] : 0);
}

void PutGids(output::CdrWriter& w, const std::vector<Guid>& gids, size_t bytes) {
  w.SequenceLength(gids.size());
  for (const Guid& g : gids) PutGid(w, g, bytes);
}

Guid ReadGid(ros::CdrReader& r, size_t bytes) {
  Guid g{};
  const std::string_view data = r.Bytes(bytes);
  std::copy_n(data.begin(), g.size(), g.begin());
  return g;
}

std::vector<Guid> ReadGids(ros::CdrReader& r, size_t bytes) {
  std::vector<Guid> out(r.SequenceLength(bytes));
  for (Guid& g : out) g = ReadGid(r, bytes);
  return out;
}

bool NameStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool NameChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

// A name part: [A-Za-z_][A-Za-z0-9_]*.
bool ValidPart(std::string_view s) {
  return !s.empty() && NameStart(s.front()) && std::all_of(s.begin(), s.end(), NameChar);
}

}  // namespace

RosDistro ParseRosDistro(std::string_view name) {
  if (name == "humble") return RosDistro::kHumble;
  if (name == "iron" || name == "jazzy" || name == "kilted" || name == "rolling") return RosDistro::kIronOrLater;
  throw std::invalid_argument("ROS 2 distribution '" + std::string(name) +
                              "' is none of humble, iron, jazzy, kilted, rolling");
}

size_t GidBytes(RosDistro distro) { return distro == RosDistro::kHumble ? 24 : 16; }

std::string EncodeParticipantEntitiesInfo(const ParticipantEntities& info, RosDistro distro) {
  const size_t bytes = GidBytes(distro);
  output::CdrWriter w;
  PutGid(w, info.gid, bytes);
  w.SequenceLength(info.nodes.size());
  for (const NodeEntities& n : info.nodes) {
    w.String(n.ns);
    w.String(n.name);
    PutGids(w, n.readers, bytes);
    PutGids(w, n.writers, bytes);
  }
  return w.data();
}

ParticipantEntities DecodeParticipantEntitiesInfo(std::string_view cdr, RosDistro distro) {
  const size_t bytes = GidBytes(distro);
  ros::CdrReader r(cdr);
  ParticipantEntities info;
  info.gid = ReadGid(r, bytes);
  // A node is at least two empty strings (4 + 1 bytes each) and two counts.
  info.nodes.resize(r.SequenceLength(18));
  for (NodeEntities& n : info.nodes) {
    n.ns = r.String();
    n.name = r.String();
    n.readers = ReadGids(r, bytes);
    n.writers = ReadGids(r, bytes);
  }
  return info;
}

void CheckNodeName(const std::string& ns, const std::string& name) {
  if (!ValidPart(name)) {
    throw std::invalid_argument("node name '" + name + "': letters, digits and _ only, not starting with a digit");
  }
  if (ns == "/") return;
  bool ok = ns.size() > 1 && ns.front() == '/' && ns.back() != '/';
  for (size_t at = 1; ok && at < ns.size();) {
    const size_t next = std::min(ns.find('/', at), ns.size());
    ok = ValidPart(std::string_view(ns).substr(at, next - at));
    at = next + 1;
  }
  if (!ok) throw std::invalid_argument("namespace '" + ns + "': '/' or /part/part... (letters, digits, _)");
}

Node::Node(const NodeOptions& options) : options_(options) {
  CheckNodeName(options_.ns, options_.name);
  participant_ = std::make_unique<Participant>(options_.participant);
  // rmw's own settings for the graph topic: reliable, transient local, keep last 1.
  graph_ = participant_->CreateWriter(kGraphTopic, kGraphType,
                                      Qos{Reliability::kReliable, Durability::kTransientLocal, 1},
                                      /*raw_dds_topic=*/true);
  std::lock_guard lock(mu_);
  entities_.gid = participant_->guid();
  entities_.nodes.push_back(NodeEntities{options_.ns, options_.name, {}, {}});
  Announce();
}

Node::~Node() {
  // Tell the graph the node is gone before the participant goes.
  try {
    std::lock_guard lock(mu_);
    entities_.nodes.clear();
    Announce();
  } catch (const std::exception&) {
  }
  graph_.reset();
}

std::unique_ptr<Writer> Node::CreatePublisher(const std::string& topic, const std::string& type, const Qos& qos) {
  auto writer = participant_->CreateWriter(topic, type, qos);
  Add(&NodeEntities::writers, writer->guid());
  return writer;
}

std::unique_ptr<Reader> Node::CreateSubscription(const std::string& topic, const std::string& type, const Qos& qos) {
  auto reader = participant_->CreateReader(topic, type, qos);
  Add(&NodeEntities::readers, reader->guid());
  return reader;
}

void Node::Add(std::vector<Guid> NodeEntities::*list, const Guid& gid) {
  std::lock_guard lock(mu_);
  (entities_.nodes.front().*list).push_back(gid);
  Announce();
}

void Node::Announce() { graph_->Write(EncodeParticipantEntitiesInfo(entities_, options_.distro)); }

}  // namespace locaid::ros2
