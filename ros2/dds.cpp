#include "ros2/dds.hpp"

#include "ros2/raw_type.hpp"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace locaid::ros2 {
namespace {

constexpr std::string_view kRosTopicPrefix = "rt";

// Cyclone's return code (negative) as a DdsError naming the call.
int32_t Check(int32_t rc, const std::string& what) {
  if (rc < 0) throw DdsError(what + ": " + dds_strretcode(rc));
  return rc;
}

bool RosNameChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '/'; }

Guid GuidOf(dds_entity_t entity) {
  dds_guid_t g;
  Check(dds_get_guid(entity, &g), "dds_get_guid");
  Guid out;
  std::memcpy(out.data(), g.v, out.size());
  return out;
}

Guid ToGuid(const dds_guid_t& g) {
  Guid out;
  std::memcpy(out.data(), g.v, out.size());
  return out;
}

// Readers and writers: the QoS asked for plus XCDR1 (rmw_cyclonedds_cpp's).
dds_qos_t* EndpointQos(const Qos& q) {
  if (q.depth < 1) throw std::invalid_argument("QoS depth must be >= 1, got " + std::to_string(q.depth));
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, q.reliability == Reliability::kReliable ? DDS_RELIABILITY_RELIABLE
                                                                    : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_SECS(1));
  dds_qset_durability(qos, q.durability == Durability::kTransientLocal ? DDS_DURABILITY_TRANSIENT_LOCAL
                                                                         : DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.depth);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  return qos;
}

// A topic of the raw type (ros2/raw_type.hpp) named `dds_topic`.
dds_entity_t RawTopic(dds_entity_t participant, const std::string& dds_topic, const std::string& dds_type) {
  ddsi_sertype* sertype = detail::NewRawSertype(dds_type.c_str());
  const dds_entity_t topic = dds_create_topic_sertype(participant, dds_topic.c_str(), &sertype, nullptr, nullptr,
                                                      nullptr);
  if (topic < 0) {
    ddsi_sertype_unref(sertype);
    Check(topic, "dds_create_topic_sertype " + dds_topic + " (" + dds_type + ")");
  }
  return topic;
}

}  // namespace

std::string DdsTopicName(std::string_view ros_topic) {
  const std::string name(ros_topic);
  if (name.size() < 2 || name.front() != '/' || name.back() == '/' || name.find("//") != std::string::npos ||
      !std::all_of(name.begin(), name.end(), RosNameChar)) {
    throw std::invalid_argument("'" + name +
                                "' is not an absolute ROS topic name (/ and letters, digits, _ only, e.g. /locaid/odometry)");
  }
  return std::string(kRosTopicPrefix) + name;
}

std::string RosTopicName(std::string_view dds_topic) {
  if (dds_topic.size() <= kRosTopicPrefix.size() + 1 || dds_topic.substr(0, kRosTopicPrefix.size()) != kRosTopicPrefix ||
      dds_topic[kRosTopicPrefix.size()] != '/')
    return "";
  return std::string(dds_topic.substr(kRosTopicPrefix.size()));
}

std::string DdsTypeName(std::string_view ros_type) {
  const size_t a = ros_type.find("/msg/");
  const std::string name(ros_type);
  if (a == std::string_view::npos || a == 0 || a + 5 >= ros_type.size() ||
      ros_type.find('/', a + 5) != std::string_view::npos || ros_type.substr(0, a).find('/') != std::string_view::npos) {
    throw std::invalid_argument("'" + name + "' is not a ROS 2 message type (<package>/msg/<Type>)");
  }
  return std::string(ros_type.substr(0, a)) + "::msg::dds_::" + std::string(ros_type.substr(a + 5)) + "_";
}

std::string RosTypeName(std::string_view dds_type) {
  constexpr std::string_view kMiddle = "::msg::dds_::";
  const size_t a = dds_type.find(kMiddle);
  if (a == std::string_view::npos || a == 0 || dds_type.size() < a + kMiddle.size() + 2 || dds_type.back() != '_')
    return "";
  const std::string_view type = dds_type.substr(a + kMiddle.size(), dds_type.size() - a - kMiddle.size() - 1);
  if (type.find(':') != std::string_view::npos || dds_type.substr(0, a).find(':') != std::string_view::npos) return "";
  return std::string(dds_type.substr(0, a)) + "/msg/" + std::string(type);
}

