// Helpers for the server integration tests: an in-process server on a loopback
// port with a deterministic estimator, subprocess runner for the real CLI,
// and a push client. Fault tests add: child processes (fork + exec, with an
// optional file size limit), the real locaid-server as a process, a thread
// that collects a pose stream, a check for non-finite pose fields and a
// synthetic drive rendered by locaid-synth.
#pragma once

#include "locaid/v1/localization.grpc.pb.h"
#include "server/server.hpp"
#include "temp_dir.hpp"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <utility>
#include <vector>

namespace locaid::server::testing {

namespace v1 = locaid::v1;

// Which sanitizer this build has (gcc defines __SANITIZE_*__, clang answers
// __has_feature).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kUnderAddressSanitizer = true;
#elif defined(__has_feature)
inline constexpr bool kUnderAddressSanitizer = __has_feature(address_sanitizer);
#else
inline constexpr bool kUnderAddressSanitizer = false;
#endif
#if defined(__SANITIZE_THREAD__)
inline constexpr bool kUnderThreadSanitizer = true;
#elif defined(__has_feature)
inline constexpr bool kUnderThreadSanitizer = __has_feature(thread_sanitizer);
#else
inline constexpr bool kUnderThreadSanitizer = false;
#endif
// How many times slower a sanitizer build runs the server and its clients.
// Hang bounds, and the sensor time a test needs to stay running, are
// stretched by it; it is never used to check a speed.
inline constexpr int kSanitizerSlowdown = kUnderThreadSanitizer ? 10 : kUnderAddressSanitizer ? 3 : 1;
using locaid::test_support::ScopedTempDir;

// Moves 1 m east per frame. Mode: GPS_FUSED while a fix came within the
// last second of sensor time, else VO_ONLY (the scenario stage, not the
// estimator, decides whether GPS is out). Counts the fixes it was given as
// "GPS used" (a recorded drive's OXTS reaches it as the scenario's fixes), so
// tests can see that samples reached it; each fix rides on the next pose.
class FakeEstimator : public pipeline::Estimator {
 public:
  // fail_at >= 0: Process() throws on that frame (0-based), so the session fails.
  explicit FakeEstimator(int fail_at = -1) : fail_at_(fail_at) {}
  void Fuse(const pipeline::Measurements& m) override {
    for (const auto& f : m.gps) {
      ++gps_used_;
      last_fix_ns_ = f.t_ns;
      pipeline::GpsFeed feed;
      feed.fix = f;
      feed.update.used = true;
      feed.update.nis = 1.0;
      feed.update.gate = 9.21;
      feeds_.push_back(feed);
    }
  }
  pipeline::FrameResult Process(const vo::StereoFrame& frame) override {
    if (frames_ == fail_at_) throw std::runtime_error("fake estimator failed at frame " + std::to_string(frames_));
    pipeline::FrameResult e;
    e.pose.t_ns = frame.t_ns;
    e.pose.T_enu_body.translation() = Eigen::Vector3d(static_cast<double>(frames_++), 0, 0);
    e.pose.lat_deg = 49.0;
    e.pose.lon_deg = 8.4;
    e.pose.gps_used = gps_used_;
    const bool recent = last_fix_ns_ && frame.t_ns - *last_fix_ns_ <= 1'000'000'000;
    e.pose.mode = recent ? fusion::Mode::kGpsFused : fusion::Mode::kVoOnly;
    e.pose.seconds_since_gps = recent ? 0.0 : 1.0;
    e.vo.inliers = 100;
    e.vo.status = vo::Status::kOk;
    e.gps_feeds = std::exchange(feeds_, {});
    return e;
  }
  const fusion::EnuFrame& enu() const override { return enu_; }  // never has an origin

