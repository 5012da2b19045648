// locaid-push: plays a KITTI or synthetic drive into a live session the way a
// car would feed it, in real time: stereo frames, the IMU as typed ImuSample
// messages, and GPS either as the drive's OXTS records (degraded by the
// session's scenario) or from a gpsd the server reads (e.g. gpsfake playing
// the NMEA `locaid-nmea` wrote for the same drive and --start-utc).
//
//   locaid-push --server ADDR --drive DIR [--gps oxts|gpsd|none] [--gpsd HOST:PORT]
//               [--start-utc ISO8601] [--rate 1] [--out-csv F]
//
// Prints the session id on stdout, progress on stderr, and the pose count per
// mode at the end. Exit status: 0 when the stream ended OK, 1 otherwise.
#include "connection/connection.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts.hpp"
#include "locaid/v1/localization.grpc.pb.h"
#include "output/live_source.hpp"
#include "sensors/gpsd_client.hpp"
#include "sensors/nmea.hpp"

#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <climits>
#include <optional>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

namespace {

namespace v1 = locaid::v1;
using Clock = std::chrono::steady_clock;

struct Options {
  locaid::connection::Connection conn;
  std::string drive, gps = "oxts", gpsd = "127.0.0.1:2947", start_utc, scenario, out_csv, vo_method;
  std::vector<double> lever_arm;
  double rate = 1.0, max_gps_delay_s = 0, gps_lead_s = 0.2, wait_fix_s = 20;
  int frames = 0;
};

v1::LiveSource LiveSourceFor(const locaid::kitti::StereoDataset& d, const Options& o) {
  v1::LiveSource l = locaid::output::LiveSourceOf(d.camera(), d.T_cam0_imu());
  for (double v : o.lever_arm) l.add_gps_antenna_body_m(v);
  l.set_max_gps_delay_s(o.max_gps_delay_s);
  if (o.gps == "gpsd") {
    const auto colon = o.gpsd.rfind(':');
    auto* g = l.mutable_gps_source()->mutable_gpsd();
    g->set_host(o.gpsd.substr(0, colon));
    if (colon != std::string::npos) g->set_port(static_cast<uint32_t>(std::stoul(o.gpsd.substr(colon + 1))));
  }
  return l;
}

v1::PushRequest ImuMessage(const locaid::kitti::OxtsSample& s, int64_t shift_ns) {
  v1::PushRequest r;
  auto* m = r.mutable_imu();
  m->set_t_ns(s.t_ns + shift_ns);
  m->mutable_accel_mps2()->set_x(s.record.ax_mps2);
  m->mutable_accel_mps2()->set_y(s.record.ay_mps2);
  m->mutable_accel_mps2()->set_z(s.record.az_mps2);
  m->mutable_gyro_radps()->set_x(s.record.wx_radps);
  m->mutable_gyro_radps()->set_y(s.record.wy_radps);
  m->mutable_gyro_radps()->set_z(s.record.wz_radps);
  return r;
}

// Poses coming back on the push stream: counted per mode, optionally as CSV.
class PoseSink {
 public:
  explicit PoseSink(const std::string& csv_path) {
    if (csv_path.empty()) return;
    csv_.open(csv_path);
    if (!csv_) throw std::runtime_error("--out-csv " + csv_path + ": cannot write");
    csv_ << "t_ns,frame,mode,east_m,north_m,up_m,lat_deg,lon_deg,alt_m,sigma_h_m,seconds_since_gps,gps_outage\n";
  }
  void Add(const v1::PoseUpdate& p) {
    std::lock_guard lock(mu_);
    ++modes_[v1::Mode_Name(p.mode())];
    ++count_;
    if (!csv_.is_open()) return;
    const double sh = std::sqrt(std::max(0.0, p.covariance(0) + p.covariance(7)));
    char line[320];
    std::snprintf(line, sizeof line, "%lld,%lld,%s,%.4f,%.4f,%.4f,%.9f,%.9f,%.4f,%.4f,%.3f,%d\n",
                  static_cast<long long>(p.t_ns()), static_cast<long long>(p.frame_index()),
                  v1::Mode_Name(p.mode()).c_str(), p.position_enu_m().x(), p.position_enu_m().y(),
                  p.position_enu_m().z(), p.latitude_deg(), p.longitude_deg(), p.altitude_m(), sh,
                  p.seconds_since_gps(), p.gps_outage_active() ? 1 : 0);
    csv_ << line << std::flush;  // readable while the drive plays
  }
  int count() {
    std::lock_guard lock(mu_);
    return count_;
  }
  std::string Summary() {
    std::lock_guard lock(mu_);
    std::string s = "poses " + std::to_string(count_);
    for (const auto& [mode, n] : modes_) s += " " + mode + " " + std::to_string(n);
    return s;
  }