Qos ParseQos(std::string_view text, Qos q) {
  std::stringstream in{std::string(text)};
  for (std::string part; std::getline(in, part, ',');) {
    if (part == "reliable") {
      q.reliability = Reliability::kReliable;
    } else if (part == "best_effort") {
      q.reliability = Reliability::kBestEffort;
    } else if (part == "volatile") {
      q.durability = Durability::kVolatile;
    } else if (part == "transient_local") {
      q.durability = Durability::kTransientLocal;
    } else if (part.rfind("depth=", 0) == 0 && part.size() > 6 && part.size() <= 11 &&
               part.find_first_not_of("0123456789", 6) == std::string::npos && std::stol(part.substr(6)) >= 1 &&
               std::stol(part.substr(6)) <= 100000) {
      q.depth = static_cast<int>(std::stol(part.substr(6)));
    } else {
      throw std::invalid_argument("QoS '" + std::string(text) + "': '" + part +
                                  "' is none of reliable, best_effort, volatile, transient_local, depth=N (1..100000)");
    }
  }
  return q;
}

std::string DescribeQos(const Qos& q) {
  return std::string(q.reliability == Reliability::kReliable ? "reliable" : "best_effort") + ", " +
         (q.durability == Durability::kTransientLocal ? "transient_local" : "volatile") + ", depth " +
         std::to_string(q.depth);
}

std::string GuidText(const Guid& guid) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (const uint8_t b : guid) {
    out += kHex[b >> 4];
    out += kHex[b & 15];
  }
  return out;
}

uint32_t DomainId(int flag) {
  long id = flag;
  if (flag < 0) {
    const char* env = std::getenv("ROS_DOMAIN_ID");
    if (env == nullptr || *env == '\0') return 0;
    char* end = nullptr;
    id = std::strtol(env, &end, 10);
    if (*end != '\0') throw std::invalid_argument(std::string("ROS_DOMAIN_ID '") + env + "' is not a number");
  }
  if (id < 0 || id > 232) {
    throw std::invalid_argument("domain id " + std::to_string(id) + " is outside 0..232");
  }
  return static_cast<uint32_t>(id);
}

// ------------------------------------------------------------------ entities --

Writer::~Writer() {
  dds_delete(writer_);
  dds_delete(topic_);
}

void Writer::Write(std::string_view cdr) {
  const detail::RawSample sample{cdr.data(), cdr.size()};
  Check(dds_write(writer_, &sample), "dds_write " + ros_topic_);
}

Guid Writer::guid() const { return GuidOf(writer_); }

int Writer::matched() const {
  dds_publication_matched_status_t s;
  return dds_get_publication_matched_status(writer_, &s) < 0 ? 0 : static_cast<int>(s.current_count);
}

Reader::~Reader() {
  dds_delete(reader_);
  dds_delete(topic_);
}

size_t Reader::Take(std::vector<Sample>& out, size_t max) {
  constexpr uint32_t kBatch = 16;
  size_t taken = 0;
  while (taken < max) {
    ddsi_serdata* samples[kBatch];
    dds_sample_info_t infos[kBatch];
    const int32_t n = dds_takecdr(reader_, samples, kBatch, infos, DDS_ANY_STATE);
    if (n <= 0) break;
    for (int32_t i = 0; i < n; ++i) {
      if (infos[i].valid_data) {
        Sample s;
        s.data = std::string(detail::RawBytes(samples[i]));
        s.source_time_ns = infos[i].source_timestamp;
        dds_builtintopic_endpoint_t* pub = dds_get_matched_publication_data(reader_, infos[i].publication_handle);
        if (pub != nullptr) {
          s.publication = ToGuid(pub->key);
          dds_builtintopic_free_endpoint(pub);
        }
        out.push_back(std::move(s));
        ++taken;
      }
      ddsi_serdata_unref(samples[i]);
    }
    if (n < static_cast<int32_t>(kBatch)) break;
  }
  return taken;
}

Guid Reader::guid() const { return GuidOf(reader_); }

int Reader::matched() const {
  dds_subscription_matched_status_t s;
  return dds_get_subscription_matched_status(reader_, &s) < 0 ? 0 : static_cast<int>(s.current_count);
}