 private:
  int fail_at_ = -1;
  int frames_ = 0;
  int gps_used_ = 0;
  std::optional<int64_t> last_fix_ns_;
  std::vector<pipeline::GpsFeed> feeds_;
  fusion::EnuFrame enu_;
};

// VO method "fake-fail-at-3" gives an estimator that throws on frame 3.
inline pipeline::EstimatorMaker FakeFactory() {
  return [](const pipeline::EstimatorInputs& in) -> std::unique_ptr<pipeline::Estimator> {
    const std::string& vo_method = in.localizer.vo_method;
    if (vo_method == "fake-fail-at-3") return std::make_unique<FakeEstimator>(3);
    if (vo_method != "default" && vo_method != "thesis") {
      throw std::invalid_argument("unknown VO method '" + vo_method + "'");
    }
    return std::make_unique<FakeEstimator>();
  };
}

// `work_dir`: the test's own folder (synthetic drives; the default is shared
// by every server of the user, and a starting server clears it).
inline ServerConfig LoopbackConfig(const std::filesystem::path& work_dir) {
  ServerConfig c;
  c.listen = "127.0.0.1:0";
  c.work_dir = work_dir.string();
  c.shutdown_grace_s = 0.5;
  return c;
}

struct CliResult {
  int exit_code = -1;
  std::string out, err;
};

inline std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The values of one column of a CSV record (`locaid subscribe --format csv`),
// found by its name in the header, one per data line; empty when the
// header has no such column.
inline std::vector<std::string> CsvColumn(const std::string& text, const std::string& name) {
  std::istringstream in(text);
  std::string line, cell;
  std::getline(in, line);
  std::istringstream header(line);
  size_t column = 0;
  while (std::getline(header, cell, ',') && cell != name) ++column;
  if (cell != name) return {};
  std::vector<std::string> values;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string value;
    for (size_t i = 0; i <= column; ++i) {
      if (!std::getline(fields, value, ',')) {
        value.clear();  // a short line: no value
        break;
      }
    }
    values.push_back(value);
  }
  return values;
}

inline std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs a command line (already quoted), capturing stdout and stderr (through
// files in a folder of the call's own).
inline CliResult RunShell(const std::string& command) {
  const ScopedTempDir dir("cli");
  const auto out = dir / "out", err = dir / "err";
  const int rc = std::system((command + " >" + out.string() + " 2>" + err.string()).c_str());
  CliResult r;
  r.exit_code = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  return r;
}

// The real CLI against any --server target (host:port or unix:PATH).
inline CliResult RunCliAt(const std::string& target, const std::vector<std::string>& args,
                          const std::vector<std::string>& pre = {}) {
  std::string cmd = ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid") + " --server " + ShellQuote(target);
  for (const auto& a : pre) cmd.append(" ").append(ShellQuote(a));
  for (const auto& a : args) cmd.append(" ").append(ShellQuote(a));
  return RunShell(cmd);
}

inline CliResult RunCli(int port, const std::vector<std::string>& args, const std::vector<std::string>& pre = {}) {
  return RunCliAt("127.0.0.1:" + std::to_string(port), args, pre);
}

inline std::shared_ptr<grpc::Channel> MakeChannel(int port) {
  return grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
}
inline std::unique_ptr<v1::Localization::Stub> MakeStub(int port) { return v1::Localization::NewStub(MakeChannel(port)); }

inline void SetDeadline(grpc::ClientContext* ctx, double seconds = 30) {
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
}

// Unary GetStats / GetSession of one session with a 10 s deadline.
inline grpc::Status FetchStats(v1::Localization::Stub* stub, const std::string& id, v1::SessionStats* out) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 10);
  v1::GetStatsRequest req;
  req.set_session_id(id);
  return stub->GetStats(&ctx, req, out);
}
inline grpc::Status FetchSession(v1::Localization::Stub* stub, const std::string& id, v1::Session* out) {
  grpc::ClientContext ctx;
  SetDeadline(&ctx, 10);
  v1::GetSessionRequest req;
  req.set_session_id(id);
  return stub->GetSession(&ctx, req, out);
}

