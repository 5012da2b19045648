// libFuzzer target: ROS 2's graph message as locaid-ros2 reads it
// (ros2/graph.hpp DecodeParticipantEntitiesInfo: rmw_dds_common's
// ParticipantEntitiesInfo, the humble and the iron+ gid layout).
// Contract: it returns the message or throws ros::CdrError; what it returns
// encodes and decodes to itself (gids, names, every node's readers and
// writers).
#include "fuzz/fuzz_support.hpp"
#include "ros/cdr.hpp"
#include "ros2/graph.hpp"

#include <exception>
#include <typeinfo>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using locaid::ros2::RosDistro;
  const std::string_view cdr = locaid::fuzz::AsText(data, size);
  for (const RosDistro distro : {RosDistro::kHumble, RosDistro::kIronOrLater}) {
    locaid::ros2::ParticipantEntities info;
    try {
      info = locaid::ros2::DecodeParticipantEntitiesInfo(cdr, distro);
    } catch (const locaid::ros::CdrError&) {
      continue;
    } catch (const std::exception& e) {
      locaid::fuzz::Fail(std::string("DecodeParticipantEntitiesInfo threw ") + typeid(e).name() + ": " + e.what());
    }
    try {
      const auto again = locaid::ros2::DecodeParticipantEntitiesInfo(
          locaid::ros2::EncodeParticipantEntitiesInfo(info, distro), distro);
      LOCAID_FUZZ_CHECK(again.gid == info.gid && again.nodes.size() == info.nodes.size(), "round trip differs");
      for (size_t i = 0; i < info.nodes.size(); ++i) {
        const auto &a = info.nodes[i], &b = again.nodes[i];
        LOCAID_FUZZ_CHECK(a.ns == b.ns && a.name == b.name && a.readers == b.readers && a.writers == b.writers,
                          "a node differs after the round trip");
      }
    } catch (const std::exception& e) {
      locaid::fuzz::Fail(std::string("re-encoding threw ") + typeid(e).name() + ": " + e.what());
    }
  }
  return 0;
}
