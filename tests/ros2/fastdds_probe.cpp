// locaid-fastdds-probe: a Fast DDS subscriber of locaid-ros2's
// nav_msgs/Odometry, for checks outside the test binaries (the image test:
// the adapter in its compose container, the probe on the host). It binds one
// address (UDPv4, no multicast, no shared memory), names its peers by
// unicast, waits for `--count` poses or `--timeout-s`, and prints what it
// received as one JSON object: the samples' frame ids, header stamps and
// positions, and how many writers it matched. Exit 0 with `--count`
// samples, 1 without, 2 on bad arguments.
//
//   locaid-fastdds-probe --domain 7 --address 10.89.0.1 --peer 10.89.0.5
//       [--topic /locaid/odometry] [--count 20] [--timeout-s 120]
#include "fast_peer.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace {

namespace fdds = eprosima::fastdds::dds;
using locaid::ros2::testing::FastPeer;
using locaid::ros2::testing::StampNs;
using Odometry = nav_msgs::msg::dds_::Odometry_PubSubType;

struct Options {
  uint32_t domain = 0;
  std::string address = "127.0.0.1", topic = "/locaid/odometry";
  std::vector<std::string> peers;
  size_t count = 20;
  double timeout_s = 120;
};

nlohmann::json Probe(const Options& o) {
  // Fast DDS reads its profiles from a file: one of this process's own.
  const std::filesystem::path xml =
      std::filesystem::temp_directory_path() / ("locaid-fastdds-probe-" + std::to_string(::getpid()) + ".xml");
  std::ofstream(xml) << locaid::ros2::testing::FastDdsUnicastXml(o.address, o.peers);
  nlohmann::json out;
  try {
    FastPeer peer(o.domain, xml);
    std::filesystem::remove(xml);
    auto reader = peer.Subscribe<Odometry>("rt" + o.topic, {true, false, 100});
    const bool enough = reader->WaitCount(o.count, o.timeout_s);
    fdds::SubscriptionMatchedStatus matched;
    reader->reader->get_subscription_matched_status(matched);
    out = {{"domain", o.domain}, {"topic", o.topic}, {"received", reader->count()},
           {"complete", enough}, {"writers_matched", matched.total_count}};
    nlohmann::json samples = nlohmann::json::array();
    for (const auto& r : reader->samples()) {
      const auto& m = r.msg;
      const auto& p = m.pose().pose().position();
      samples.push_back({{"stamp_ns", StampNs(m.header().stamp())},
                         {"frame_id", m.header().frame_id()},
                         {"child_frame_id", m.child_frame_id()},
                         {"position", {p.x(), p.y(), p.z()}}});
    }
    out["samples"] = std::move(samples);
  } catch (...) {
    std::filesystem::remove(xml);
    throw;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Subscribes to locaid-ros2's nav_msgs/Odometry with Fast DDS and prints what arrived as JSON"};
  Options o;
  app.add_option("--domain", o.domain, "DDS domain id (ROS_DOMAIN_ID)")->required()->check(CLI::Range(0, 232));
  app.add_option("--address", o.address, "the one IPv4 address the participant binds")->capture_default_str();
  app.add_option("--peer", o.peers, "a unicast peer's IPv4 address (repeatable)")->required();
  app.add_option("--topic", o.topic, "ROS 2 topic name")->capture_default_str();
  app.add_option("--count", o.count, "samples to wait for")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--timeout-s", o.timeout_s, "how long to wait")->capture_default_str()->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  if (o.topic.empty() || o.topic[0] != '/') {
    std::cerr << "locaid-fastdds-probe: --topic must start with '/', got '" << o.topic << "'\n";
    return 2;
  }
  try {
    const nlohmann::json out = Probe(o);
    std::cout << out.dump() << "\n";
    return out["complete"].get<bool>() ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "locaid-fastdds-probe: " << e.what() << "\n";
    return 2;
  }
}