// The same, with a test failure (not a status) when the call fails.
inline v1::SessionStats GetStats(v1::Localization::Stub* stub, const std::string& id) {
  v1::SessionStats stats;
  const grpc::Status s = FetchStats(stub, id, &stats);
  EXPECT_TRUE(s.ok()) << s.error_message();
  return stats;
}
inline v1::Session GetSession(v1::Localization::Stub* stub, const std::string& id) {
  v1::Session session;
  const grpc::Status s = FetchSession(stub, id, &session);
  EXPECT_TRUE(s.ok()) << s.error_message();
  return session;
}

// Waits (bounded) until `pred(stats)` holds; returns the last stats seen.
template <typename Pred>
v1::SessionStats WaitStats(v1::Localization::Stub* stub, const std::string& id, double timeout_s, Pred pred) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  v1::SessionStats s = GetStats(stub, id);
  while (!pred(s) && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    s = GetStats(stub, id);
  }
  return s;
}

inline v1::LiveSource SmallCamera(int w = 32, int h = 24) {
  v1::LiveSource l;
  l.set_fx(30);
  l.set_fy(30);
  l.set_cx(w / 2.0);
  l.set_cy(h / 2.0);
  l.set_baseline_m(0.5);
  l.set_width(w);
  l.set_height(h);
  return l;
}

inline v1::PushRequest Gray8Frame(int64_t t_ns, int w = 32, int h = 24) {
  v1::PushRequest r;
  auto* f = r.mutable_frame();
  f->set_t_ns(t_ns);
  f->set_encoding(v1::IMAGE_ENCODING_GRAY8);
  std::string img(static_cast<size_t>(w * h), '\0');
  for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<char>((i * 7 + static_cast<size_t>(t_ns / 1000000)) & 0xff);
  f->set_left(img);
  f->set_right(img);
  return r;
}

inline std::string OxtsLine(double lat = 49.0, double lon = 8.4) {
  std::ostringstream s;
  s.precision(10);
  s << lat << " " << lon << " 110 0 0 0.5 5 0 5 0 0 0 0 9.81 0 0 9.81 0 0 0 0 0 0 0.1 0.1 4 10 5 5 5";
  return s.str();
}

inline v1::PushRequest Oxts(int64_t t_ns, const std::string& line) {
  v1::PushRequest r;
  r.mutable_oxts()->set_t_ns(t_ns);
  r.mutable_oxts()->set_line(line);
  return r;
}

// ------------------------------------------------------ fault-test helpers --

// A child process (fork + exec) with stdout and stderr in files; killed
// (SIGKILL) and reaped by the destructor if still running.
class ChildProcess {
 public:
  struct Options {
    std::filesystem::path out = "/dev/null", err = "/dev/null";
    // RLIMIT_FSIZE of the child, bytes (0 = unlimited). SIGXFSZ is left at
    // its default action, so a child that does not ignore it dies of it.
    rlim_t file_size_limit = 0;
  };

  ChildProcess(const std::vector<std::string>& argv, const Options& options) {
    // Everything the child needs is prepared before fork (the test process
    // has gRPC threads; the child only makes async-signal-safe calls).
    std::vector<std::string> args = argv;
    std::vector<char*> cargv;
    for (auto& a : args) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    const std::string out = options.out.string(), err = options.err.string();
    const rlim_t limit = options.file_size_limit;
    pid_ = ::fork();
    if (pid_ == 0) {
      if (limit > 0) {
        const rlimit rl{limit, limit};
        if (::setrlimit(RLIMIT_FSIZE, &rl) != 0) ::_exit(126);
      }
      ::signal(SIGXFSZ, SIG_DFL);
      const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (o < 0 || e < 0) ::_exit(126);
      ::dup2(o, 1);
      ::dup2(e, 2);
      ::execv(cargv[0], cargv.data());
      ::_exit(127);
    }
  }
  ~ChildProcess() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      Wait(10);
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  bool started() const { return pid_ > 0; }
  bool running() const { return pid_ > 0 && !reaped_; }
  bool Signal(int sig) const { return running() && ::kill(pid_, sig) == 0; }
  // Waits (bounded) for the child to end; true once it has been reaped.
  bool Wait(double timeout_s) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (running()) {
      const pid_t r = ::waitpid(pid_, &status_, WNOHANG);
      if (r == pid_ || (r < 0 && errno == ECHILD)) {
        reaped_ = true;
        break;
      }
      if (std::chrono::steady_clock::now() >= until) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return true;
  }
  // After Wait(): exit code, or -1 if it was killed by a signal.
  int exit_code() const { return reaped_ && WIFEXITED(status_) ? WEXITSTATUS(status_) : -1; }
  int term_signal() const { return reaped_ && WIFSIGNALED(status_) ? WTERMSIG(status_) : 0; }

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  bool reaped_ = false;
};

