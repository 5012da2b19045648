// ROS 2 topics on Eclipse Cyclone DDS without ROS: a participant, writers and
// readers of plain CDR (XCDR1) messages under ROS 2's naming conventions.
//
//  - A ROS topic "/locaid/odometry" is the DDS topic "rt/locaid/odometry"; a
//    ROS type "nav_msgs/msg/Odometry" is the DDS type
//    "nav_msgs::msg::dds_::Odometry_" (what rmw_cyclonedds_cpp and
//    rmw_fastrtps_cpp register).
//  - Samples are the message's CDR bytes, encapsulation header included, as
//    locaid's encoders write them (output/cdr_writer.hpp) and its decoders
//    read them (ros/messages.hpp): a type-agnostic "raw" sertype carries the
//    bytes as they are, in both directions, so a message that does not
//    decode reaches the caller (and is counted there) instead of being
//    dropped inside DDS. No type information is announced; peers match on
//    topic and type name, as ROS 2's own rmw implementations do.
//  - Readers and writers ask for the XCDR1 data representation, as
//    rmw_cyclonedds_cpp does.
//
// The DDS configuration (interfaces, peers, multicast) is Cyclone's own:
// CYCLONEDDS_URI, or the XML text given to the participant. Errors are
// DdsError naming the call and Cyclone's return code.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace locaid::ros2 {

class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "/locaid/odometry" -> "rt/locaid/odometry". Throws std::invalid_argument
// for a name that is not absolute, ends with '/', or holds a character ROS
// names do not allow.
std::string DdsTopicName(std::string_view ros_topic);
// "rt/locaid/odometry" -> "/locaid/odometry"; "" for a DDS topic that is not
// a ROS topic (no "rt/" prefix).
std::string RosTopicName(std::string_view dds_topic);
// "nav_msgs/msg/Odometry" -> "nav_msgs::msg::dds_::Odometry_". Throws
// std::invalid_argument unless the name is "<package>/msg/<Type>".
std::string DdsTypeName(std::string_view ros_type);
// The inverse; "" when `dds_type` is not of that form.
std::string RosTypeName(std::string_view dds_type);

enum class Reliability { kReliable, kBestEffort };
enum class Durability { kVolatile, kTransientLocal };
struct Qos {
  Reliability reliability = Reliability::kReliable;
  Durability durability = Durability::kVolatile;
  int depth = 10;  // keep last N (>= 1)
};
// ROS 2's "sensor data" profile: best effort, volatile, keep last `depth`.
inline Qos SensorDataQos(int depth = 5) { return {Reliability::kBestEffort, Durability::kVolatile, depth}; }
// "reliable", "best_effort" / "volatile", "transient_local" / "depth=N",
// comma separated, over `base`; throws std::invalid_argument naming the part.
Qos ParseQos(std::string_view text, Qos base);
std::string DescribeQos(const Qos& qos);  // "reliable, transient_local, depth 1"

// A DDS GUID (participant prefix + entity id), as ROS 2 uses it for a gid.
using Guid = std::array<uint8_t, 16>;
std::string GuidText(const Guid& guid);  // 32 hex digits

// One message taken from a reader.
struct Sample {
  std::string data;              // CDR bytes, encapsulation header included
  int64_t source_time_ns = 0;    // the writer's source timestamp
  Guid publication{};            // the writer that sent it
};

// A publication (remote or local) seen through DDS discovery.
struct Publication {
  std::string topic, type;  // DDS names ("rt/imu", "sensor_msgs::msg::dds_::Imu_")
  Guid guid{}, participant{};
  bool alive = true;        // false: it went away (disposed)
};

class Participant;

class Writer {
 public:
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  // Publishes one message (CDR with its encapsulation header). Throws
  // DdsError when DDS refuses it.
  void Write(std::string_view cdr);
  Guid guid() const;
  // Readers matched with it now.
  int matched() const;
  const std::string& ros_topic() const { return ros_topic_; }

 private:
  friend class Participant;
  Writer(int32_t topic, int32_t writer, std::string ros_topic) : topic_(topic), writer_(writer), ros_topic_(std::move(ros_topic)) {}
  int32_t topic_, writer_;
  std::string ros_topic_;
};

class Reader {
 public:
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  // Appends every message waiting (at most `max`); returns how many.
  size_t Take(std::vector<Sample>& out, size_t max = 256);
  Guid guid() const;
  int matched() const;  // writers matched with it now
  const std::string& ros_topic() const { return ros_topic_; }
  int32_t handle() const { return reader_; }

 private:
  friend class Participant;
  Reader(int32_t topic, int32_t reader, std::string ros_topic) : topic_(topic), reader_(reader), ros_topic_(std::move(ros_topic)) {}
  int32_t topic_, reader_;
  std::string ros_topic_;
};

struct ParticipantOptions {
  uint32_t domain_id = 0;
  // Cyclone's XML configuration; empty: Cyclone's default (CYCLONEDDS_URI).
  std::string config_xml;
  // The participant's USER_DATA, as rmw_cyclonedds_cpp sets it.
  std::string user_data = "enclave=/;";
};

class Participant {
 public:
  explicit Participant(const ParticipantOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  // `ros_topic` is a ROS name ("/tf") unless `raw_dds_topic`: then it is
  // the DDS topic name as is (ROS 2's graph topic "ros_discovery_info").
  std::unique_ptr<Writer> CreateWriter(const std::string& ros_topic, const std::string& ros_type, const Qos& qos,
                                       bool raw_dds_topic = false);
  std::unique_ptr<Reader> CreateReader(const std::string& ros_topic, const std::string& ros_type, const Qos& qos,
                                       bool raw_dds_topic = false);

  // Waits at most `timeout` until one of this participant's readers has a
  // message (or, after WatchPublications(), discovery has news). One
  // thread at a time.
  void Wait(std::chrono::milliseconds timeout);
  // From now on TakePublications() returns the publications DDS discovers.
  void WatchPublications();
  // Publications discovered (or gone) since the last call.
  std::vector<Publication> TakePublications();

  Guid guid() const;
  uint32_t domain_id() const { return domain_id_; }

 private:
  int32_t participant_ = 0, domain_ = 0, publications_ = 0, waitset_ = 0;
  uint32_t domain_id_ = 0;
};

// The domain id: `flag` when >= 0, else ROS_DOMAIN_ID (0 when unset).
// Throws std::invalid_argument for a value outside 0..232 (what fits the
// RTPS port mapping) or an environment value that is not a number.
uint32_t DomainId(int flag);

}  // namespace locaid::ros2