Participant::Participant(const ParticipantOptions& options) : domain_id_(options.domain_id) {
  if (!options.config_xml.empty()) {
    domain_ = Check(dds_create_domain(options.domain_id, options.config_xml.c_str()), "dds_create_domain");
  }
  dds_qos_t* qos = dds_create_qos();
  dds_qset_userdata(qos, options.user_data.data(), options.user_data.size());
  participant_ = dds_create_participant(options.domain_id, qos, nullptr);
  dds_delete_qos(qos);
  if (participant_ < 0) {
    if (domain_ > 0) dds_delete(domain_);
    Check(participant_, "dds_create_participant (domain " + std::to_string(options.domain_id) + ")");
  }
  waitset_ = dds_create_waitset(participant_);
  if (waitset_ < 0) {
    dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
    Check(waitset_, "dds_create_waitset");
  }
}

Participant::~Participant() {
  dds_delete(participant_);  // and everything in it; Writer/Reader deletes later just fail
  if (domain_ > 0) dds_delete(domain_);
}

std::unique_ptr<Writer> Participant::CreateWriter(const std::string& ros_topic, const std::string& ros_type,
                                                  const Qos& qos, bool raw_dds_topic) {
  const std::string topic_name = raw_dds_topic ? ros_topic : DdsTopicName(ros_topic);
  const dds_entity_t topic = RawTopic(participant_, topic_name, DdsTypeName(ros_type));
  dds_qos_t* q = EndpointQos(qos);
  const dds_entity_t writer = dds_create_writer(participant_, topic, q, nullptr);
  dds_delete_qos(q);
  if (writer < 0) {
    dds_delete(topic);
    Check(writer, "dds_create_writer " + topic_name);
  }
  return std::unique_ptr<Writer>(new Writer(topic, writer, ros_topic));
}

std::unique_ptr<Reader> Participant::CreateReader(const std::string& ros_topic, const std::string& ros_type,
                                                  const Qos& qos, bool raw_dds_topic) {
  const std::string topic_name = raw_dds_topic ? ros_topic : DdsTopicName(ros_topic);
  const dds_entity_t topic = RawTopic(participant_, topic_name, DdsTypeName(ros_type));
  dds_qos_t* q = EndpointQos(qos);
  dds_qset_ignorelocal(q, DDS_IGNORELOCAL_PARTICIPANT);  // a node's own publications are not its input
  const dds_entity_t reader = dds_create_reader(participant_, topic, q, nullptr);
  dds_delete_qos(q);
  if (reader < 0) {
    dds_delete(topic);
    Check(reader, "dds_create_reader " + topic_name);
  }
  const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
  if (condition < 0 || dds_waitset_attach(waitset_, condition, reader) < 0) {
    dds_delete(reader);
    dds_delete(topic);
    Check(condition < 0 ? condition : DDS_RETCODE_ERROR, "waiting on " + topic_name);
  }
  return std::unique_ptr<Reader>(new Reader(topic, reader, ros_topic));
}

void Participant::Wait(std::chrono::milliseconds timeout) {
  dds_waitset_wait(waitset_, nullptr, 0, DDS_MSECS(timeout.count()));
}

void Participant::WatchPublications() {
  if (publications_ > 0) return;
  publications_ = Check(dds_create_reader(participant_, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr),
                        "reading DCPSPublication");
  const dds_entity_t condition = Check(dds_create_readcondition(publications_, DDS_NOT_READ_SAMPLE_STATE),
                                       "DCPSPublication read condition");
  Check(dds_waitset_attach(waitset_, condition, publications_), "waiting on DCPSPublication");
}

std::vector<Publication> Participant::TakePublications() {
  std::vector<Publication> out;
  if (publications_ <= 0) return out;
  constexpr size_t kBatch = 16;
  for (;;) {
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    const int32_t n = dds_take(publications_, samples, infos, kBatch, kBatch);
    if (n <= 0) break;
    for (int32_t i = 0; i < n; ++i) {
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      Publication p;
      p.guid = ToGuid(e->key);
      p.alive = infos[i].valid_data && infos[i].instance_state == DDS_ALIVE_INSTANCE_STATE;
      if (infos[i].valid_data) {
        p.participant = ToGuid(e->participant_key);
        p.topic = e->topic_name ? e->topic_name : "";
        p.type = e->type_name ? e->type_name : "";
      }
      out.push_back(std::move(p));
    }
    dds_return_loan(publications_, samples, n);
    if (n < static_cast<int32_t>(kBatch)) break;
  }
  return out;
}

Guid Participant::guid() const { return GuidOf(participant_); }

}  // namespace locaid::ros2
