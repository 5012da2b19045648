// Streaming benchmark: one live session on an in-process server (127.0.0.1),
// frames pushed at --rate-hz through PushSensorData, a constant-cost estimator
// (so only the service is measured), N subscribers as callback clients over
// --channels connections, optionally one stalled subscriber that never reads.
// Prints per-run: delay from hub publish (after the EKF output) to client
// receipt (p50/p99/max), loss, session frame rate and process RSS.
#include "server/service.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

namespace v1 = locaid::v1;
using namespace locaid::server;

namespace {

class ConstantEstimator : public FrameEstimator {
 public:
  Estimate Process(const locaid::vo::StereoFrame& frame, std::span<const locaid::kitti::OxtsSample>) override {
    Estimate e;
    e.pose.t_ns = frame.t_ns;
    e.pose.T_enu_body.translation() = Eigen::Vector3d(static_cast<double>(n_++), 0, 0);
    e.pose.mode = locaid::fusion::Mode::kGpsFused;
    e.vo_status = locaid::vo::Status::kOk;
    return e;
  }
  void ScheduleOutage(int64_t, int64_t) override {}
  void StartOutageNow() override {}
  void StopOutageNow() override {}
  void SetScenario(const locaid::fusion::Scenario&) override {}
  bool origin(double*, double*, double*) const override { return false; }

 private:
  int n_ = 0;
};

int64_t NowNs() { return UnixNowNs(); }

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

class Subscriber : public grpc::ClientReadReactor<v1::PoseUpdate> {
 public:
  Subscriber(v1::Localization::Stub* stub, const std::string& id, uint32_t queue, bool stalled) : stalled_(stalled) {
    req_.set_session_id(id);
    req_.set_queue_size(queue);
    stub->async()->StreamPoses(&ctx_, &req_, this);
    if (!stalled_) StartRead(&msg_);
    StartCall();
  }
  void OnReadDone(bool ok) override {
    if (!ok) return;
    delays_us_.push_back(static_cast<float>((NowNs() - msg_.published_unix_ns()) * 1e-3));
    ++received_;
    last_dropped_ = msg_.dropped_for_subscriber();
    StartRead(&msg_);
  }
  void OnDone(const grpc::Status&) override {
    std::lock_guard lock(mu_);
    done_ = true;
    cv_.notify_all();
  }
  void Cancel() { ctx_.TryCancel(); }
  void Wait() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [this] { return done_; });
  }
  std::vector<float> delays_us_;
  uint64_t received_ = 0, last_dropped_ = 0;

 private:
  bool stalled_;
  grpc::ClientContext ctx_;
  v1::StreamPosesRequest req_;
  v1::PoseUpdate msg_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool done_ = false;
};

double Percentile(std::vector<float> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  int subscribers = 100, frames = 600, channels = 4;
  double rate_hz = 100;
  bool stalled = false;
  CLI::App app{"locaid streaming benchmark"};
  app.add_option("--subscribers", subscribers)->capture_default_str();
  app.add_option("--frames", frames)->capture_default_str();
  app.add_option("--rate-hz", rate_hz, "push rate (0 = as fast as possible)")->capture_default_str();
  app.add_option("--channels", channels, "client connections shared by the subscribers")->capture_default_str();
  app.add_flag("--stalled", stalled, "add one subscriber that never reads");
  CLI11_PARSE(app, argc, argv);

  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.max_subscribers_per_session = 100000;
  LocalizationServer server(config, [](const EstimatorSetup&) { return std::make_unique<ConstantEstimator>(); });
  const std::string target = "127.0.0.1:" + std::to_string(server.port());
  std::vector<std::unique_ptr<v1::Localization::Stub>> stubs;
  for (int c = 0; c < channels; ++c) {
    grpc::ChannelArguments args;
    args.SetInt("locaid.channel", c);  // distinct connections
    stubs.push_back(v1::Localization::NewStub(grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args)));
  }
  grpc::ChannelArguments stall_args;
  stall_args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1024);
  stall_args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  auto stall_stub = v1::Localization::NewStub(grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), stall_args));

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
  std::vector<std::unique_ptr<Subscriber>> subs;
  for (int i = 0; i < subscribers; ++i) {
    subs.push_back(std::make_unique<Subscriber>(stubs[static_cast<size_t>(i % channels)].get(), session.id(),
                                                static_cast<uint32_t>(frames), false));
  }
  std::unique_ptr<Subscriber> stall;
  if (stalled) stall = std::make_unique<Subscriber>(stall_stub.get(), session.id(), 64, true);
  for (int i = 0; i < 1000; ++i) {  // wait until all are attached
    grpc::ClientContext ctx;
    v1::GetStatsRequest req; req.set_session_id(session.id());
    v1::SessionStats st;
    stubs[0]->GetStats(&ctx, req, &st);
    if (st.subscribers() >= static_cast<uint32_t>(subscribers + (stalled ? 1 : 0))) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }

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
  v1::SessionStats st;
  {
    grpc::ClientContext ctx;
    v1::GetStatsRequest req; req.set_session_id(session.id());
    stubs[0]->GetStats(&ctx, req, &st);
  }
  const long rss_peak = RssKb();
  if (stall) stall->Cancel();
  for (auto& s : subs) s->Wait();
  if (stall) stall->Wait();

  std::vector<float> all;
  uint64_t lost = 0, received = 0;
  for (auto& s : subs) {
    all.insert(all.end(), s->delays_us_.begin(), s->delays_us_.end());
    received += s->received_;
    lost += static_cast<uint64_t>(frames) - s->received_;
  }
  uint64_t stalled_dropped = 0;
  for (const auto& sub : st.subscriber()) stalled_dropped = std::max<uint64_t>(stalled_dropped, sub.dropped());
  std::printf("subscribers=%d stalled=%d frames=%d rate_hz=%.0f channels=%d\n", subscribers, stalled ? 1 : 0, frames,
              rate_hz, channels);
  std::printf("delay_us p50=%.0f p99=%.0f max=%.0f  received=%llu lost=%llu  stalled_dropped=%llu\n",
              Percentile(all, 0.5), Percentile(all, 0.99), Percentile(all, 1.0),
              static_cast<unsigned long long>(received), static_cast<unsigned long long>(lost),
              static_cast<unsigned long long>(stalled_dropped));
  std::printf("session_fps=%.1f (frames %llu in %.2f s push)  rss_kb start=%ld end=%ld\n",
              static_cast<double>(st.frames_processed()) / push_s,
              static_cast<unsigned long long>(st.frames_processed()), push_s, rss_start, rss_peak);
  server.Shutdown();
  return lost == 0 ? 0 : 1;
}
