// locaid-ros2: locaid on a ROS 2 car, without a bridge: a session's poses
// published as ROS 2 topics (nav_msgs/Odometry, NavSatFix, /tf, /tf_static,
// /diagnostics) and, with --inputs, the car's sensor topics feeding a live
// session, over Eclipse Cyclone DDS as a ROS 2 node (docs/ros2.md).
//
//   locaid-ros2 --server 127.0.0.1:50051 [--session ID|newest]     # poses out
//   locaid-ros2 --server 127.0.0.1:50051 --inputs car.yaml          # topics in, poses out
//
// Threads (started and joined here): the session follower (follow mode) or
// the input thread (--inputs: DDS in, PushSensorData, with the threads
// LiveInput starts per session), a ticker (diagnostics without poses, the
// --stats-json file), and main, which waits for SIGTERM/SIGINT. Exit status:
// 0 after a signal, 1 when DDS or the inputs cannot be set up, 2 for bad
// flags.
#include "connection/connection.hpp"
#include "connection/session_follower.hpp"
#include "output/ros2_recording.hpp"
#include "ros2/apps/live_input.hpp"
#include "ros2/graph.hpp"
#include "ros2/pose_publisher.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>

namespace r2 = locaid::ros2;
using nlohmann::json;

namespace {

std::mutex g_log_mu;

void Log(const std::string& line) {
  std::lock_guard lock(g_log_mu);
  std::cerr << "locaid-ros2: " << line << std::endl;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

double ProcessCpuS() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

json TopicsJson(r2::LiveInput& input) {
  json topics = json::object();
  for (const auto& [role, s] : input.topic_stats()) {
    topics[r2::InputRoleKey(role)] = {{"topic", s.topic},         {"type", s.type},
                                      {"received", s.received},   {"used", s.used},
                                      {"undecodable", s.undecodable}, {"late", s.late},
                                      {"bad", s.bad},             {"unpaired", s.unpaired},
                                      {"wrong_type", s.wrong_type}, {"silences", s.silences},
                                      {"silent", s.silent},       {"last_error", s.last_error}};
  }
  return topics;
}

// What the adapter did so far, for --stats-json (written whole, then renamed).
void WriteStats(const std::string& path, r2::PosePublisher* publisher, r2::LiveInput* input, double wall_s) {
  json j;
  const auto out = publisher ? publisher->stats() : r2::PosePublisher::Stats{};
  j["poses"] = out.poses;
  j["messages"] = out.messages;
  j["cpu_s"] = ProcessCpuS();
  j["wall_s"] = wall_s;
  if (input) {
    const r2::LiveInputCounters c = input->counters();
    j["inputs"] = TopicsJson(*input);
    j["image_cpu_s"] = input->image_cpu_s();
    j["session_id"] = c.session_id;
    j["sessions"] = c.sessions;
    j["frames_dropped_late"] = c.frames_dropped_late;
    j["items_sent"] = c.items_sent;
    j["server_rejected"] = c.server_rejected;
    j["server_last_rejection"] = c.server_last_rejection;
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    f << j.dump(2) << "\n";
    if (!f) return;
  }
  std::rename(tmp.c_str(), path.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  std::string server, token_file, tls_ca, session = "newest", inputs, scenario, dds_config, distro = "jazzy";
  std::string node_name = "locaid_ros2", ns = "/", rig_flag = "kitti", stats_json;
  std::vector<std::string> topic_flags, qos_flags, frame_flags;
  int domain = -1;
  double lag_s = 0, diagnostics_period_s = 1.0;
  r2::InputSetupOptions setup;
  r2::AssemblerOptions assembler;
  double stereo_tolerance_ms = 10, reorder_window_ms = 300;
  size_t max_queued_frames = 2;

  CLI::App app{"locaid-ros2: a locaid session's poses as ROS 2 topics, and a ROS 2 car's topics into a live session, "
               "over DDS (docs/ros2.md)"};
  app.add_option("--server", server, "locaid-server address: host:port or unix:PATH")->required();
  app.add_option("--token-file", token_file, "file holding the server's bearer token")->check(CLI::ExistingFile);
  app.add_option("--tls-ca", tls_ca, "PEM file of the CA (or self-signed cert) to trust; enables TLS")
      ->check(CLI::ExistingFile);
  app.add_option("--session", session, "session whose poses to publish, or 'newest' (follows the newest "
                                       "STARTING/RUNNING one; not with --inputs)")
      ->capture_default_str();
  app.add_option("--lag", lag_s, "publish the smoothed poses, S seconds of sensor time behind (docs/api.md "
                                 "\"Lagged stream\")")
      ->check(CLI::Range(0.0, 30.0));
  app.add_option("--inputs", inputs, "YAML naming the car's topics (keys of --bag-topics: left_image, left_info, "
                                     "right_image, right_info, imu, gps, speed; left out: picked by type): "
                                     "start a live session fed from them")
      ->check(CLI::ExistingFile);
  app.add_option("--scenario", scenario, "--inputs: the session's scenario, a built-in name or a YAML file "
                                         "(outages on the car's own fixes)");
  app.add_option("--domain", domain, "DDS domain id (default: ROS_DOMAIN_ID, else 0)")->check(CLI::Range(0, 232));
  app.add_option("--dds-config", dds_config, "Cyclone DDS XML configuration file (default: CYCLONEDDS_URI)")
      ->check(CLI::ExistingFile);
  app.add_option("--ros-distro", distro, "ROS 2 distribution of the graph's gid layout: humble (24 bytes) or iron, "
                                         "jazzy, kilted, rolling (16)")
      ->capture_default_str();
  app.add_option("--node-name", node_name, "the node's name in the ROS 2 graph")->capture_default_str();
  app.add_option("--namespace", ns, "the node's namespace")->capture_default_str();
  app.add_option("--topic", topic_flags, "KEY=TOPIC (odometry, fix, tf, tf_static, gps, diagnostics); an empty "
                                         "TOPIC turns it off");
  app.add_option("--qos", qos_flags, "KEY=QOS: reliable|best_effort, volatile|transient_local, depth=N "
                                     "(comma separated), over the defaults");
  app.add_option("--frame", frame_flags, "KEY=FRAME_ID (map, body, camera, gps)");
  app.add_option("--diagnostics-period-s", diagnostics_period_s, "diagnostics at most this often; 0: every pose")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
  app.add_option("--rig", rig_flag, "without --inputs, the camera rig on /tf_static: kitti (the KITTI "
                                    "2011_09_26 rig, as `locaid subscribe --format ros2-mcap`) or none")
      ->check(CLI::IsMember({"kitti", "none"}))
      ->capture_default_str();
  app.add_option("--stereo-tolerance-ms", stereo_tolerance_ms, "--inputs: left and right stamps at most this apart "
                                                               "are a pair")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--reorder-window-ms", reorder_window_ms, "--inputs: how long a stream that lags may hold the "
                                                           "others back")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  double gps_hold_ms = 200;
  app.add_option("--gps-hold-ms", gps_hold_ms, "--inputs: how long the other topics wait for a fix that may still "
                                               "come (sent in order; later fixes are fused as late fixes)")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  app.add_option("--silent-after-s", assembler.silent_after_s, "--inputs: a topic without a message this long "
                                                               "is reported silent")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--discovery-s", setup.discovery_s, "--inputs: DDS discovery time before topics are picked by "
                                                     "type")
      ->check(CLI::Range(0.0, 600.0))
      ->capture_default_str();
  app.add_option("--setup-timeout-s", setup.setup_timeout_s, "--inputs: then a topic or first message still "
                                                             "missing is an error")
      ->check(CLI::Range(0.1, 86400.0))
      ->capture_default_str();
  app.add_option("--max-queued-frames", max_queued_frames, "--inputs: frames waiting for the session; a newer one "
                                                           "drops the oldest")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--stats-json", stats_json, "write the adapter's counters to this file every second and at exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }

  r2::NodeOptions node_options;
  r2::PosePublisherOptions publishing;
  locaid::connection::Connection connection;
  locaid::v1::Scenario scenario_msg;
  try {
    if (!inputs.empty() && session != "newest") throw std::invalid_argument("--session and --inputs exclude each other");
    node_options.participant.domain_id = r2::DomainId(domain);
    if (!dds_config.empty()) node_options.participant.config_xml = ReadFile(dds_config);
    node_options.distro = r2::ParseRosDistro(distro);
    node_options.name = node_name;
    node_options.ns = ns;
    r2::CheckNodeName(ns, node_name);
    for (const auto& f : topic_flags) r2::SetTopicOption(publishing, f);
    for (const auto& f : qos_flags) r2::SetQosOption(publishing, f);
    for (const auto& f : frame_flags) r2::SetFrameOption(publishing, f);
    publishing.diagnostics_period_s = diagnostics_period_s;
    if (inputs.empty() && rig_flag == "kitti") publishing.T_body_cam0 = locaid::output::KittiRigTBodyCam0();
    if (scenario.find('/') != std::string::npos || scenario.ends_with(".yaml") || scenario.ends_with(".yml")) {
      scenario_msg.set_yaml(ReadFile(scenario));
    } else if (!scenario.empty()) {
      scenario_msg.set_name(scenario);
    }
    connection.server = server;
    connection.token_file = token_file;
    connection.tls_ca = tls_ca;
    locaid::connection::ResolveToken(connection);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\nRun with --help for more information.\n";
    return 2;
  }
  const auto channel = locaid::connection::MakeChannel(connection);

  // Signals are taken by sigwait on main; SIGUSR1 is the input thread giving up.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGUSR1);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  const auto t0 = std::chrono::steady_clock::now();
  std::unique_ptr<r2::Node> node;
  try {
    node = std::make_unique<r2::Node>(node_options);
  } catch (const std::exception& e) {
    Log(std::string("DDS: ") + e.what());
    return 1;
  }
  Log("node " + (ns == "/" ? "/" : ns + "/") + node_name + " on DDS domain " +
      std::to_string(node_options.participant.domain_id) + " (" + distro + " graph), server " + server);

  std::unique_ptr<r2::PosePublisher> follow_publisher;
  std::unique_ptr<locaid::connection::SessionFollower> follower;
  std::unique_ptr<r2::LiveInput> input;
  std::thread worker;
  std::atomic<int> exit_code{0};
  try {
    if (inputs.empty()) {
      follow_publisher = std::make_unique<r2::PosePublisher>(*node, publishing);
      locaid::connection::FollowerOptions follow;
      follow.channel = channel;
      follow.token = connection.token;
      follow.session = session == "newest" ? "" : session;
      follow.smoothing_lag_s = lag_s;
      follow.log = Log;
      r2::PosePublisher* pub = follow_publisher.get();
      follower = std::make_unique<locaid::connection::SessionFollower>(
          follow, [pub](const std::string&) { pub->NewSession(); },
          [pub](const locaid::v1::PoseUpdate& pose) { pub->Publish(pose); });
      worker = std::thread([&] { follower->Run(); });
    } else {
      r2::LiveInputOptions li;
      li.channel = channel;
      li.token = connection.token;
      li.topics = locaid::bag::LoadBagTopics(inputs);
      li.setup = setup;
      assembler.stereo_tolerance_s = stereo_tolerance_ms * 1e-3;
      assembler.reorder_window_s = reorder_window_ms * 1e-3;
      assembler.gps_hold_s = gps_hold_ms * 1e-3;
      li.assembler = assembler;
      li.scenario = scenario_msg;
      li.smoothing_lag_s = lag_s;
      li.max_queued_frames = max_queued_frames;
      li.log = Log;
      input = std::make_unique<r2::LiveInput>(*node, publishing, li);
      worker = std::thread([&] {
        exit_code = input->Run();
        if (exit_code != 0) kill(getpid(), SIGUSR1);
      });
    }
  } catch (const std::exception& e) {
    Log(e.what());
    if (worker.joinable()) worker.join();
    return inputs.empty() ? 1 : 2;
  }
  const auto publisher = [&]() -> r2::PosePublisher* {
    return follow_publisher ? follow_publisher.get() : input ? input->publisher() : nullptr;
  };

  std::mutex tick_mu;
  std::condition_variable tick_cv;
  bool ticking = true;
  std::thread ticker([&] {
    auto next_stats = std::chrono::steady_clock::now();
    std::unique_lock lock(tick_mu);
    while (ticking) {
      tick_cv.wait_for(lock, std::chrono::milliseconds(200));
      if (!ticking) break;
      if (auto* p = publisher()) p->Tick();
      if (!stats_json.empty() && std::chrono::steady_clock::now() >= next_stats) {
        WriteStats(stats_json, publisher(), input.get(),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        next_stats += std::chrono::seconds(1);
      }
    }
  });

  int signal = 0;
  sigwait(&signals, &signal);
  if (signal != SIGUSR1) Log(std::string("stopping on ") + (signal == SIGTERM ? "SIGTERM" : "SIGINT"));
  if (follower) follower->Stop();
  if (input) input->Stop();
  worker.join();
  {
    std::lock_guard lock(tick_mu);
    ticking = false;
  }
  tick_cv.notify_all();
  ticker.join();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!stats_json.empty()) WriteStats(stats_json, publisher(), input.get(), wall_s);
  const auto out = publisher() ? publisher()->stats() : r2::PosePublisher::Stats{};
  std::ostringstream summary;
  summary << "stopped: " << out.poses << " poses, " << out.messages << " messages published; CPU "
          << ProcessCpuS() << " s in " << wall_s << " s";
  if (input) {
    const auto c = input->counters();
    summary << " (images " << input->image_cpu_s() << " s); " << c.items_sent << " items sent to " << c.sessions
            << " session(s), " << c.frames_dropped_late << " frames dropped late, " << c.server_rejected
            << " refused by the session";
    for (const auto& [role, s] : input->topic_stats()) {
      summary << "\n  " << r2::InputRoleKey(role) << " " << s.topic << ": " << s.received << " received, " << s.used
              << " used";
      for (const auto& [n, what] : {std::pair{s.undecodable, "undecodable"}, {s.late, "late"}, {s.bad, "bad"},
                                    {s.unpaired, "unpaired"}, {s.wrong_type, "publications of a wrong type"},
                                    {s.silences, "silences"}}) {
        if (n > 0) summary << ", " << n << " " << what;
      }
      if (!s.last_error.empty()) summary << " (last: " << s.last_error << ")";
    }
  }
  Log(summary.str());
  input.reset();
  follower.reset();
  follow_publisher.reset();
  node.reset();
  return exit_code;
}
