// locaid: command-line client of locaid-server.
//
//   locaid health [--service NAME] [--wait S]
//   locaid session start --kitti PATH | --bag PATH [--bag-topics F] | --synthetic SEED [--scenario NAME|--scenario-file F] [--vo M] [--rate R]
//   locaid session start --live --camera-left P --camera-right P | --camera-stereo P
//                        --camera-info-left F --camera-info-right F [--gpsd HOST:PORT]
//   locaid session list | get ID | stop ID [--remove]
//   locaid subscribe ID [--from-start] [--lag S] [--format print|tum|kitti|csv|geojson|mcap|ros2-mcap] [--out FILE] [--max N]
//   locaid outage start ID [--duration S] | stop ID | window ID --start S --duration S
//   locaid camera-fault start ID --kind K [--duration S] [--gain G] [--noise-dn N] [--blur-px S]
//                     | stop ID | window ID --kind K --start S --duration S [...]
//   locaid scenario ID (--name NAME | --file YAML)
//   locaid stats ID
// Every call carries a deadline (--timeout-s; subscribe: --stream-timeout-s).
#include "connection/connection.hpp"
#include "clients/cli_camera_fault.hpp"
#include "clients/cli_print.hpp"
#include "clients/cli_session_start.hpp"
#include "clients/recorder.hpp"
#include "output/mcap_recording.hpp"
#include "output/ros2_recording.hpp"
#include "locaid/v1/localization.grpc.pb.h"

#include <CLI/CLI.hpp>
#include <grpcpp/grpcpp.h>
#include <grpcpp/generic/generic_stub.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/un.h>
#include <unistd.h>

namespace v1 = locaid::v1;
using locaid::clients::AddCameraFaultCommand;
using locaid::clients::CameraFaultCommand;
using locaid::clients::AddStartOptions;
using locaid::clients::CameraFaultMessage;
using locaid::clients::FillScenario;
using locaid::clients::ModeName;
using locaid::clients::PrintSession;
using locaid::clients::PrintStats;
using locaid::clients::RecordError;
using locaid::clients::Recorder;
using locaid::clients::StartOptions;
using locaid::clients::StartSessionRequest;

namespace {

struct Common : locaid::connection::Connection {
  double timeout_s = 10;
};

// Checks a --server address; returns "" when usable, else the reason.
// Accepted: host:port (host a name, IPv4 or [IPv6], port 1-65535),
// unix:PATH (absolute or relative) and unix:///ABS/PATH, and gRPC target
// URIs with an explicit scheme (dns:, ipv4:, ipv6:, unix-abstract:) as is.
std::string CheckServerAddress(const std::string& a) {
  if (a.rfind("unix:", 0) == 0) {
    std::string path = a.substr(5);
    if (path.rfind("//", 0) == 0) {
      path = path.substr(2);
      if (path.empty() || path[0] != '/') return "unix://PATH needs an absolute path (unix:///abs/path)";
    }
    if (path.empty()) return "unix: needs a socket path (unix:/abs/path or unix:relative/path)";
    constexpr size_t kSunPathBytes = sizeof(sockaddr_un{}.sun_path);
    if (path.size() >= kSunPathBytes) {
      return "the socket path is " + std::to_string(path.size()) + " bytes, must be < " + std::to_string(kSunPathBytes);
    }
    return "";
  }
  for (const char* scheme : {"dns:", "ipv4:", "ipv6:", "unix-abstract:"}) {
    if (a.rfind(scheme, 0) == 0) return "";
  }
  const auto colon = a.rfind(':');
  if (colon == std::string::npos) return "expected host:port or unix:PATH";
  const std::string host = a.substr(0, colon), port = a.substr(colon + 1);
  if (host.empty()) return "the host before ':' is empty";
  if (host.find(':') != std::string::npos && !(host.front() == '[' && host.back() == ']')) {
    return "an IPv6 host must be in brackets ([::1]:50051)";
  }
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) < 1 || std::stoi(port) > 65535) {
    return "port '" + port + "' is not a number in [1, 65535]";
  }
  return "";
}

