// The Fast DDS side of the locaid-ros2 tests and benchmark: a participant of
// eProsima Fast DDS (Debian's libfastrtps, the DDS under ROS 2's default rmw)
// with the ROS 2 types fastddsgen made from idl/, publishing and subscribing
// under ROS 2's names, and the loopback-only configurations of both vendors:
// every participant on 127.0.0.1, multicast off, unicast peers, the test's
// own domain id. No packet leaves the machine. A participant has one topic
// per name: a publisher of another type on a topic is a second FastPeer.
#pragma once

#include "builtin_interfaces/msg/TimePubSubTypes.h"
#include "diagnostic_msgs/msg/DiagnosticArrayPubSubTypes.h"
#include "geometry_msgs/msg/TwistStampedPubSubTypes.h"
#include "nav_msgs/msg/OdometryPubSubTypes.h"
#include "rmw_dds_common/msg/ParticipantEntitiesInfoPubSubTypes.h"
#include "sensor_msgs/msg/CameraInfoPubSubTypes.h"
#include "sensor_msgs/msg/CompressedImagePubSubTypes.h"
#include "sensor_msgs/msg/ImagePubSubTypes.h"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/NavSatFixPubSubTypes.h"
#include "std_msgs/msg/HeaderPubSubTypes.h"
#include "tf2_msgs/msg/TFMessagePubSubTypes.h"

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/subscriber/qos/SubscriberQos.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <unistd.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace locaid::ros2::testing {

namespace fdds = eprosima::fastdds::dds;

// A domain of the test's own (CTest runs tests of one executable in
// separate processes, two at a time): 100..219 from the process id.
inline uint32_t TestDomain() { return 100 + static_cast<uint32_t>(::getpid()) % 120; }

inline int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Cyclone DDS: 127.0.0.1 only, no multicast, peers found by unicast on the
// standard ports of participant indices 0..20.
inline std::string CycloneLoopbackXml() {
  return R"(<CycloneDDS><Domain id="any">
  <General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General>
  <Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>
    <Peers><Peer address="127.0.0.1"/></Peers></Discovery>
</Domain></CycloneDDS>
)";
}

// Fast DDS: profile "loopback", a UDPv4 transport on one address only (no
// shared memory, no multicast), peers by unicast on the given addresses
// (127.0.0.1 for the tests; the image test's probe binds the compose
// network's gateway and names the adapter's container).
inline std::string FastDdsUnicastXml(const std::string& address, const std::vector<std::string>& peers) {
  std::string peer_list;
  for (const std::string& p : peers) peer_list += "<locator><udpv4><address>" + p + "</address></udpv4></locator>";
  const std::string at = "<locator><udpv4><address>" + address + "</address></udpv4></locator>";
  return R"(<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor><transport_id>udp_one_address</transport_id><type>UDPv4</type>
      <interfaceWhiteList><address>)" +
         address + R"(</address></interfaceWhiteList></transport_descriptor>
  </transport_descriptors>
  <participant profile_name="loopback">
    <rtps>
      <userTransports><transport_id>udp_one_address</transport_id></userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
      <builtin>
        <metatrafficUnicastLocatorList>)" +
         at + R"(</metatrafficUnicastLocatorList>
        <initialPeersList>)" +
         peer_list + R"(</initialPeersList>
      </builtin>
      <defaultUnicastLocatorList>)" +
         at + R"(</defaultUnicastLocatorList>
    </rtps>
  </participant>
</profiles>
)";
}
inline std::string FastDdsLoopbackXml() { return FastDdsUnicastXml("127.0.0.1", {"127.0.0.1"}); }

// Both configurations written into `dir`; CYCLONEDDS_URI points at
// Cyclone's, for this process and the children it starts.
struct DdsLoopback {
  explicit DdsLoopback(const std::filesystem::path& dir, uint32_t domain_id = TestDomain())
      : cyclone(dir / "cyclonedds.xml"), fastdds(dir / "fastdds.xml"), domain(domain_id) {
    std::ofstream(cyclone) << CycloneLoopbackXml();
    std::ofstream(fastdds) << FastDdsLoopbackXml();
    ::setenv("CYCLONEDDS_URI", ("file://" + cyclone.string()).c_str(), 1);
  }
  std::filesystem::path cyclone, fastdds;
  uint32_t domain;
};

struct FastQos {
  bool reliable = true, transient_local = false;
  int depth = 10;
};