 private:
  std::mutex mu_;
  std::ofstream csv_;
  std::map<std::string, int> modes_;
  int count_ = 0;
};

int64_t SteadyNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

// The receiver's clock, read from the same gpsd as the server: on a car the
// camera and the GNSS receiver share UTC, and a player such as gpsfake keeps
// only roughly to it. Frames are paced on it (offset = arrival - UTC of the
// newest report), so they reach the server as they would beside a receiver.
class ReceiverClock {
 public:
  ReceiverClock(std::string host, uint16_t port) : thread_([this, host, port] { Run(host, port); }) {}
  ~ReceiverClock() {
    stop_ = true;
    thread_.join();
  }
  std::optional<int64_t> offset_ns() const {
    const int64_t v = offset_.load();
    return v == kUnset ? std::nullopt : std::optional<int64_t>(v);
  }

 private:
  static constexpr int64_t kUnset = INT64_MIN;
  void Run(const std::string& host, uint16_t port) {
    while (!stop_) {
      try {
        locaid::sensors::GpsdClient client(host, port);
        while (!stop_)
          for (const auto& r : client.Read(std::chrono::milliseconds(100))) {
            if (r.t_ns <= last_t_ns_) continue;  // an epoch reported again
            last_t_ns_ = r.t_ns;
            offset_ = SteadyNs() - r.t_ns;
          }
      } catch (const std::exception&) {
        std::this_thread::sleep_for(std::chrono::milliseconds(200));  // gpsd not (yet) there
      }
    }
  }
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> offset_{kUnset};
  int64_t last_t_ns_ = 0;
  std::thread thread_;
};

int Run(Options& o) {
  locaid::connection::ResolveToken(o.conn);
  const auto dataset = locaid::kitti::OpenDataset(o.drive);
  const auto& oxts = dataset->oxts();
  if (dataset->size() == 0) throw std::runtime_error(o.drive + ": no frames");
  // The drive's clock: its first OXTS record is --start-utc, as in locaid-nmea.
  const int64_t t0 = oxts.empty() ? dataset->time_ns(0) : oxts.front().t_ns;
  const int64_t shift = o.start_utc.empty() ? 0 : locaid::sensors::ParseIso8601Utc(o.start_utc) - t0;

  auto stub = v1::Localization::NewStub(locaid::connection::MakeChannel(o.conn));
  grpc::ClientContext ctx;
  locaid::connection::Prepare(o.conn, &ctx, 0);
  auto stream = stub->PushSensorData(&ctx);
  v1::PushRequest start;
  *start.mutable_start()->mutable_live() = LiveSourceFor(*dataset, o);
  if (!o.scenario.empty()) {
    if (std::ifstream f(o.scenario); f) {
      std::ostringstream text;
      text << f.rdbuf();
      start.mutable_start()->mutable_scenario()->set_yaml(text.str());
    } else {
      start.mutable_start()->mutable_scenario()->set_name(o.scenario);
    }
  }
  start.mutable_start()->set_vo_method(o.vo_method);
  v1::PushResponse first;
  if (!stream->Write(start) || !stream->Read(&first) || !first.has_session()) {
    const grpc::Status s = stream->Finish();
    std::cerr << "locaid-push: " << s.error_message() << "\n";
    return 1;
  }
  const std::string id = first.session().id();
  std::cout << id << std::endl;
  PoseSink sink(o.out_csv);
  std::thread reader([&] {
    v1::PushResponse r;
    while (stream->Read(&r)) {
      if (r.has_pose()) sink.Add(r.pose());
      if (r.has_rejected())
        std::cerr << "locaid-push: rejected " << r.rejected().kind() << " " << r.rejected().index() << ": "
                  << r.rejected().reason() << "\n";
    }
  });
  // gpsd: frames are paced on the receiver's clock and lead its reports by
  // gps_lead_s, as a camera leads a GNSS receiver's output on a car.
  std::unique_ptr<ReceiverClock> receiver;
  if (o.gps == "gpsd") {
    const auto colon = o.gpsd.rfind(':');
    receiver = std::make_unique<ReceiverClock>(o.gpsd.substr(0, colon),
                                               static_cast<uint16_t>(std::stoul(o.gpsd.substr(colon + 1))));
    const auto until = Clock::now() + std::chrono::duration<double>(o.wait_fix_s);
    while (!receiver->offset_ns() && Clock::now() < until) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (!receiver->offset_ns()) std::cerr << "locaid-push: no report from gpsd within " << o.wait_fix_s << " s\n";
  }
  const auto wall0 = Clock::now();
  const auto lead_ns = static_cast<int64_t>(o.gps_lead_s * 1e9);
  const size_t n = o.frames > 0 ? std::min<size_t>(dataset->size(), static_cast<size_t>(o.frames)) : dataset->size();
  size_t next_oxts = 0;
  auto last_report = Clock::now();
  bool ok = true;
  for (size_t i = 0; i < n && ok; ++i) {
    if (!dataset->has_stereo(i)) continue;
    const int64_t t = dataset->time_ns(i);
    for (; next_oxts < oxts.size() && oxts[next_oxts].t_ns <= t && ok; ++next_oxts) {
      const auto& s = oxts[next_oxts];
      if (o.gps == "oxts") {
        v1::PushRequest r;
        r.mutable_oxts()->set_t_ns(s.t_ns + shift);
        r.mutable_oxts()->set_line(locaid::kitti::WriteOxtsLine(s.record));
        ok = stream->Write(r);
      } else {
        ok = stream->Write(ImuMessage(s, shift));
      }
    }
    if (receiver && receiver->offset_ns()) {
      const int64_t due_ns = t + shift + *receiver->offset_ns() - lead_ns;
      std::this_thread::sleep_for(std::chrono::nanoseconds(std::max<int64_t>(0, due_ns - SteadyNs())));
    } else if (o.rate > 0) {
      const double due_s = static_cast<double>(t - t0) * 1e-9 / o.rate;
      std::this_thread::sleep_until(wall0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(due_s)));
    }
    const auto images = dataset->Load(i);
    v1::PushRequest r;
    auto* f = r.mutable_frame();
    f->set_t_ns(t + shift);
    f->set_encoding(v1::IMAGE_ENCODING_GRAY8);
    f->set_left(std::string(reinterpret_cast<const char*>(images.left.data), images.left.total()));
    f->set_right(std::string(reinterpret_cast<const char*>(images.right.data), images.right.total()));
    ok = ok && stream->Write(r);
    if (Clock::now() - last_report > std::chrono::seconds(10)) {
      std::cerr << "locaid-push: frame " << i + 1 << "/" << n << ", " << sink.Summary() << "\n";
      last_report = Clock::now();
    }
  }
  stream->WritesDone();
  reader.join();
  const grpc::Status status = stream->Finish();
  std::cerr << "locaid-push: " << sink.Summary() << "\n";
  if (!status.ok()) std::cerr << "locaid-push: stream ended: " << status.error_message() << "\n";
  return status.ok() && ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"locaid-push: play a drive into a live session in real time"};
  app.add_option("--server", o.conn.server, "server address")->capture_default_str();
  app.add_option("--token-file", o.conn.token_file, "file holding the bearer token");
  app.add_option("--tls-ca", o.conn.tls_ca, "PEM of the CA to trust; enables TLS");
  app.add_option("--drive", o.drive, "KITTI raw or synthetic drive folder")->required()->check(CLI::ExistingDirectory);
  app.add_option("--gps", o.gps, "oxts: OXTS records (GPS degraded by the scenario); gpsd: the server reads "
                                 "--gpsd, the IMU goes as ImuSample; none: ImuSample only")
      ->check(CLI::IsMember({"oxts", "gpsd", "none"}))
      ->capture_default_str();
  app.add_option("--gpsd", o.gpsd, "HOST:PORT of the gpsd the server reads (--gps gpsd)")->capture_default_str();
  app.add_option("--scenario", o.scenario, "session scenario: built-in name or YAML file");
  app.add_option("--vo-method", o.vo_method, "VO method (default: the server's)");
  app.add_option("--start-utc", o.start_utc, "UTC of the drive's first OXTS record (as locaid-nmea); frames, IMU "
                                             "and OXTS times are shifted to it");
  app.add_option("--rate", o.rate, "playback rate (1 = real time, 0 = as fast as the server takes it)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--lever-arm", o.lever_arm, "GPS antenna in the body frame: x y z, m")->expected(3);
  app.add_option("--max-gps-delay", o.max_gps_delay_s, "LiveSource.max_gps_delay_s (0 = server default 0.5 s)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--gps-lead", o.gps_lead_s,
                 "gpsd: frames are paced on the receiver's clock (read from the same gpsd) and lead its reports by "
                 "this, s")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  app.add_option("--frames", o.frames, "push at most N frames (0 = all)")->check(CLI::NonNegativeNumber);
  app.add_option("--out-csv", o.out_csv, "write the poses that come back as CSV");
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(o);
  } catch (const std::exception& e) {
    std::cerr << "locaid-push: " << e.what() << "\n";
    return 1;
  }
}
