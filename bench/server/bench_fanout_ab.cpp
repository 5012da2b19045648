// A/B experiment for the streaming delay target: does the gRPC API used for
// the pose streams matter? Two minimal servers fan one PoseUpdate per tick
// out to N StreamPoses streams on 127.0.0.1, with no session, hub or EKF:
//
//   --mode callback  the callback API (what locaid-server uses): two fan-out
//                    threads call StartWrite; OnWriteDone runs on gRPC's
//                    callback threads (gRPC 1.51 never runs it inline).
//   --mode async     the completion-queue API: two completion queues whose
//                    own polling threads do every write and handle every
//                    completion (a grpc::Alarm wakes them per tick), so no
//                    thread hand-off per write.
//
// The subscribers run in a child process (this program with --client-of) as
// in locaid-bench-streaming: N callback readers over 4 connections. A stream
// whose write is in flight keeps only the newest pose, as the hub does.
// Printed: delay from publish to receipt (p50/p99/max) over all messages
// after the first 20 of each stream (warm-up), and how many arrived.
#include "bench/server/spawn_self.hpp"
#include "bench/server/subscriber.hpp"
#include "locaid/v1/localization.grpc.pb.h"

#include <CLI/CLI.hpp>
#include <grpcpp/alarm.h>
#include <grpcpp/grpcpp.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace v1 = locaid::v1;

constexpr int kConnections = 4;
constexpr int kFanoutThreads = 2;  // callback: writer threads; async: completion queues
constexpr size_t kWarmupMessages = 20;

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// ------------------------------------------------------------ subscribers --


int RunClients(const std::string& target, int subscribers) {
  std::vector<std::unique_ptr<v1::Localization::Stub>> stubs;
  for (int c = 0; c < kConnections; ++c) {
    grpc::ChannelArguments args;
    args.SetInt("locaid.bench.connection", c);  // distinct connections
    stubs.push_back(v1::Localization::NewStub(
        grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args)));
  }
  std::vector<std::unique_ptr<locaid::bench::Subscriber>> readers;
  for (int i = 0; i < subscribers; ++i) readers.push_back(std::make_unique<locaid::bench::Subscriber>(stubs[static_cast<size_t>(i % kConnections)].get(), "", 0, false));
  std::vector<float> all;
  for (auto& r : readers) {
    r->Wait();
    if (r->delays_us_.size() > kWarmupMessages)
      all.insert(all.end(), r->delays_us_.begin() + kWarmupMessages, r->delays_us_.end());
  }
  if (all.empty()) {
    std::printf("result 0 0 0 0\n");
    return 1;
  }
  std::sort(all.begin(), all.end());
  std::printf("result %zu %.0f %.0f %.0f\n", all.size(), all[all.size() / 2], all[all.size() * 99 / 100],
              all.back());
  return 0;
}

// --------------------------------------------------------- callback mode --

class CallbackWriter : public grpc::ServerWriteReactor<v1::PoseUpdate> {
 public:
  explicit CallbackWriter(int messages) : left_(messages) {}
  // Writes p now, or after the write in flight (newest only).
  void Offer(const v1::PoseUpdate& p) {
    std::lock_guard lock(mu_);
    if (done_) return;
    if (writing_) {
      pending_ = p;
      return;
    }
    out_ = p;
    writing_ = true;
    StartWrite(&out_);
  }
  void OnWriteDone(bool ok) override {
    std::lock_guard lock(mu_);
    writing_ = false;
    if (!ok || cancelled_) {
      FinishLocked(grpc::Status::CANCELLED);
      return;
    }
    if (--left_ == 0) {
      FinishLocked(grpc::Status::OK);
      return;
    }
    if (pending_) {
      out_ = *pending_;
      pending_.reset();
      writing_ = true;
      StartWrite(&out_);
    }
  }
  // Server shutdown or client gone: finish now, or after the write in flight.
  void OnCancel() override {
    std::lock_guard lock(mu_);
    cancelled_ = true;
    if (!writing_) FinishLocked(grpc::Status::CANCELLED);
  }
  void OnDone() override {}

 private:
  void FinishLocked(const grpc::Status& status) {
    if (done_) return;
    done_ = true;
    Finish(status);
  }

  std::mutex mu_;
  bool writing_ = false, done_ = false, cancelled_ = false;
  std::optional<v1::PoseUpdate> pending_;
  v1::PoseUpdate out_;
  int left_;
};