// VmRSS of a process from /proc/PID/status, kB (-1 if it cannot be read).
inline long VmRssKb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::strtol(line.c_str() + 6, nullptr, 10);
  }
  return -1;
}

// The real build/bin/locaid-server on 127.0.0.1, port picked by the OS and
// read from --port-file. `dir` holds the port file and the server's log.
class ServerProcess {
 public:
  // `port` 0: the OS picks one (see port()).
  explicit ServerProcess(const std::filesystem::path& dir, const std::vector<std::string>& extra_args = {},
                         int port = 0) {
    std::filesystem::create_directories(dir);
    const auto port_file = dir / "port";
    std::filesystem::remove(port_file);
    std::vector<std::string> argv = {std::string(LOCAID_BIN_DIR) + "/locaid-server", "--listen",
                                     "127.0.0.1:" + std::to_string(port),
                                     "--port-file", port_file.string(), "--work-dir", (dir / "work").string()};
    argv.insert(argv.end(), extra_args.begin(), extra_args.end());
    log_out_ = dir / "server.out";
    log_err_ = dir / "server.err";
    child_ = std::make_unique<ChildProcess>(argv, ChildProcess::Options{log_out_, log_err_, 0});
    for (int i = 0; i < 1000 && port_ == 0 && child_->running(); ++i) {  // at most 10 s
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      std::ifstream in(port_file);
      in >> port_;
      if (child_->Wait(0)) break;
    }
  }
  int port() const { return port_; }
  ChildProcess& process() { return *child_; }
  std::string log() const { return Slurp(log_out_) + Slurp(log_err_); }
  std::shared_ptr<grpc::Channel> NewChannel(int tag = 0) const {
    // A distinct argument gives each tag its own connection.
    grpc::ChannelArguments args;
    args.SetInt("locaid.test.channel_tag", tag);
    return grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port_), grpc::InsecureChannelCredentials(),
                                     args);
  }

 private:
  std::unique_ptr<ChildProcess> child_;
  std::filesystem::path log_out_, log_err_;
  int port_ = 0;
};

// argv of the real CLI against 127.0.0.1:port.
inline std::vector<std::string> CliArgv(int port, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {std::string(LOCAID_BIN_DIR) + "/locaid", "--server",
                                   "127.0.0.1:" + std::to_string(port)};
  argv.insert(argv.end(), args.begin(), args.end());
  return argv;
}