// A sample as it arrived.
template <class T>
struct Received {
  T msg;
  int64_t received_unix_ns = 0;
  std::array<uint8_t, 16> publication{};  // the writer's GUID
};

template <class PubSub>
class FastReader : public fdds::DataReaderListener {
 public:
  using T = typename PubSub::type;
  // The reader goes with its listener (this), never after it.
  ~FastReader() override {
    if (reader != nullptr) const_cast<fdds::Subscriber*>(reader->get_subscriber())->delete_datareader(reader);
  }
  void on_data_available(fdds::DataReader* reader) override {
    T msg;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&msg, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      Received<T> r{msg, UnixNowNs(), {}};
      std::memcpy(r.publication.data(), info.publication_handle.value, 16);
      std::lock_guard lock(mu_);
      if (on_sample_) on_sample_(r);
      samples_.push_back(std::move(r));
      cv_.notify_all();
    }
  }
  std::vector<Received<T>> samples() {
    std::lock_guard lock(mu_);
    return samples_;
  }
  size_t count() {
    std::lock_guard lock(mu_);
    return samples_.size();
  }
  // Waits (bounded) until `pred(samples)` holds.
  bool WaitFor(const std::function<bool(const std::vector<Received<T>>&)>& pred, double timeout_s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] { return pred(samples_); });
  }
  bool WaitCount(size_t n, double timeout_s) {
    return WaitFor([n](const auto& s) { return s.size() >= n; }, timeout_s);
  }
  // Waits (bounded) until the reader matched a writer.
  bool WaitMatched(double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    fdds::SubscriptionMatchedStatus m;
    for (;;) {
      reader->get_subscription_matched_status(m);
      if (m.current_count > 0) return true;
      if (std::chrono::steady_clock::now() >= until) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  // Runs on the DDS thread for every sample, under the reader's lock.
  void OnSample(std::function<void(const Received<T>&)> f) {
    std::lock_guard lock(mu_);
    on_sample_ = std::move(f);
  }
  fdds::DataReader* reader = nullptr;

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<Received<T>> samples_;
  std::function<void(const Received<T>&)> on_sample_;
};

class FastWriter {
 public:
  FastWriter(fdds::DataWriter* writer, fdds::TypeSupport type) : writer_(writer), type_(std::move(type)) {}
  bool Write(void* sample) { return writer_->write(sample); }
  // A message given as CDR (encapsulation included), deserialized by the
  // generated type and published by Fast DDS.
  bool WriteCdr(std::string_view cdr) {
    eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<uint32_t>(cdr.size()));
    std::memcpy(payload.data, cdr.data(), cdr.size());
    payload.length = static_cast<uint32_t>(cdr.size());
    void* sample = type_->createData();
    const bool ok = type_->deserialize(&payload, sample) && writer_->write(sample);
    type_->deleteData(sample);
    return ok;
  }
  int matched() {
    fdds::PublicationMatchedStatus s;
    writer_->get_publication_matched_status(s);
    return s.current_count;
  }
  bool WaitMatched(int n, double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (matched() < n) {
      if (std::chrono::steady_clock::now() >= until) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
  }
  fdds::DataWriter* writer() { return writer_; }

 private:
  fdds::DataWriter* writer_;
  fdds::TypeSupport type_;
};

class FastPeer {
 public:
  FastPeer(uint32_t domain, const std::filesystem::path& profiles) {
    auto* factory = fdds::DomainParticipantFactory::get_instance();
    static bool loaded = false;  // Fast DDS keeps a process's profiles (every test writes the same)
    if (!loaded) {
      if (factory->load_XML_profiles_file(profiles.string()) != ReturnCode_t::RETCODE_OK)
        throw std::runtime_error("Fast DDS: cannot load " + profiles.string());
      loaded = true;
    }
    participant_ = factory->create_participant_with_profile(static_cast<fdds::DomainId_t>(domain), "loopback");
    if (participant_ == nullptr) throw std::runtime_error("Fast DDS: no participant");
    publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
    // Readers are enabled once made: a transient local sample arriving while
    // create_datareader runs would find its listener's reader not set yet.
    fdds::SubscriberQos sq = fdds::SUBSCRIBER_QOS_DEFAULT;
    sq.entity_factory().autoenable_created_entities = false;
    subscriber_ = participant_->create_subscriber(sq);
  }
  ~FastPeer() {
    participant_->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }
  FastPeer(const FastPeer&) = delete;
  FastPeer& operator=(const FastPeer&) = delete;

  // `dds_topic` as DDS names it ("rt/locaid/odometry", "ros_discovery_info").
  template <class PubSub>
  std::unique_ptr<FastReader<PubSub>> Subscribe(const std::string& dds_topic, FastQos q = {}) {
    fdds::Topic* topic = TopicOf(dds_topic, fdds::TypeSupport(new PubSub()));
    fdds::DataReaderQos rq = fdds::DATAREADER_QOS_DEFAULT;
    rq.reliability().kind = q.reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS;
    rq.durability().kind = q.transient_local ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS : fdds::VOLATILE_DURABILITY_QOS;
    rq.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    rq.history().depth = q.depth;
    auto reader = std::make_unique<FastReader<PubSub>>();
    reader->reader = subscriber_->create_datareader(topic, rq, reader.get());
    if (reader->reader == nullptr || reader->reader->enable() != ReturnCode_t::RETCODE_OK)
      throw std::runtime_error("Fast DDS: no reader on " + dds_topic);
    return reader;
  }
  template <class PubSub>
  void Unsubscribe(std::unique_ptr<FastReader<PubSub>>& reader) {
    reader.reset();
  }

  template <class PubSub>
  std::unique_ptr<FastWriter> Advertise(const std::string& dds_topic, FastQos q = {}) {
    fdds::TypeSupport type(new PubSub());
    fdds::Topic* topic = TopicOf(dds_topic, type);
    fdds::DataWriterQos wq = fdds::DATAWRITER_QOS_DEFAULT;
    wq.reliability().kind = q.reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS;
    wq.durability().kind = q.transient_local ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS : fdds::VOLATILE_DURABILITY_QOS;
    wq.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    wq.history().depth = q.depth;
    fdds::DataWriter* w = publisher_->create_datawriter(topic, wq);
    if (w == nullptr) throw std::runtime_error("Fast DDS: no writer on " + dds_topic);
    return std::make_unique<FastWriter>(w, participant_->find_type(type.get_type_name()));
  }
  void Unadvertise(std::unique_ptr<FastWriter>& writer) {
    publisher_->delete_datawriter(writer->writer());
    writer.reset();
  }

  // A writer for a ROS 2 type by its name ("sensor_msgs/msg/Imu"), fed CDR.
  std::unique_ptr<FastWriter> AdvertiseRos(const std::string& ros_type, const std::string& dds_topic, FastQos q = {}) {
    using namespace sensor_msgs::msg::dds_;
    if (ros_type == "sensor_msgs/msg/Image") return Advertise<Image_PubSubType>(dds_topic, q);
    if (ros_type == "sensor_msgs/msg/CompressedImage") return Advertise<CompressedImage_PubSubType>(dds_topic, q);
    if (ros_type == "sensor_msgs/msg/CameraInfo") return Advertise<CameraInfo_PubSubType>(dds_topic, q);
    if (ros_type == "sensor_msgs/msg/Imu") return Advertise<Imu_PubSubType>(dds_topic, q);
    if (ros_type == "sensor_msgs/msg/NavSatFix") return Advertise<NavSatFix_PubSubType>(dds_topic, q);
    if (ros_type == "geometry_msgs/msg/TwistStamped")
      return Advertise<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(dds_topic, q);
    if (ros_type == "tf2_msgs/msg/TFMessage") return Advertise<tf2_msgs::msg::dds_::TFMessage_PubSubType>(dds_topic, q);
    throw std::invalid_argument("FastPeer: no IDL for " + ros_type);
  }

  fdds::DomainParticipant* participant() { return participant_; }

 private:
  fdds::Topic* TopicOf(const std::string& name, fdds::TypeSupport type) {
    if (participant_->find_type(type.get_type_name()).empty()) type.register_type(participant_);
    if (auto it = topics_.find(name); it != topics_.end()) {
      // One topic per name in a participant: another type needs a peer of its own.
      if (it->second->get_type_name() != type.get_type_name())
        throw std::invalid_argument("FastPeer: " + name + " is " + it->second->get_type_name() + " here");
      return it->second;
    }
    fdds::Topic* topic = participant_->create_topic(name, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    if (topic == nullptr) throw std::runtime_error("Fast DDS: no topic " + name);
    topics_[name] = topic;
    return topic;
  }

  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  std::map<std::string, fdds::Topic*> topics_;
};

// builtin_interfaces/Time as int64 ns.
template <class Time>
int64_t StampNs(const Time& t) {
  return static_cast<int64_t>(t.sec()) * 1'000'000'000 + t.nanosec();
}

}  // namespace locaid::ros2::testing