class CallbackServer : public v1::Localization::CallbackService {
 public:
  explicit CallbackServer(int messages) : messages_(messages) {}
  grpc::ServerWriteReactor<v1::PoseUpdate>* StreamPoses(grpc::CallbackServerContext*,
                                                        const v1::StreamPosesRequest*) override {
    auto writer = std::make_unique<CallbackWriter>(messages_);
    std::lock_guard lock(mu_);
    writers_.push_back(std::move(writer));  // owned here until the end of the run
    return writers_.back().get();
  }
  size_t attached() {
    std::lock_guard lock(mu_);
    return writers_.size();
  }
  // Fan-out threads: worker w offers each published pose to writers w, w+n, ...
  void StartFanout() {
    for (int w = 0; w < kFanoutThreads; ++w) {
      threads_.emplace_back([this, w] {
        uint64_t seen = 0;
        for (;;) {
          v1::PoseUpdate p;
          {
            std::unique_lock lock(fan_mu_);
            fan_cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
            if (stop_) return;
            seen = generation_;
            p = latest_;
          }
          for (size_t i = static_cast<size_t>(w); i < writers_.size(); i += kFanoutThreads) writers_[i]->Offer(p);
        }
      });
    }
  }
  void Publish(const v1::PoseUpdate& p) {
    std::lock_guard lock(fan_mu_);
    latest_ = p;
    ++generation_;
    fan_cv_.notify_all();
  }
  void StopFanout() {
    {
      std::lock_guard lock(fan_mu_);
      stop_ = true;
      fan_cv_.notify_all();
    }
    for (auto& t : threads_) t.join();
  }

 private:
  const int messages_;
  std::mutex mu_;
  std::vector<std::unique_ptr<CallbackWriter>> writers_;
  std::vector<std::thread> threads_;
  std::mutex fan_mu_;
  std::condition_variable fan_cv_;
  v1::PoseUpdate latest_;
  uint64_t generation_ = 0;
  bool stop_ = false;
};

// ------------------------------------------------------------ async mode --

struct AsyncStream {
  explicit AsyncStream(int messages) : left(messages) {}
  grpc::ServerContext ctx;
  v1::StreamPosesRequest req;
  grpc::ServerAsyncWriter<v1::PoseUpdate> writer{&ctx};
  enum class State { kRequested, kIdle, kWriting, kFinishing } state = State::kRequested;
  std::optional<v1::PoseUpdate> pending;
  v1::PoseUpdate out;
  int left;
};

// Completion-queue tags: a stream's event, or the per-tick publish alarm.
struct Tag {
  AsyncStream* stream = nullptr;  // nullptr: publish
};

class AsyncServer {
 public:
  AsyncServer(grpc::ServerBuilder& builder, int messages, int subscribers)
      : messages_(messages), subscribers_(subscribers) {
    builder.RegisterService(&service_);
    for (int q = 0; q < kFanoutThreads; ++q) queues_.push_back(builder.AddCompletionQueue());
  }
  void Start() {
    streams_.resize(queues_.size());
    for (size_t q = 0; q < queues_.size(); ++q) threads_.emplace_back([this, q] { Poll(q); });
  }
  size_t attached() const { return attached_.load(); }
  void Publish(const v1::PoseUpdate& p) {
    {
      std::lock_guard lock(mu_);
      latest_ = p;
    }
    for (auto& q : queues_) {
      auto alarm = std::make_unique<grpc::Alarm>();
      alarm->Set(q.get(), gpr_now(GPR_CLOCK_MONOTONIC), new Tag{});
      alarms_.push_back(std::move(alarm));
    }
  }
  void Stop() {
    for (auto& q : queues_) q->Shutdown();
    for (auto& t : threads_) t.join();
    for (auto& per_queue : streams_)
      for (AsyncStream* s : per_queue) delete s;
  }

 private:
  void Write(AsyncStream* s, const v1::PoseUpdate& p) {
    if (s->state == AsyncStream::State::kWriting) {
      s->pending = p;
      return;
    }
    if (s->state != AsyncStream::State::kIdle) return;
    s->out = p;
    s->state = AsyncStream::State::kWriting;
    s->writer.Write(s->out, new Tag{s});
  }
  void Poll(size_t q) {
    grpc::ServerCompletionQueue* cq = queues_[q].get();
    for (int i = 0; i < subscribers_; ++i) {  // enough outstanding requests on each queue
      auto* s = new AsyncStream(messages_);
      service_.RequestStreamPoses(&s->ctx, &s->req, &s->writer, cq, cq, new Tag{s});
      pending_requests_[q].push_back(s);
    }
    void* raw = nullptr;
    bool ok = false;
    while (cq->Next(&raw, &ok)) {
      std::unique_ptr<Tag> tag(static_cast<Tag*>(raw));
      if (tag->stream == nullptr) {
        v1::PoseUpdate p;
        {
          std::lock_guard lock(mu_);
          p = latest_;
        }
        for (AsyncStream* s : streams_[q]) Write(s, p);
        continue;
      }
      AsyncStream* s = tag->stream;
      if (!ok) continue;
      switch (s->state) {
        case AsyncStream::State::kRequested:
          s->state = AsyncStream::State::kIdle;
          streams_[q].push_back(s);
          std::erase(pending_requests_[q], s);
          ++attached_;
          break;
        case AsyncStream::State::kWriting:
          s->state = AsyncStream::State::kIdle;
          if (--s->left == 0) {
            s->state = AsyncStream::State::kFinishing;
            s->writer.Finish(grpc::Status::OK, new Tag{s});
          } else if (s->pending) {
            const v1::PoseUpdate p = *s->pending;
            s->pending.reset();
            Write(s, p);
          }
          break;
        case AsyncStream::State::kIdle:
        case AsyncStream::State::kFinishing:
          break;
      }
    }
    for (AsyncStream* s : pending_requests_[q]) delete s;  // requests never matched
  }