void Prepare(const Common& c, grpc::ClientContext* ctx, double timeout_s) {
  locaid::connection::Prepare(c, ctx, timeout_s);
}

// Exit codes: 0 OK, 1 RPC error (status printed), 2 usage error, 3 health
// NOT_SERVING / UNKNOWN, 4 the record file could not be written (subscribe:
// disk full, file size limit, I/O error; the file is kept valid up to the
// last complete pose and the message says how many poses it holds).
int Fail(const grpc::Status& s) {
  std::cerr << "error: " << locaid::connection::StatusCodeName(s.error_code()) << ": " << s.error_message() << "\n";
  return 1;
}

std::unique_ptr<grpc::ClientContext> g_stream_ctx;

void OnSignal(int) { if (g_stream_ctx) g_stream_ctx->TryCancel(); }

struct SubscribeOptions {
  std::string session_id;
  std::string format = "print", out_path;
  bool from_start = false, progress = false;
  uint64_t max_poses = 0;
  uint32_t queue = 0;
  double lag_s = 0;  // StreamPosesRequest.smoothing_lag_s
  double stream_timeout_s = 24 * 3600;
};

// One unary call with the common deadline and credentials: prints the
// response with `print` (exit 0) or the error status (exit 1).
template <typename Request, typename Response, typename Print>
int Unary(const Common& c, v1::Localization::Stub& stub,
          grpc::Status (v1::Localization::Stub::*call)(grpc::ClientContext*, const Request&, Response*),
          const Request& req, Print print) {
  grpc::ClientContext ctx;
  Prepare(c, &ctx, c.timeout_s);
  Response resp;
  const grpc::Status s = (stub.*call)(&ctx, req, &resp);
  if (!s.ok()) return Fail(s);
  print(resp);
  return 0;
}

// grpc.health.v1.Health/Check through the generic stub: the request is
// {1: service (string)}, the response {1: status (enum, 1 = SERVING)}.
// wait_s > 0: waits up to wait_s for a server that is still starting (the
// call is queued until the channel connects) instead of failing at once.
int Health(const Common& c, const std::shared_ptr<grpc::Channel>& channel, const std::string& service,
           double wait_s) {
  grpc::GenericStub generic(channel);
  grpc::ClientContext ctx;
  Prepare(c, &ctx, wait_s > 0 ? wait_s : c.timeout_s);
  if (wait_s > 0) ctx.set_wait_for_ready(true);
  std::string req_bytes;
  if (!service.empty()) {
    req_bytes.push_back(0x0a);
    req_bytes.push_back(static_cast<char>(service.size()));
    req_bytes += service;
  }
  grpc::Slice slice(req_bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::promise<grpc::Status> done;
  generic.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                    [&done](grpc::Status st) { done.set_value(st); });
  const grpc::Status s = done.get_future().get();
  if (!s.ok()) return Fail(s);
  std::vector<grpc::Slice> slices;
  (void)response.Dump(&slices);
  std::string resp_bytes;
  for (const auto& sl : slices) resp_bytes.append(reinterpret_cast<const char*>(sl.begin()), sl.size());
  const int status = resp_bytes.size() >= 2 && resp_bytes[0] == 0x08 ? resp_bytes[1] : 0;
  const bool serving = status == 1;
  std::cout << (serving ? "SERVING" : status == 2 ? "NOT_SERVING" : "UNKNOWN") << "\n";
  return serving ? 0 : 3;
}