// One StreamPoses call read on its own thread until the stream ends.
class PoseCollector {
 public:
  PoseCollector(std::shared_ptr<grpc::Channel> channel, const std::string& session_id, bool from_start,
                double deadline_s = 120, uint32_t queue_size = 0)
      : PoseCollector(std::move(channel), Request(session_id, from_start, queue_size), deadline_s) {}
  // Any request (a smoothing lag, say); `on_pose` runs on the reading thread
  // after each pose is read, before it is kept (what it writes is safe to
  // read once the pose is in poses()).
  PoseCollector(std::shared_ptr<grpc::Channel> channel, v1::StreamPosesRequest request, double deadline_s,
                std::function<void(const v1::PoseUpdate&)> on_pose = {})
      : stub_(v1::Localization::NewStub(std::move(channel))), req_(std::move(request)) {
    SetDeadline(&ctx_, deadline_s);
    thread_ = std::thread([this, on_pose = std::move(on_pose)] {
      auto reader = stub_->StreamPoses(&ctx_, req_);
      v1::PoseUpdate p;
      while (reader->Read(&p)) {
        if (on_pose) on_pose(p);
        std::lock_guard lock(mu_);
        poses_.push_back(p);
        cv_.notify_all();
      }
      const grpc::Status s = reader->Finish();
      std::lock_guard lock(mu_);
      status_ = s;
      done_ = true;
      cv_.notify_all();
    });
  }
  ~PoseCollector() {
    if (thread_.joinable()) {
      ctx_.TryCancel();
      thread_.join();
    }
  }
  PoseCollector(const PoseCollector&) = delete;
  PoseCollector& operator=(const PoseCollector&) = delete;

  // Waits (bounded) for the stream to end; false on timeout.
  bool WaitDone(double timeout_s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [this] { return done_; });
  }
  bool WaitPoses(size_t n, double timeout_s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                        [&] { return poses_.size() >= n || done_; }) &&
           poses_.size() >= n;
  }
  bool done() {
    std::lock_guard lock(mu_);
    return done_;
  }
  grpc::Status status() {
    std::lock_guard lock(mu_);
    return status_;
  }
  std::vector<v1::PoseUpdate> poses() {
    std::lock_guard lock(mu_);
    return poses_;
  }
  size_t count() {
    std::lock_guard lock(mu_);
    return poses_.size();
  }

  static v1::StreamPosesRequest Request(const std::string& session_id, bool from_start, uint32_t queue_size = 0) {
    v1::StreamPosesRequest r;
    r.set_session_id(session_id);
    r.set_from_start(from_start);
    r.set_queue_size(queue_size);
    return r;
  }

 private:
  std::unique_ptr<v1::Localization::Stub> stub_;
  grpc::ClientContext ctx_;
  v1::StreamPosesRequest req_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<v1::PoseUpdate> poses_;
  grpc::Status status_;
  bool done_ = false;
};

// Names of the double/float fields of `m` (recursively, repeated ones with
// their index) that are NaN or infinite. PoseUpdate.seconds_since_gps may be
// +Infinity (documented: before the first accepted fix); pass it in `allow_inf`.
inline void NonFiniteFields(const google::protobuf::Message& m, const std::string& prefix,
                            const std::vector<std::string>& allow_inf, std::vector<std::string>* out) {
  using google::protobuf::FieldDescriptor;
  const auto* d = m.GetDescriptor();
  const auto* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const FieldDescriptor* f = d->field(i);
    const std::string name = prefix + f->name();
    auto check = [&](double v, const std::string& where) {
      if (std::isnan(v)) out->push_back(where + "=nan");
      else if (std::isinf(v) && !(v > 0 && std::find(allow_inf.begin(), allow_inf.end(), name) != allow_inf.end())) {
        out->push_back(where + "=" + (v > 0 ? "inf" : "-inf"));
      }
    };
    if (f->is_repeated()) {
      const int n = r->FieldSize(m, f);
      for (int k = 0; k < n; ++k) {
        const std::string where = name + "[" + std::to_string(k) + "]";
        if (f->cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE) check(r->GetRepeatedDouble(m, f, k), where);
        if (f->cpp_type() == FieldDescriptor::CPPTYPE_FLOAT) check(r->GetRepeatedFloat(m, f, k), where);
        if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
          NonFiniteFields(r->GetRepeatedMessage(m, f, k), where + ".", allow_inf, out);
        }
      }
    } else {
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE) check(r->GetDouble(m, f), name);
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_FLOAT) check(r->GetFloat(m, f), name);
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE && r->HasField(m, f)) {
        NonFiniteFields(r->GetMessage(m, f), name + ".", allow_inf, out);
      }
    }
  }
}