  v1::Localization::AsyncService service_;
  const int messages_, subscribers_;
  std::vector<std::unique_ptr<grpc::ServerCompletionQueue>> queues_;
  std::vector<std::thread> threads_;
  std::vector<std::vector<AsyncStream*>> streams_;  // per queue, touched by its thread only
  std::vector<AsyncStream*> pending_requests_[kFanoutThreads];
  std::atomic<size_t> attached_{0};
  std::mutex mu_;
  v1::PoseUpdate latest_;
  std::vector<std::unique_ptr<grpc::Alarm>> alarms_;  // publisher thread only
};

// ------------------------------------------------------------------ main --

}  // namespace

int main(int argc, char** argv) {
  std::string mode = "callback", client_of;
  int subscribers = 100, messages = 600;
  double rate_hz = 100;
  CLI::App app{"gRPC fan-out A/B: callback API vs completion-queue API"};
  app.add_option("--mode", mode, "callback | async")->check(CLI::IsMember({"callback", "async"}))->capture_default_str();
  app.add_option("--subscribers", subscribers)->check(CLI::Range(1, 2000))->capture_default_str();
  app.add_option("--messages", messages, "messages per stream")->check(CLI::Range(kWarmupMessages + 1, size_t{100000}))->capture_default_str();
  app.add_option("--rate-hz", rate_hz)->check(CLI::Range(1.0, 10000.0))->capture_default_str();
  app.add_option("--client-of", client_of, "internal: run only the subscribers against this address");
  CLI11_PARSE(app, argc, argv);
  if (!client_of.empty()) return RunClients(client_of, subscribers);

  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  std::unique_ptr<CallbackServer> callback;
  std::unique_ptr<AsyncServer> async;
  if (mode == "callback") {
    callback = std::make_unique<CallbackServer>(messages);
    builder.RegisterService(callback.get());
  } else {
    async = std::make_unique<AsyncServer>(builder, messages, subscribers);
  }
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::fprintf(stderr, "server did not start\n");
    return 1;
  }
  if (async) async->Start();
  const std::string target = "127.0.0.1:" + std::to_string(port);
  locaid::bench::Child child = locaid::bench::SpawnSelf({"locaid-bench-fanout-ab", "--client-of", target, "--subscribers",
                              std::to_string(subscribers)});
  close(child.to_child);  // the subscribers take no input
  const auto attached = [&] { return callback ? callback->attached() : async->attached(); };
  for (int i = 0; i < 3000 && attached() < static_cast<size_t>(subscribers); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (attached() < static_cast<size_t>(subscribers)) {
    std::fprintf(stderr, "only %zu of %d subscribers attached within 30 s\n", attached(), subscribers);
    kill(child.pid, SIGKILL);
    waitpid(child.pid, nullptr, 0);
    return 1;
  }
  if (callback) callback->StartFanout();

  const auto t0 = std::chrono::steady_clock::now();
  for (int m = 0; m < messages; ++m) {
    std::this_thread::sleep_until(t0 + std::chrono::microseconds(static_cast<int64_t>((m + 1) * 1e6 / rate_hz)));
    v1::PoseUpdate p;  // a pose of the usual size: position, 36 covariance values
    p.set_session_id("ab");
    p.set_sequence(static_cast<uint64_t>(m));
    p.mutable_position_enu_m()->set_x(m);
    for (int k = 0; k < 36; ++k) p.add_covariance(0.1 * k);
    p.set_published_unix_ns(UnixNowNs());
    if (callback) callback->Publish(p);
    else async->Publish(p);
  }
  // A stream that skipped a message (newest-only) is still open: give the
  // rest a second to drain, then end every stream; the child reports after
  // its last stream ended.
  std::this_thread::sleep_for(std::chrono::seconds(1));
  if (callback) callback->StopFanout();
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  const std::string out = locaid::bench::ReadAll(child.from_child);
  close(child.from_child);
  int status = 0;
  waitpid(child.pid, &status, 0);
  if (async) async->Stop();

  size_t n = 0;
  double p50 = 0, p99 = 0, max = 0;
  if (std::sscanf(out.c_str(), "result %zu %lf %lf %lf", &n, &p50, &p99, &max) != 4 || n == 0) {
    std::fprintf(stderr, "client process failed (status %d): %s\n", status, out.c_str());
    return 1;
  }
  std::printf("mode=%s subscribers=%d messages=%d rate_hz=%.0f connections=%d\n", mode.c_str(), subscribers,
              messages, rate_hz, kConnections);
  std::printf("delay_us p50=%.0f p99=%.0f max=%.0f  (%zu messages after warm-up)\n", p50, p99, max, n);
  return 0;
}