// Streams a session's poses into the chosen format until the stream ends,
// --max poses, or SIGINT/SIGTERM. MCAP: the Foxglove bridge's channels in
// one indexed file, closed (summary and footer written) also on a signal;
// ros2-mcap likewise, as a ROS 2 bag (camera mount: the KITTI 2011_09_26 rig).
int Subscribe(const Common& c, v1::Localization::Stub& stub, const SubscribeOptions& o) {
  // Usage first: it needs no server.
  if ((o.format == "mcap" || o.format == "ros2-mcap") && o.out_path.empty())
    throw std::runtime_error("--out is required for --format " + o.format);
  {  // An unknown id fails here, before a record file exists.
    grpc::ClientContext ctx;
    Prepare(c, &ctx, c.timeout_s);
    v1::GetSessionRequest get;
    get.set_session_id(o.session_id);
    v1::Session session;
    if (const grpc::Status s = stub.GetSession(&ctx, get, &session); !s.ok()) return Fail(s);
  }
  std::optional<Recorder> recorder;
  std::unique_ptr<locaid::output::McapRecording> mcap;
  std::unique_ptr<locaid::output::Ros2Recording> bag;
  if (o.format == "mcap") {
    mcap = std::make_unique<locaid::output::McapRecording>(o.out_path);
  } else if (o.format == "ros2-mcap") {
    bag = std::make_unique<locaid::output::Ros2Recording>(
        o.out_path, locaid::output::Ros2RecordingOptions{{}, locaid::output::KittiRigTBodyCam0()});
  } else {
    recorder.emplace(o.format, o.out_path);
  }
  v1::StreamPosesRequest req;
  req.set_session_id(o.session_id);
  req.set_from_start(o.from_start);
  req.set_queue_size(o.queue);
  req.set_smoothing_lag_s(o.lag_s);
  g_stream_ctx = std::make_unique<grpc::ClientContext>();
  Prepare(c, g_stream_ctx.get(), o.stream_timeout_s);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  auto reader = stub.StreamPoses(g_stream_ctx.get(), req);
  v1::PoseUpdate pose;
  uint64_t n = 0, dropped = 0;
  while (reader->Read(&pose)) {
    const auto now_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    const double delay_ms = static_cast<double>(now_ns - pose.published_unix_ns()) * 1e-6;
    try {
      if (mcap) {
        mcap->Add(pose);
      } else if (bag) {
        bag->Add(pose);
      } else {
        recorder->Add(pose, delay_ms);
      }
    } catch (const std::runtime_error& e) {  // RecordError, or McapWriter's std::system_error
      g_stream_ctx->TryCancel();
      (void)reader->Finish();
      std::cerr << "error: " << e.what() << "\n";
      return 4;
    }
    ++n;
    dropped = pose.dropped_for_subscriber();
    if (o.progress && n % 50 == 0) {
      std::cerr << "received " << n << " poses (seq " << pose.sequence() << ", dropped " << dropped << ", mode "
                << ModeName(pose.mode()) << ")\n";
    }
    if (o.max_poses > 0 && n >= o.max_poses) {
      g_stream_ctx->TryCancel();
      break;
    }
  }
  const grpc::Status s = reader->Finish();
  try {
    if (mcap) {
      mcap->Close();
    } else if (bag) {
      bag->Close();
    } else {
      recorder->Close();
    }
  } catch (const std::runtime_error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 4;
  }
  if (o.progress || o.format != "print") std::cerr << "received " << n << " poses, dropped " << dropped << "\n";
  if (o.max_poses > 0 && n >= o.max_poses) return 0;
  if (!s.ok() && s.error_code() != grpc::CANCELLED) {
    // Nothing came (the session went away meanwhile): no empty record left.
    if (n == 0 && !o.out_path.empty()) std::filesystem::remove(o.out_path);
    return Fail(s);
  }
  return 0;
}

// The command line: the options every command shares, each command's
// subcommand (parsed() says which ran) and what its options fill.
struct Commands {
  Common common;
  CLI::App* health = nullptr;
  std::string health_service;
  double health_wait_s = 0;
  CLI::App *start = nullptr, *list = nullptr, *get = nullptr, *stop = nullptr;
  StartOptions start_options;
  std::string session_id;  // every command on one session
  bool remove = false;
  CLI::App* subscribe = nullptr;
  SubscribeOptions sub;
  CLI::App *outage = nullptr, *outage_start = nullptr, *outage_stop = nullptr;
  double outage_start_s = 0, outage_duration_s = 0;
  CameraFaultCommand camera_fault;
  CLI::App* scenario = nullptr;
  std::string scenario_name, scenario_file;
  CLI::App* stats = nullptr;
};

