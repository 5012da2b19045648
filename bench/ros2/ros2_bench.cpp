// locaid-bench-ros2: what locaid-ros2 costs, measured against a Fast DDS
// subscriber (the DDS under ROS 2's default rmw) on loopback, with the real
// locaid-server and locaid-ros2 as child processes (docs/ros2.md,
// "Benchmark").
//
//   locaid-bench-ros2 delay --rate-hz 10 --seconds 30
//     A live session fed small GRAY8 frames at the rate (poses at that rate;
//     the pose content does not matter), locaid-ros2 following it. Delay of
//     each pose from leaving the filter (PoseUpdate.published_unix_ns, read
//     from a gRPC subscriber of the same session) to a Fast DDS reader of
//     /locaid/odometry receiving it (matched on header.stamp = t_ns): p50,
//     p99, max; poses lost; locaid-ros2's CPU per second.
//
//   locaid-bench-ros2 inputs --bag drive.mcap
//     A ROS 2 bag (e.g. the KITTI excerpt written by
//     tests/rosbag/js/kitti_to_bag.mjs) played in real time by a Fast DDS
//     publisher into locaid-ros2 --inputs: locaid-ros2's CPU (all of it, and
//     the part spent decoding and rectifying images), and the delay from a
//     left Image published to the Odometry of its stamp received.
//
// One JSON object on stdout. The clocks are this host's (Unix time).
#include "fast_peer.hpp"
#include "process.hpp"  // tests/sweep: a child process of its own

#include "bag/ros_bag.hpp"
#include "locaid/v1/localization.grpc.pb.h"
#include "ros/messages.hpp"
#include "ros2/dds.hpp"

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>


namespace {

namespace v1 = locaid::v1;
namespace rt = locaid::ros2::testing;
namespace fs = std::filesystem;
using nlohmann::json;

// A child process (stdout and stderr into its log), stopped with SIGTERM.
class Process {
 public:
  Process(const std::vector<std::string>& argv, const fs::path& log) : child_(argv, log.string()) {
    if (!child_.started()) throw std::runtime_error("cannot start " + argv[0]);
  }
  ~Process() { Stop(); }
  void Stop() {
    if (stopped_) return;
    child_.Signal(SIGTERM);
    child_.Wait();
    stopped_ = true;
  }
  // CPU seconds (user + system) so far, from /proc/PID/stat.
  double CpuS() const {
    std::ifstream in("/proc/" + std::to_string(child_.pid()) + "/stat");
    std::string stat((std::istreambuf_iterator<char>(in)), {});
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));
    std::string f;
    double ticks = 0;
    for (int i = 3; i <= 15 && fields >> f; ++i)
      if (i == 14 || i == 15) ticks += std::stod(f);
    return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
  }

 private:
  locaid::sweep_test::Background child_;
  bool stopped_ = false;
};

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p / 100.0 * static_cast<double>(v.size())))];
}

json Summary(const std::vector<double>& ms) {
  return {{"n", ms.size()},
          {"p50_ms", Percentile(ms, 50)},
          {"p99_ms", Percentile(ms, 99)},
          {"max_ms", ms.empty() ? NAN : *std::max_element(ms.begin(), ms.end())}};
}

struct Rig {
  fs::path dir;
  std::string bin;
  std::unique_ptr<rt::DdsLoopback> loopback;
  std::unique_ptr<rt::FastPeer> fast;
  std::unique_ptr<Process> server;
  std::string address;

