// Streaming benchmark: one live session on a server in this process
// (127.0.0.1), frames pushed at --rate-hz through PushSensorData, a
// constant-cost estimator (so only the service is measured), N subscribers as
// callback clients over --channels connections, optionally one stalled
// subscriber that never reads.
//
// By default the subscribers run in a CHILD process (this program re-executed
// with --client-of), so server and clients have separate gRPC stacks and
// threads as in production (the machine's cores are still shared); with
// --in-process they run in the server's process.
//
// With --unix the server also listens on a Unix-domain socket (a fresh
// folder under the temp directory) and the subscribers connect through it;
// the session setup, the push stream and the stats calls stay on TCP.
//
// Prints per-run: delay from hub publish (published_unix_ns, stamped after the
// EKF output) to client receipt wall time (p50/p99/max), loss, session frame
// rate, server RSS and the CPU time of the server and of the client process
// per published pose.
#include "bench/server/spawn_self.hpp"
#include "bench/server/subscriber.hpp"
#include "server/server.hpp"

#include <CLI/CLI.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

namespace v1 = locaid::v1;
using namespace locaid::server;

namespace {

class ConstantEstimator : public locaid::pipeline::Estimator {
 public:
  void Fuse(const locaid::pipeline::Measurements&) override {}
  locaid::pipeline::FrameResult Process(const locaid::vo::StereoFrame& frame) override {
    locaid::pipeline::FrameResult e;
    e.pose.t_ns = frame.t_ns;
    e.pose.T_enu_body.translation() = Eigen::Vector3d(static_cast<double>(n_++), 0, 0);
    e.pose.mode = locaid::fusion::Mode::kGpsFused;
    e.vo.status = locaid::vo::Status::kOk;
    return e;
  }
  const locaid::fusion::EnuFrame& enu() const override { return enu_; }

 private:
  int n_ = 0;
  locaid::fusion::EnuFrame enu_;  // never has an origin
};

long RssKb() {
  std::ifstream in("/proc/self/status");
  std::string key;
  long value = 0;
  while (in >> key) {
    if (key == "VmRSS:") {
      in >> value;
      return value;
    }
    in.ignore(1 << 12, '\n');
  }
  return -1;
}

double Percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

double CpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

std::vector<std::unique_ptr<v1::Localization::Stub>> MakeStubs(const std::string& target, int channels) {
  std::vector<std::unique_ptr<v1::Localization::Stub>> stubs;
  for (int c = 0; c < channels; ++c) {
    grpc::ChannelArguments args;
    args.SetInt("locaid.channel", c);  // distinct connections
    stubs.push_back(v1::Localization::NewStub(grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args)));
  }
  return stubs;
}

std::unique_ptr<v1::Localization::Stub> MakeStallStub(const std::string& target) {
  grpc::ChannelArguments stall_args;
  stall_args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1024);
  stall_args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  return v1::Localization::NewStub(grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), stall_args));
}

// `n` subscribers that read `frames` poses each, spread over the stubs' connections.
std::vector<std::unique_ptr<locaid::bench::Subscriber>> MakeSubscribers(const std::vector<std::unique_ptr<v1::Localization::Stub>>& stubs,
                                                         const std::string& session_id, int n, int frames) {
  std::vector<std::unique_ptr<locaid::bench::Subscriber>> subs;
  for (int i = 0; i < n; ++i) {
    subs.push_back(std::make_unique<locaid::bench::Subscriber>(stubs[static_cast<size_t>(i) % stubs.size()].get(), session_id,
                                                static_cast<uint32_t>(frames), false));
  }
  return subs;
}

// Result line of the subscribers (printed by the child, parsed by the parent).
struct ClientResult {
  double p50_us = 0, p99_us = 0, max_us = 0, cpu_s = 0;
  uint64_t received = 0, lost = 0;
};

ClientResult Summarize(const std::vector<std::unique_ptr<locaid::bench::Subscriber>>& subs, int frames, double cpu_s) {
  std::vector<float> all;
  ClientResult r;
  for (const auto& s : subs) {
    all.insert(all.end(), s->delays_us_.begin(), s->delays_us_.end());
    r.received += s->received_;
    r.lost += static_cast<uint64_t>(frames) - s->received_;
  }
  r.p50_us = Percentile(all, 0.5);
  r.p99_us = Percentile(all, 0.99);
  r.max_us = Percentile(all, 1.0);
  r.cpu_s = cpu_s;
  return r;
}