void AddCommands(CLI::App& app, Commands& c) {
  Common& common = c.common;
  app.require_subcommand(1);
  app.add_option("--server", common.server,
                 "host:port, or unix:PATH for the server's --listen-unix socket (unix:/abs/path, unix:rel/path)")
      ->capture_default_str();
  app.add_option("--token", common.token, "bearer token");
  app.add_option("--token-file", common.token_file, "file holding the bearer token (keeps it out of argv)");
  app.add_option("--tls-ca", common.tls_ca, "PEM file of the CA (or self-signed cert) to trust; enables TLS");
  app.add_option("--timeout-s", common.timeout_s, "deadline of unary calls, seconds")->capture_default_str();

  c.health = app.add_subcommand("health", "grpc.health.v1 check: prints SERVING / NOT_SERVING");
  c.health->add_option("--service", c.health_service, "service name (empty = whole server)");
  c.health->add_option("--wait", c.health_wait_s, "wait up to this many seconds for a server that is still starting")
      ->check(CLI::Range(0.0, 3600.0));

  auto* session = app.add_subcommand("session", "start, list, get or stop sessions");
  session->require_subcommand(1);
  c.start = session->add_subcommand("start", "start a session; prints its id");
  AddStartOptions(*c.start, c.start_options);
  c.list = session->add_subcommand("list", "list sessions");
  c.get = session->add_subcommand("get", "show one session");
  c.stop = session->add_subcommand("stop", "stop a session");
  c.get->add_option("id", c.session_id)->required();
  c.stop->add_option("id", c.session_id)->required();
  c.stop->add_flag("--remove", c.remove, "also forget it");

  c.subscribe = app.add_subcommand("subscribe", "stream a session's poses");
  SubscribeOptions& sub = c.sub;
  c.subscribe->add_option("id", sub.session_id)->required();
  c.subscribe->add_flag("--from-start", sub.from_start, "begin with the session's history");
  c.subscribe->add_option("--format", sub.format,
                          "print|tum|kitti|csv|geojson|mcap (Foxglove channels)|ros2-mcap (ROS 2 bag); see docs/api.md")
      ->check(CLI::IsMember({"print", "tum", "kitti", "csv", "geojson", "mcap", "ros2-mcap"}))
      ->capture_default_str();
  c.subscribe->add_option("--out", sub.out_path, "record file (formats other than print)");
  c.subscribe->add_option("--max", sub.max_poses, "stop after N poses (0 = until the stream ends)");
  c.subscribe->add_option("--queue", sub.queue, "server-side queue length for this subscriber");
  c.subscribe->add_option("--lag", sub.lag_s,
                          "smoothed poses: each frame's pose given everything up to S seconds (sensor time) later, "
                          "sent once the session is S s past it (0 = the causal stream; docs/api.md \"Lagged stream\")")
      ->check(CLI::Range(0.0, 30.0));
  c.subscribe->add_flag("--progress", sub.progress, "print progress to stderr");
  c.subscribe->add_option("--stream-timeout-s", sub.stream_timeout_s, "deadline of the stream")->capture_default_str();

  c.outage = app.add_subcommand("outage", "inject GPS outages into a running session");
  c.outage->require_subcommand(1);
  c.outage_start = c.outage->add_subcommand("start", "GPS dropout from now");
  c.outage_start->add_option("id", c.session_id)->required();
  c.outage_start->add_option("--duration", c.outage_duration_s, "seconds of sensor time (0 = until 'outage stop')");
  c.outage_stop = c.outage->add_subcommand("stop", "end injected dropouts now");
  c.outage_stop->add_option("id", c.session_id)->required();
  auto* window = c.outage->add_subcommand("window", "dropout in [start, start+duration) since the first frame");
  window->add_option("id", c.session_id)->required();
  window->add_option("--start", c.outage_start_s, "seconds since the first frame")->required();
  window->add_option("--duration", c.outage_duration_s, "seconds")->required();

  c.camera_fault = AddCameraFaultCommand(app, c.session_id);

  c.scenario = app.add_subcommand("scenario", "change a running session's GPS scenario");
  c.scenario->add_option("id", c.session_id)->required();
  auto* sc_name = c.scenario->add_option("--name", c.scenario_name, "built-in scenario (or a .yaml/.yml file)");
  auto* sc_file = c.scenario->add_option("--file", c.scenario_file, "scenario YAML file");
  sc_name->excludes(sc_file);

  c.stats = app.add_subcommand("stats", "session statistics");
  c.stats->add_option("id", c.session_id)->required();
}