  Rig(const std::string& bin_dir, uint32_t domain) : bin(bin_dir) {
    char pattern[] = "/tmp/locaid_ros2_bench_XXXXXX";
    dir = mkdtemp(pattern);
    loopback = std::make_unique<rt::DdsLoopback>(dir, domain);
    fast = std::make_unique<rt::FastPeer>(domain, loopback->fastdds);
    server = std::make_unique<Process>(
        std::vector<std::string>{bin + "/locaid-server", "--listen", "127.0.0.1:0", "--port-file",
                                 (dir / "port").string(), "--work-dir", (dir / "work").string()},
        dir / "server.log");
    for (int i = 0; i < 200 && !fs::exists(dir / "port"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::ifstream port(dir / "port");
    int p = 0;
    port >> p;
    if (p <= 0) throw std::runtime_error("locaid-server did not start");
    address = "127.0.0.1:" + std::to_string(p);
  }
  ~Rig() {
    server.reset();
    fast.reset();
    std::error_code ignored;
    fs::remove_all(dir, ignored);
  }
  std::unique_ptr<Process> Ros2(const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {bin + "/locaid-ros2", "--server", address, "--domain",
                                     std::to_string(loopback->domain), "--stats-json", (dir / "ros2.json").string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    return std::make_unique<Process>(argv, dir / "ros2.log");
  }
};

json Delay(const std::string& bin, double rate_hz, double seconds) {
  Rig rig(bin, locaid::ros2::testing::TestDomain());
  auto odom = rig.fast->Subscribe<nav_msgs::msg::dds_::Odometry_PubSubType>("rt/locaid/odometry", {true, false, 100});
  std::mutex mu;
  std::map<int64_t, int64_t> received;  // t_ns -> receipt (Unix ns)
  odom->OnSample([&](const auto& r) {
    std::lock_guard lock(mu);
    received[rt::StampNs(r.msg.header().stamp())] = r.received_unix_ns;
  });
  auto stub = v1::Localization::NewStub(grpc::CreateChannel(rig.address, grpc::InsecureChannelCredentials()));
  grpc::ClientContext push_ctx;
  auto push = stub->PushSensorData(&push_ctx);
  v1::PushRequest start;
  auto* live = start.mutable_start()->mutable_live();
  live->set_fx(30), live->set_fy(30), live->set_cx(16), live->set_cy(12), live->set_baseline_m(0.5);
  live->set_width(32), live->set_height(24), live->set_no_imu(true);
  v1::PushResponse first;
  if (!push->Write(start) || !push->Read(&first) || !first.has_session()) throw std::runtime_error("PushSensorData failed");
  std::thread drain([&] {
    v1::PushResponse r;
    while (push->Read(&r)) {
    }
  });
  // The server's hand-over time of each pose, from a gRPC subscriber.
  std::map<int64_t, int64_t> published;
  grpc::ClientContext poses_ctx;
  v1::StreamPosesRequest req;
  req.set_session_id(first.session().id());
  auto poses = stub->StreamPoses(&poses_ctx, req);
  std::thread collect([&] {
    v1::PoseUpdate p;
    while (poses->Read(&p)) {
      std::lock_guard lock(mu);
      published[p.t_ns()] = p.published_unix_ns();
    }
  });
  // locaid-ros2 follows this session from the start (not polling for the newest).
  auto ros2 = rig.Ros2({"--session", first.session().id()});
  if (!odom->WaitMatched(10)) throw std::runtime_error("no DDS match with locaid-ros2 in 10 s");
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));  // every stream attached
  const auto period = std::chrono::duration<double>(1.0 / rate_hz);
  const int frames = static_cast<int>(rate_hz * seconds);
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = ros2->CpuS();
  std::string image(32 * 24, '\0');
  for (int k = 0; k < frames; ++k) {
    std::this_thread::sleep_until(t0 + k * period);
    v1::PushRequest f;
    f.mutable_frame()->set_t_ns(rt::UnixNowNs());
    f.mutable_frame()->set_encoding(v1::IMAGE_ENCODING_GRAY8);
    for (size_t i = 0; i < image.size(); ++i) image[i] = static_cast<char>((i * 7 + static_cast<size_t>(k)) & 0xff);
    f.mutable_frame()->set_left(image);
    f.mutable_frame()->set_right(image);
    push->Write(f);
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu_s = ros2->CpuS() - cpu0;
  push->WritesDone();
  drain.join();
  push->Finish();
  collect.join();
  poses->Finish();
  ros2->Stop();
  std::vector<double> delays_ms;
  std::lock_guard lock(mu);
  for (const auto& [t, pub] : published) {
    const auto it = received.find(t);
    if (it != received.end()) delays_ms.push_back(static_cast<double>(it->second - pub) * 1e-6);
  }
  json j = Summary(delays_ms);
  j["rate_hz"] = rate_hz;
  j["poses"] = published.size();
  j["lost"] = published.size() - delays_ms.size();
  j["ros2_cpu_cores"] = cpu_s / wall_s;
  return j;
}

json Inputs(const std::string& bin, const fs::path& bag_path) {
  Rig rig(bin, locaid::ros2::testing::TestDomain());
  struct Timed {
    int64_t at_ns;
    std::string topic, cdr;
  };
  std::vector<Timed> play;
  std::map<std::string, std::string> types;
  {
    locaid::bag::RosBag bag(bag_path);
    locaid::bag::BagMessage m;
    int64_t first = -1;
    while (bag.Next(m)) {
      if (first < 0) first = static_cast<int64_t>(m.log_time_ns);
      types[std::string(m.topic)] = std::string(m.type);
      play.push_back({static_cast<int64_t>(m.log_time_ns) - first, std::string(m.topic), std::string(m.data)});
    }
  }
  std::map<std::string, std::unique_ptr<rt::FastWriter>> writers;
  for (const auto& [topic, type] : types) {
    const bool tf = topic == "/tf_static";
    writers[topic] = rig.fast->AdvertiseRos(type, locaid::ros2::DdsTopicName(topic), {true, tf, tf ? 1 : 50});
  }
  auto odom = rig.fast->Subscribe<nav_msgs::msg::dds_::Odometry_PubSubType>("rt/locaid/odometry", {true, false, 100});
  std::mutex mu;
  std::map<int64_t, int64_t> received, sent;  // stamp -> Unix ns
  odom->OnSample([&](const auto& r) {
    std::lock_guard lock(mu);
    received[rt::StampNs(r.msg.header().stamp())] = r.received_unix_ns;
  });
  auto ros2 = rig.Ros2({"--inputs", "/dev/null", "--discovery-s", "1"});  // topics picked by type
  // The first message of each topic until the session starts (camera_info, IMU frame, /tf_static).
  std::map<std::string, const Timed*> firsts;
  for (const Timed& t : play) firsts.emplace(t.topic, &t);
  const auto ros2_log = [&] {
    std::ifstream in(rig.dir / "ros2.log");
    return std::string((std::istreambuf_iterator<char>(in)), {});
  };
  for (int i = 0; ros2_log().find("started (live") == std::string::npos; ++i) {
    if (i > 300) throw std::runtime_error("locaid-ros2 did not start a session:\n" + ros2_log());
    for (const auto& [topic, t] : firsts) writers.at(topic)->WriteCdr(t->cdr);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  // Its publishers exist once its inputs are set up.
  if (!odom->WaitMatched(10)) throw std::runtime_error("no DDS match with locaid-ros2 in 10 s");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const std::string left = "/camera/left/image_raw";
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = ros2->CpuS();
  for (const Timed& t : play) {
    std::this_thread::sleep_until(t0 + std::chrono::nanoseconds(t.at_ns));
    const int64_t now = rt::UnixNowNs();
    writers.at(t.topic)->WriteCdr(t.cdr);
    if (t.topic == left) {
      std::lock_guard lock(mu);
      sent[locaid::ros::DecodeHeader(t.cdr).stamp_ns] = now;
    }
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu_s = ros2->CpuS() - cpu0;
  ros2->Stop();
  std::ifstream stats_file(rig.dir / "ros2.json");
  const json stats = json::parse(stats_file, nullptr, false);
  std::vector<double> delays_ms;
  std::lock_guard lock(mu);
  for (const auto& [t, at] : sent) {
    const auto it = received.find(t);
    if (it != received.end()) delays_ms.push_back(static_cast<double>(it->second - at) * 1e-6);
  }
  json j;
  j["image_to_odometry"] = Summary(delays_ms);
  j["frames"] = sent.size();
  j["poses_received"] = received.size();
  j["wall_s"] = wall_s;
  j["ros2_cpu_cores"] = cpu_s / wall_s;
  const double image_cpu_s = stats.is_object() ? stats.value("image_cpu_s", 0.0) : 0.0;
  j["ros2_image_cpu_cores"] = image_cpu_s / wall_s;  // whole run; decoding happens while playing
  j["ros2_cpu_cores_beyond_images"] = (cpu_s - image_cpu_s) / wall_s;
  j["frames_dropped_late"] = stats.is_object() ? stats.value("frames_dropped_late", 0) : 0;
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locaid-bench-ros2: locaid-ros2's delay and CPU against a Fast DDS peer on loopback"};
  std::string bin = (fs::path(argv[0]).parent_path()).string();
  double rate_hz = 10, seconds = 30;
  std::string bag;
  app.add_option("--bin-dir", bin, "where locaid-server and locaid-ros2 are")->capture_default_str();
  auto* delay = app.add_subcommand("delay", "pose leaving the filter -> Fast DDS /locaid/odometry");
  delay->add_option("--rate-hz", rate_hz, "poses per second")->capture_default_str();
  delay->add_option("--seconds", seconds, "how long")->capture_default_str();
  auto* inputs = app.add_subcommand("inputs", "a bag played over Fast DDS into locaid-ros2 --inputs");
  inputs->add_option("--bag", bag, "ROS 2 bag (MCAP)")->required()->check(CLI::ExistingFile);
  app.require_subcommand(1);
  CLI11_PARSE(app, argc, argv);
  try {
    const json j = delay->parsed() ? Delay(bin, rate_hz, seconds) : Inputs(bin, bag);
    std::cout << j.dump(2) << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "locaid-bench-ros2: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
