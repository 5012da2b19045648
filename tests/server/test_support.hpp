// Helpers for the server integration tests: an in-process server on a loopback
// port with a deterministic estimator, subprocess runner for the real CLI,
// and a push client.
#pragma once

#include "locaid/v1/localization.grpc.pb.h"
#include "server/service.hpp"

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <sys/wait.h>

namespace locaid::server::testing {

namespace v1 = locaid::v1;

// Moves 1 m east per frame. Mode: VO_ONLY inside an outage (forced or a
// scheduled window on the frame clock), else GPS_FUSED. Counts OXTS samples
// it was given as "GPS used", so tests can see that OXTS reached it.
class FakeEstimator : public FrameEstimator {
 public:
  Estimate Process(const vo::StereoFrame& frame, std::span<const kitti::OxtsSample> oxts) override {
    Estimate e;
    e.pose.t_ns = frame.t_ns;
    e.pose.T_enu_body.translation() = Eigen::Vector3d(static_cast<double>(frames_++), 0, 0);
    e.pose.lat_deg = 49.0;
    e.pose.lon_deg = 8.4;
    gps_used_ += static_cast<int>(oxts.size());
    e.pose.gps_used = gps_used_;
    e.in_outage = forced_;
    for (const auto& [a, b] : windows_) e.in_outage = e.in_outage || (frame.t_ns >= a && frame.t_ns < b);
    e.pose.mode = e.in_outage ? fusion::Mode::kVoOnly : fusion::Mode::kGpsFused;
    e.pose.seconds_since_gps = e.in_outage ? 1.0 : 0.0;
    e.vo_inliers = 100;
    e.vo_status = vo::Status::kOk;
    return e;
  }
  void ScheduleOutage(int64_t start_ns, int64_t end_ns) override { windows_.emplace_back(start_ns, end_ns); }
  void StartOutageNow() override { forced_ = true; }
  void StopOutageNow() override {
    forced_ = false;
    windows_.clear();
  }
  void SetScenario(const fusion::Scenario&) override {}
  bool origin(double*, double*, double*) const override { return false; }

 private:
  int frames_ = 0;
  int gps_used_ = 0;
  bool forced_ = false;
  std::vector<std::pair<int64_t, int64_t>> windows_;
};

inline EstimatorFactory FakeFactory() {
  return [](const EstimatorSetup& setup) -> std::unique_ptr<FrameEstimator> {
    if (setup.vo_method != "default" && setup.vo_method != "thesis") {
      throw std::invalid_argument("unknown VO method '" + setup.vo_method + "'");
    }
    return std::make_unique<FakeEstimator>();
  };
}

inline ServerConfig LoopbackConfig() {
  ServerConfig c;
  c.listen = "127.0.0.1:0";
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

inline std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs a command line (already quoted), capturing stdout and stderr.
inline CliResult RunShell(const std::string& command) {
  static int counter = 0;
  const auto dir = std::filesystem::path(::testing::TempDir());
  const std::string stem = "cli_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  const auto out = dir / (stem + ".out"), err = dir / (stem + ".err");
  const int rc = std::system((command + " >" + out.string() + " 2>" + err.string()).c_str());
  CliResult r;
  r.exit_code = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  r.out = Slurp(out);
  r.err = Slurp(err);
  return r;
}

inline CliResult RunCli(int port, const std::vector<std::string>& args, const std::vector<std::string>& pre = {}) {
  std::string cmd = ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid") + " --server 127.0.0.1:" + std::to_string(port);
  for (const auto& a : pre) cmd += " " + ShellQuote(a);
  for (const auto& a : args) cmd += " " + ShellQuote(a);
  return RunShell(cmd);
}

inline std::unique_ptr<v1::Localization::Stub> MakeStub(int port, const std::string& token = {}) {
  (void)token;
  return v1::Localization::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));
}

inline void SetDeadline(grpc::ClientContext* ctx, double seconds = 30) {
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
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

}  // namespace locaid::server::testing