// Runs the parsed command against the server; its exit status (see Fail).
int Run(const Commands& c) {
  const Common& common = c.common;
  auto channel = locaid::connection::MakeChannel(common);
  auto stub = v1::Localization::NewStub(channel);
  auto with_id = [&c](auto req) {
    req.set_session_id(c.session_id);
    return req;
  };
  if (c.health->parsed()) return Health(common, channel, c.health_service, c.health_wait_s);
  if (c.start->parsed()) {
    return Unary(common, *stub, &v1::Localization::Stub::StartSession, StartSessionRequest(c.start_options),
                 [](const v1::Session& s) { std::cout << s.id() << "\n"; });
  }
  if (c.subscribe->parsed()) return Subscribe(common, *stub, c.sub);
  if (c.list->parsed()) {
    return Unary(common, *stub, &v1::Localization::Stub::ListSessions, v1::ListSessionsRequest{},
                 [](const v1::ListSessionsResponse& r) {
                   for (const auto& s : r.sessions()) PrintSession(s);
                 });
  }
  if (c.get->parsed()) {
    return Unary(common, *stub, &v1::Localization::Stub::GetSession, with_id(v1::GetSessionRequest{}), PrintSession);
  }
  if (c.stop->parsed()) {
    v1::StopSessionRequest req = with_id(v1::StopSessionRequest{});
    req.set_remove(c.remove);
    return Unary(common, *stub, &v1::Localization::Stub::StopSession, req, PrintSession);
  }
  if (c.stats->parsed()) {
    return Unary(common, *stub, &v1::Localization::Stub::GetStats, with_id(v1::GetStatsRequest{}), PrintStats);
  }
  if (c.outage->parsed()) {
    v1::InjectOutageRequest req = with_id(v1::InjectOutageRequest{});
    req.set_start_s(c.outage_start_s);
    req.set_duration_s(c.outage_duration_s);
    req.set_action(c.outage_start->parsed()  ? v1::InjectOutageRequest::START_NOW
                   : c.outage_stop->parsed() ? v1::InjectOutageRequest::STOP_NOW
                                             : v1::InjectOutageRequest::WINDOW);
    return Unary(common, *stub, &v1::Localization::Stub::InjectOutage, req, PrintSession);
  }
  const CameraFaultCommand& cam = c.camera_fault;
  if (cam.command->parsed()) {
    v1::InjectCameraFaultRequest req = with_id(v1::InjectCameraFaultRequest{});
    req.set_action(cam.start->parsed()  ? v1::InjectCameraFaultRequest::START_NOW
                   : cam.stop->parsed() ? v1::InjectCameraFaultRequest::STOP_NOW
                                        : v1::InjectCameraFaultRequest::WINDOW);
    if (!cam.stop->parsed()) *req.mutable_fault() = CameraFaultMessage(*cam.args);
    return Unary(common, *stub, &v1::Localization::Stub::InjectCameraFault, req, PrintSession);
  }
  if (c.scenario->parsed()) {
    v1::SetScenarioRequest req = with_id(v1::SetScenarioRequest{});
    FillScenario(c.scenario_name, c.scenario_file, req.mutable_scenario());
    return Unary(common, *stub, &v1::Localization::Stub::SetScenario, req, PrintSession);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locaid: client of locaid-server"};
  Commands commands;  // the parser fills it: it stays where it is
  AddCommands(app, commands);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help / --version exit 0; every usage error exits 2 (not CLI11's own codes).
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (const std::string why = CheckServerAddress(commands.common.server); !why.empty()) {
    std::cerr << "error: --server '" << commands.common.server << "': " << why << "\n";
    return 2;
  }
  // A file size limit (RLIMIT_FSIZE) must show up as EFBIG from write(2),
  // handled like a full disk, not kill the recorder.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    locaid::connection::ResolveToken(commands.common);
    return Run(commands);
  } catch (const RecordError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 4;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  }
}