inline std::vector<std::string> NonFinitePoseFields(const v1::PoseUpdate& p) {
  std::vector<std::string> out;
  NonFiniteFields(p, "", {"seconds_since_gps"}, &out);
  return out;
}

// Renders a synthetic KITTI raw sync drive with build/bin/locaid-synth into
// `date_dir`; returns the drive folder (or "" with the error in *error).
inline std::filesystem::path RenderSynthDrive(const std::filesystem::path& date_dir, int frames, uint64_t seed,
                                              int width, int height, std::string* error) {
  std::filesystem::remove_all(date_dir);
  const CliResult r = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-synth") + " -q --out " +
                               ShellQuote(date_dir.string()) + " --frames " + std::to_string(frames) + " --seed " +
                               std::to_string(seed) + " --width " + std::to_string(width) + " --height " +
                               std::to_string(height));
  if (r.exit_code != 0) {
    *error = "locaid-synth failed (" + std::to_string(r.exit_code) + "): " + r.err;
    return {};
  }
  for (const auto& e : std::filesystem::directory_iterator(date_dir)) {
    if (e.is_directory() && e.path().filename().string().find("_sync") != std::string::npos) return e.path();
  }
  *error = "locaid-synth wrote no *_sync folder into " + date_dir.string();
  return {};
}

// A push stream attached to (or creating) a live session.
class Pusher {
 public:
  Pusher(v1::Localization::Stub* stub, const std::string& session_id, const v1::LiveSource& live = SmallCamera()) {
    SetDeadline(&ctx_, 60);
    stream_ = stub->PushSensorData(&ctx_);
    v1::PushRequest start;
    start.mutable_start()->set_session_id(session_id);
    *start.mutable_start()->mutable_live() = live;
    ok_ = stream_->Write(start);
    v1::PushResponse first;
    ok_ = ok_ && stream_->Read(&first) && first.has_session();
    session_ = first.session();
    reader_ = std::thread([this] {
      v1::PushResponse r;
      while (stream_->Read(&r)) {
        std::lock_guard lock(mu_);
        if (r.has_pose()) poses_.push_back(r.pose());
        if (r.has_rejected()) rejected_.push_back(r.rejected());
        cv_.notify_all();
      }
    });
  }
  ~Pusher() {
    if (reader_.joinable()) {
      ctx_.TryCancel();
      reader_.join();
    }
  }
  bool ok() const { return ok_; }
  const v1::Session& session() const { return session_; }
  bool Write(const v1::PushRequest& r) { return stream_->Write(r); }
  // Waits (bounded) until n poses arrived.
  bool WaitPoses(size_t n) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, std::chrono::seconds(30 * kSanitizerSlowdown), [&] { return poses_.size() >= n; });
  }
  // Waits (bounded) until the pose with this sequence number (or a later one)
  // arrived. Unlike WaitPoses it does not need every pose: this stream has the
  // server's default queue, and under load it may drop older poses.
  bool WaitSequence(uint64_t sequence) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, std::chrono::seconds(30 * kSanitizerSlowdown),
                        [&] { return !poses_.empty() && poses_.back().sequence() >= sequence; });
  }
  grpc::Status Close() {
    stream_->WritesDone();
    reader_.join();
    return stream_->Finish();
  }
  std::vector<v1::PoseUpdate> poses() {
    std::lock_guard lock(mu_);
    return poses_;
  }
  std::vector<v1::PushRejected> rejected() {
    std::lock_guard lock(mu_);
    return rejected_;
  }

 private:
  grpc::ClientContext ctx_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::PushRequest, v1::PushResponse>> stream_;
  bool ok_ = false;
  v1::Session session_;
  std::thread reader_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<v1::PoseUpdate> poses_;
  std::vector<v1::PushRejected> rejected_;
};

}  // namespace locaid::server::testing