// Child mode: N subscribers (and the stalled one) on the server at `target`;
// the stalled one is cancelled when stdin reaches EOF (the parent is done
// pushing); prints one "result" line after every stream has ended.
int RunClients(const std::string& target, const std::string& session_id, int subscribers, int frames, int channels,
               bool stalled) {
  auto stubs = MakeStubs(target, channels);
  auto stall_stub = MakeStallStub(target);
  const double cpu0 = CpuSeconds();
  std::vector<std::unique_ptr<locaid::bench::Subscriber>> subs = MakeSubscribers(stubs, session_id, subscribers, frames);
  std::unique_ptr<locaid::bench::Subscriber> stall;
  if (stalled) stall = std::make_unique<locaid::bench::Subscriber>(stall_stub.get(), session_id, 64, true);
  if (stall) {
    std::string line;
    while (std::getline(std::cin, line)) {}
    stall->Cancel();
  }
  for (auto& s : subs) s->Wait();
  if (stall) stall->Wait();
  const ClientResult r = Summarize(subs, frames, CpuSeconds() - cpu0);
  std::printf("result %.0f %.0f %.0f %llu %llu %.3f\n", r.p50_us, r.p99_us, r.max_us,
              static_cast<unsigned long long>(r.received), static_cast<unsigned long long>(r.lost), r.cpu_s);
  std::fflush(stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int subscribers = 100, frames = 600, channels = 4;
  double rate_hz = 100;
  bool stalled = false, in_process = false, unix_socket = false;
  std::string client_of, client_session;
  CLI::App app{"locaid streaming benchmark"};
  app.add_option("--subscribers", subscribers)->capture_default_str();
  app.add_option("--frames", frames)->capture_default_str();
  app.add_option("--rate-hz", rate_hz, "push rate (0 = as fast as possible)")->capture_default_str();
  app.add_option("--channels", channels, "client connections shared by the subscribers")->capture_default_str();
  app.add_flag("--stalled", stalled, "add one subscriber that never reads");
  app.add_flag("--in-process", in_process, "run the subscribers in the server's process (default: a child process)");
  app.add_flag("--unix", unix_socket,
               "subscribers connect over a Unix-domain socket (server listens on both; push and stats stay on TCP)");
  app.add_option("--client-of", client_of, "internal: run only the subscribers against this server address");
  app.add_option("--client-session", client_session, "internal: session id for --client-of");
  CLI11_PARSE(app, argc, argv);
  channels = std::max(channels, 1);
  if (!client_of.empty()) return RunClients(client_of, client_session, subscribers, frames, channels, stalled);

  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.max_subscribers_per_session = 100000;
  const std::filesystem::path socket_dir =
      std::filesystem::temp_directory_path() / ("locaid-bench-uds-" + std::to_string(getpid()));
  struct RemoveDirAtExit {  // declared before the server, so removed after it has shut down
    std::filesystem::path dir;
    ~RemoveDirAtExit() {
      std::error_code ec;
      if (!dir.empty()) std::filesystem::remove_all(dir, ec);
    }
  } socket_dir_guard;
  if (unix_socket) {
    std::filesystem::remove_all(socket_dir);
    std::filesystem::create_directories(socket_dir);
    socket_dir_guard.dir = socket_dir;
    config.listen_unix = (socket_dir / "locaid.sock").string();
  }
  LocalizationServer server(config, [](const locaid::pipeline::EstimatorInputs&) { return std::make_unique<ConstantEstimator>(); });
  const std::string target = "127.0.0.1:" + std::to_string(server.port());
  const std::string sub_target = unix_socket ? server.unix_target() : target;
  // In-process TCP subscribers share the control stub's connection (channel 0), as before --unix existed.
  auto stubs = MakeStubs(target, in_process && !unix_socket ? channels : 1);
  std::vector<std::unique_ptr<v1::Localization::Stub>> unix_stubs;
  if (in_process && unix_socket) unix_stubs = MakeStubs(sub_target, channels);
  const auto& sub_stubs = unix_socket ? unix_stubs : stubs;

  // Session.
  v1::StartSessionRequest start;
  auto* live = start.mutable_live();
  live->set_fx(30); live->set_fy(30); live->set_cx(16); live->set_cy(12); live->set_baseline_m(0.5);
  live->set_width(32); live->set_height(24);
  v1::Session session;
  {
    grpc::ClientContext ctx;
    const grpc::Status s = stubs[0]->StartSession(&ctx, start, &session);
    if (!s.ok()) { std::cerr << s.error_message() << "\n"; return 1; }
  }
  const long rss_start = RssKb();
  std::vector<std::unique_ptr<locaid::bench::Subscriber>> subs;
  std::unique_ptr<v1::Localization::Stub> stall_stub;
  std::unique_ptr<locaid::bench::Subscriber> stall;
  locaid::bench::Child child;
  if (in_process) {
    subs = MakeSubscribers(sub_stubs, session.id(), subscribers, frames);
    stall_stub = MakeStallStub(sub_target);
    if (stalled) stall = std::make_unique<locaid::bench::Subscriber>(stall_stub.get(), session.id(), 64, true);
  } else {
    std::vector<std::string> args = {"locaid-bench-streaming", "--client-of", sub_target, "--client-session", session.id(),
                                     "--subscribers", std::to_string(subscribers), "--frames", std::to_string(frames),
                                     "--channels", std::to_string(channels)};
    if (stalled) args.push_back("--stalled");
    child = locaid::bench::SpawnSelf(args);
  }
  bool attached = false;
  for (int i = 0; i < 3000 && !attached; ++i) {  // wait until all are attached
    grpc::ClientContext ctx;
    v1::GetStatsRequest req; req.set_session_id(session.id());
    v1::SessionStats st;
    stubs[0]->GetStats(&ctx, req, &st);
    attached = st.subscribers() >= static_cast<uint32_t>(subscribers + (stalled ? 1 : 0));
    if (!attached) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (!attached) { std::cerr << "subscribers did not attach within 30 s\n"; return 1; }

  // Push.
  grpc::ClientContext push_ctx;
  auto push = stubs[0]->PushSensorData(&push_ctx);
  v1::PushRequest first;
  first.mutable_start()->set_session_id(session.id());
  push->Write(first);
  v1::PushResponse resp;
  push->Read(&resp);
  std::thread drain([&] { v1::PushResponse r; while (push->Read(&r)) {} });
  const std::string img(32 * 24, '\x40');
  const double cpu0 = CpuSeconds();
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < frames; ++i) {
    v1::PushRequest f;
    f.mutable_frame()->set_t_ns((i + 1) * 10'000'000LL);
    f.mutable_frame()->set_encoding(v1::IMAGE_ENCODING_GRAY8);
    f.mutable_frame()->set_left(img);
    f.mutable_frame()->set_right(img);
    push->Write(f);
    if (rate_hz > 0) std::this_thread::sleep_until(t0 + std::chrono::microseconds(static_cast<int64_t>((i + 1) * 1e6 / rate_hz)));
  }
  push->WritesDone();
  drain.join();
  push->Finish();
  const double push_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double server_cpu_s = CpuSeconds() - cpu0;  // includes the pushing client (one stream)
  v1::SessionStats st;
  {
    grpc::ClientContext ctx;
    v1::GetStatsRequest req; req.set_session_id(session.id());
    stubs[0]->GetStats(&ctx, req, &st);
  }
  const long rss_peak = RssKb();

  ClientResult r;
  if (in_process) {
    if (stall) stall->Cancel();
    for (auto& s : subs) s->Wait();
    if (stall) stall->Wait();
    r = Summarize(subs, frames, 0);
  } else {
    close(child.to_child);  // the child cancels its stalled subscriber
    const std::string out = locaid::bench::ReadAll(child.from_child);
    close(child.from_child);
    int status = 0;
    waitpid(child.pid, &status, 0);
    std::istringstream in(out.substr(std::min(out.size(), out.find("result"))));
    std::string tag;
    unsigned long long received = 0, lost = 0;
    if (!(in >> tag >> r.p50_us >> r.p99_us >> r.max_us >> received >> lost >> r.cpu_s) || tag != "result") {
      std::cerr << "client process failed (status " << status << "): " << out << "\n";
      return 1;
    }
    r.received = received;
    r.lost = lost;
  }
  uint64_t stalled_dropped = 0;
  for (const auto& sub : st.subscriber()) stalled_dropped = std::max<uint64_t>(stalled_dropped, sub.dropped());
  const double published = std::max<double>(1, static_cast<double>(st.frames_processed()));
  std::printf("subscribers=%d stalled=%d frames=%d rate_hz=%.0f channels=%d clients=%s transport=%s\n", subscribers,
              stalled ? 1 : 0, frames, rate_hz, channels, in_process ? "in-process" : "child-process",
              unix_socket ? "unix" : "tcp");
  std::printf("delay_us p50=%.0f p99=%.0f max=%.0f  received=%llu lost=%llu  stalled_dropped=%llu\n", r.p50_us,
              r.p99_us, r.max_us, static_cast<unsigned long long>(r.received),
              static_cast<unsigned long long>(r.lost), static_cast<unsigned long long>(stalled_dropped));
  std::printf("session_fps=%.1f (frames %llu in %.2f s push)  rss_kb start=%ld end=%ld\n",
              static_cast<double>(st.frames_processed()) / push_s,
              static_cast<unsigned long long>(st.frames_processed()), push_s, rss_start, rss_peak);
  if (in_process) {
    std::printf("cpu_us_per_pose process=%.0f (server + clients)\n", server_cpu_s * 1e6 / published);
  } else {
    std::printf("cpu_us_per_pose server=%.0f clients=%.0f\n", server_cpu_s * 1e6 / published,
                r.cpu_s * 1e6 / published);
  }
  server.Shutdown();
  return r.lost == 0 ? 0 : 1;
}
