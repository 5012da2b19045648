// How well a live session on GStreamer cameras localizes, against
// locaid-replay on the same drive: the real excerpt's raw images played by
// multifilesrc, rectified from camera_info files, no IMU (LiveSource.no_imu,
// `locaid session start --no-imu`; replay's --no-imu). GPS either pushed as
// typed fixes (exactly the replay's, for a like-for-like comparison) or read
// by the server from a real gpsd that gpsfake feeds with locaid-nmea's NMEA.
#include "camera_test_support.hpp"
#include "free_port.hpp"
#include "needs_tool.hpp"
#include "track_errors.hpp"

#include "kitti/dataset.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace locaid::server::testing {
namespace {

using test_support::HorizontalM;
using test_support::NearestFrame;
using test_support::ReadCsv;
using test_support::ReplayErrors;
using test_support::TrackErrors;
using test_support::TruthAt;

// The excerpt's complete pairs from frame `first` on (a bag of it holds no
// others), linked in `dir` as one gapless sequence for multifilesrc; returns
// the drive frame of each played one.
std::vector<size_t> LinkCompletePairs(const kitti::StereoDataset& d, size_t first, const fs::path& dir) {
  for (const std::string side : {"image_00", "image_01"}) fs::create_directories(dir / side / "data");
  std::vector<size_t> played;
  for (size_t k = first; k < d.size(); ++k) {
    char name[32], link[32];
    std::snprintf(name, sizeof name, "%010zu.png", k);
    if (!fs::exists(kDrive / "image_00/data" / name) || !fs::exists(kDrive / "image_01/data" / name)) continue;
    std::snprintf(link, sizeof link, "%010zu.png", played.size());
    for (const std::string side : {"image_00", "image_01"})
      fs::create_symlink(kDrive / side / "data" / name, dir / side / "data" / link);
    played.push_back(k);
  }
  return played;
}

// The excerpt's frames 0.. as a camera delivers them, linked in `dir`: where
// the recording lacks an image (left 23, right 22) both cameras repeat the
// last complete pair, as a stalled driver does.
void LinkGaplessFrames(const kitti::StereoDataset& d, const fs::path& dir) {
  for (const std::string side : {"image_00", "image_01"}) fs::create_directories(dir / side / "data");
  size_t complete = 0;
  for (size_t k = 0; k < d.size(); ++k) {
    char name[32], source[32];
    std::snprintf(name, sizeof name, "%010zu.png", k);
    if (fs::exists(kDrive / "image_00/data" / name) && fs::exists(kDrive / "image_01/data" / name)) complete = k;
    std::snprintf(source, sizeof source, "%010zu.png", complete);
    for (const std::string side : {"image_00", "image_01"})
      fs::create_symlink(kDrive / side / "data" / source, dir / side / "data" / name);
  }
}

// The session time of drive time t_drive when multifilesrc plays the
// drive's frames `played` one every period_ns from s_first: the drive's own
// come at that rate on average, with a few ms of jitter, so its time is
// mapped frame by frame, as the camera's clock stamped them.
int64_t SessionTime(const kitti::StereoDataset& d, const std::vector<size_t>& played, int64_t t_drive,
                    int64_t s_first, int64_t period_ns) {
  size_t k = 0;
  while (k + 2 < played.size() && d.time_ns(played[k + 1]) <= t_drive) ++k;
  const int64_t a = d.time_ns(played[k]), b = d.time_ns(played[k + 1]);
  const double frac = static_cast<double>(t_drive - a) / static_cast<double>(b - a);
  return s_first + std::llround((static_cast<double>(k) + frac) * static_cast<double>(period_ns));
}

// The drive's mean frame period: a camera plays it at its own rate.
int64_t FramePeriodNs(const kitti::StereoDataset& d) {
  return (d.time_ns(d.size() - 1) - d.time_ns(0)) / static_cast<int64_t>(d.size() - 1);
}

int64_t UnixNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string Replay() { return ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-replay"); }

// Like for like: locaid-replay on a ROS 2 bag of the excerpt from frame
// kFirst on (every pair complete; written by the Foxglove MCAP library's
// writer) rectifies the raw images from camera_info with the same rectifier
// and crop as the cameras, and the session gets exactly the fixes the
// replay's scenario gave its filter (its receiver's 1.5 m noise on the
// bag's fixes, a 10 s outage in the middle), pushed as a receiver delivers
// them (typed GpsFix, each when its time comes), the cameras playing the
// same frames at the drive's own rate. Neither has an IMU. The session's
// track is within 1.2x of the replay's while GPS is used (RMSE), and
// through the outage, where VO alone carries it (VO's drift: RMSE in it and
// error at its end); with two pipelines, and with one stereo pipeline of two
// named appsinks.
TEST_F(CameraSession, PushedFixesLikeTheReplayOfTheDriveAsABag) {
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("node"), "node not installed (the bag writer runs on it)");
  const fs::path bag = dir_ / "drive.mcap", replay_csv = dir_ / "replay.csv", fixes_csv = dir_ / "fixes.csv";
  const CliResult written = RunShell("node " + ShellQuote(std::string(LOCAID_ROSBAG_JS_DIR) + "/kitti_to_bag.mjs") +
                                     " --drive " + ShellQuote(kDrive.string()) + " --first-frame " +
                                     std::to_string(kFirst) + " --out " + ShellQuote(bag.string()));
  ASSERT_EQ(written.exit_code, 0) << written.out << written.err;
  // The bag's fixes are OXTS as recorded (centimetres): degraded by the
  // scenario's receiver (1.5 m), as the drive's are.
  const fs::path scenario = dir_ / "outage-degraded.yaml";
  std::ofstream(scenario) << "base: open-sky\noutages:\n  - {centered: true, duration_s: 10}\nseed: 1\n"
                          << "gps: {measured: degraded}\n";
  const CliResult replay = RunShell(Replay() + " --bag " + ShellQuote(bag.string()) + " --no-imu --scenario " +
                                    ShellQuote(scenario.string()) + " --out-csv " + ShellQuote(replay_csv.string()) + " --out-fixes " +
                                    ShellQuote(fixes_csv.string()));
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  fs::remove(bag);  // 200 MB
  const auto dataset = kitti::OpenDataset(kDrive);
  const int64_t t_first = dataset->time_ns(kFirst);  // the bag's first frame: replay's t_s = 0
  auto fixes = ReadCsv(fixes_csv);
  ASSERT_FALSE(fixes["t_ns"].empty());
  // The replay's errors per frame.
  const auto replayed = ReplayErrors(*dataset, replay_csv, fixes_csv, t_first);

  const std::vector<size_t> played = LinkCompletePairs(*dataset, kFirst, dir_ / "play");
  const int frames = static_cast<int>(played.size());
  const int64_t period_ns = FramePeriodNs(*dataset);
  const std::string framerate = "1000000000/" + std::to_string(period_ns);  // the drive's own rate
  // One session on `cameras`: its errors and the replay's at the same frames.
  const auto run = [&](const std::vector<std::string>& cameras, TrackErrors* session, TrackErrors* replayed_errors) {
    std::vector<std::string> flags = {"--no-imu"};
    flags.insert(flags.end(), cameras.begin(), cameras.end());
    const std::string id = Start(flags);
    ASSERT_FALSE(id.empty()) << server_->log();
    PoseCollector poses(server_->NewChannel(1), id, /*from_start=*/true);
    auto stub = Stub();
    Pusher pusher(stub.get(), id, v1::LiveSource());
    ASSERT_TRUE(pusher.ok());
    ASSERT_TRUE(poses.WaitPoses(1, 30));
    const int64_t s_first = poses.poses().front().t_ns();  // frame kFirst on the session clock
    // Each fix when the session clock (Unix time) reaches it, until the play ends.
    size_t next = 0;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < until) {
      for (; next < fixes["t_ns"].size(); ++next) {
        const int64_t t_session = SessionTime(*dataset, played, std::stoll(fixes["t_ns"][next]), s_first, period_ns);
        if (t_session > UnixNowNs()) break;
        v1::PushRequest push;
        auto* g = push.mutable_gps();
        g->set_t_ns(t_session);
        g->set_fix_type(v1::GPS_FIX_3D);
        g->set_latitude_deg(std::stod(fixes["lat_deg"][next]));
        g->set_longitude_deg(std::stod(fixes["lon_deg"][next]));
        g->set_altitude_m(std::stod(fixes["alt_m"][next]));
        g->set_sigma_horizontal_m(std::stod(fixes["sigma_h_m"][next]));
        g->set_sigma_vertical_m(std::stod(fixes["sigma_v_m"][next]));
        ASSERT_TRUE(pusher.Write(push));
      }
      if (poses.poses().back().vo_health() == v1::VO_HEALTH_NO_IMAGES) break;  // the play is over
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    // Each pose (one played frame every period_ns) against the truth at its
    // frame, beside the replay's error there.
    for (const auto& p : poses.poses()) {
      if (p.vo_health() == v1::VO_HEALTH_NO_IMAGES) break;
      const auto slot =
          static_cast<size_t>(std::llround(static_cast<double>(p.t_ns() - s_first) / static_cast<double>(period_ns)));
      if (slot >= played.size()) break;
      const size_t k = played[slot];
      if (p.mode() == v1::MODE_LOST || !replayed.count(k)) continue;
      const auto [lat, lon] = TruthAt(dataset->oxts(), dataset->time_ns(k));
      const auto [replay_error, in_outage] = replayed.at(k);
      session->Add(HorizontalM(lat, lon, p.latitude_deg(), p.longitude_deg()), in_outage, lat, lon);
      replayed_errors->Add(replay_error, in_outage, lat, lon);
    }
  };
  const auto play = [&](const std::string& side) { return Play(side, frames, framerate, false, dir_ / "play", 0); };
  const std::vector<std::pair<std::string, std::vector<std::string>>> setups = {
      {"two pipelines", {"--camera-left", play("image_00"), "--camera-right", play("image_01")}},
      {"one stereo pipeline",
       {"--camera-stereo", play("image_00") + " ! videoconvert ! appsink name=left " + play("image_01") +
                               " ! videoconvert ! appsink name=right"}}};
  for (const auto& [what, cameras] : setups) {
    SCOPED_TRACE(what);
    TrackErrors session, replayed_errors;
    run(cameras, &session, &replayed_errors);
    ASSERT_GT(session.n, 10);
    ASSERT_GE(session.outage_end_m, 0) << "the outage was seen";
    std::cout << "[cameras, pushed fixes, " << what << "] rmse " << session.rmse() << " m (replay of the bag "
              << replayed_errors.rmse() << " m) over " << session.n << " frames; end of a " << session.outage_m
              << " m outage " << session.outage_end_m << " m (replay " << replayed_errors.outage_end_m
              << " m), rmse in it " << session.outage_rmse() << " m (replay " << replayed_errors.outage_rmse()
              << " m)\n";
    EXPECT_LE(session.rmse(), 1.2 * replayed_errors.rmse());
    // VO's drift: the error through the outage, where VO alone carries the
    // track, and at its end.
    EXPECT_LE(session.outage_rmse(), 1.2 * replayed_errors.outage_rmse());
    EXPECT_LE(session.outage_end_m, 1.2 * replayed_errors.outage_end_m);
  }
}

// "YYYY-MM-DDTHH:MM:SS.fffZ" of a Unix time in ns (locaid-nmea --start-utc).
std::string IsoUtc(int64_t t_ns) {
  const std::time_t s = static_cast<std::time_t>(t_ns / 1000000000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char text[64];
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>((t_ns / 1000000) % 1000));
  return text;
}

// The NMEA epochs of `in` stamped at or after UTC time of day `from_s`
// (seconds since midnight), into `out`: a receiver switched on then.
void CopyEpochsFrom(const fs::path& in, const fs::path& out, double from_s) {
  std::ifstream src(in);
  std::ofstream dst(out);
  double s = 0;
  for (std::string line; std::getline(src, line);) {
    if (line.rfind("$GPGSA", 0) != 0) {  // GSA has no time: it goes with its epoch
      const std::string hhmmss = line.substr(line.find(',') + 1, 9);
      s = std::stod(hhmmss.substr(0, 2)) * 3600 + std::stod(hhmmss.substr(2, 2)) * 60 + std::stod(hhmmss.substr(4));
    }
    if (s >= from_s) dst << line << "\n";
  }
}

// GPS as a car gets it: the cameras at the drive's own frame rate, and the
// server reading a real gpsd (`--gpsd`) that Debian's gpsfake feeds with
// locaid-nmea's NMEA of the drive's degraded fixes (the same scenario),
// stamped on the session's clock. The scenario: open-sky GPS with a 10 s
// outage from 9 s; the receiver comes on a second or more into the drive
// (later on a loaded machine), and replay gets its GPS from that moment
// too. The outage is seen through gpsd's no-fix reports, and the fused
// track's RMSE and its error at the outage's end are within 1.2x of
// locaid-replay's on the same drive and scenario (its worst over 4 seeds:
// the receivers' noise draws differ, and a draw moves the end error by
// metres).
TEST_F(CameraSession, GpsFromGpsdLikeTheReplayOfTheDrive) {
  LOCAID_NEEDS_TOOL(test_support::HaveCommand("gpsfake"),
                    "gpsfake not installed (deploy/install-deps.sh installs Debian's gpsd and gpsd-clients)");
  const std::string outage = "  - {start_s: 9, duration_s: 10}\n";
  const fs::path scenario_yaml = dir_ / "outage-at-9s.yaml";
  std::ofstream(scenario_yaml) << "base: open-sky\noutages:\n" << outage << "seed: 1\n";
  const std::string scenario = ShellQuote(scenario_yaml.string());
  const auto dataset = kitti::OpenDataset(kDrive);
  const int64_t t_first = dataset->time_ns(0);
  const int64_t period_ns = FramePeriodNs(*dataset);
  const std::string framerate = "1000000000/" + std::to_string(period_ns);  // the drive's own rate

  const std::string gpsd_port = std::to_string(test_support::FreeLoopbackPort());
  // From frame 0 (the filter starts up on GPS before the outage at 5.3 s),
  // the cameras stalling on the last complete pair where the recording
  // lacks an image.
  const int frames = static_cast<int>(dataset->size());
  LinkGaplessFrames(*dataset, dir_ / "play");
  const std::string id =
      Start({"--no-imu", "--gpsd", "127.0.0.1:" + gpsd_port, "--camera-left",
             Play("image_00", frames, framerate, false, dir_ / "play", 0), "--camera-right",
             Play("image_01", frames, framerate, false, dir_ / "play", 0)});
  ASSERT_FALSE(id.empty()) << server_->log();
  PoseCollector poses(server_->NewChannel(1), id, /*from_start=*/true);
  ASSERT_TRUE(poses.WaitPoses(1, 30));
  const int64_t s_first = poses.poses().front().t_ns();  // frame 0 on the session clock
  // Drive time t -> session time s_first + (t - t_first): the NMEA's clock.
  const int64_t oxts_first = dataset->oxts().front().t_ns;
  const CliResult nmea = RunShell(ShellQuote(std::string(LOCAID_BIN_DIR) + "/locaid-nmea") + " --drive " +
                                  ShellQuote(kDrive.string()) + " --scenario " + scenario + " --start-utc " +
                                  IsoUtc(s_first + (oxts_first - t_first)) + " --out " +
                                  ShellQuote((dir_ / "all.nmea").string()));
  ASSERT_EQ(nmea.exit_code, 0) << nmea.err;
  // The receiver comes on 1 s from now: earlier epochs would arrive too late.
  const int64_t on_ns = UnixNowNs() + 1000000000;
  CopyEpochsFrom(dir_ / "all.nmea", dir_ / "gps.nmea", static_cast<double>(on_ns % 86400000000000LL) * 1e-9);
  // gpsfake runs gpsd as its child, with their control socket in $TMPDIR (the
  // test's folder); SIGTERM ends both. Three sentences an epoch, a little
  // faster than 10 Hz: early fixes wait for their frames, late ones would be
  // dropped.
  ChildProcess gpsfake({"/usr/bin/env", "TMPDIR=" + dir_.path().string(), "gpsfake", "-1", "-q", "-c", "0.03", "-P",
                        gpsd_port, (dir_ / "gps.nmea").string()},
                       {dir_ / "gpsfake.out", dir_ / "gpsfake.err", 0});
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < until && poses.poses().back().vo_health() != v1::VO_HEALTH_NO_IMAGES)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  auto stub = Stub();
  const v1::SessionStats stats = GetStats(stub.get(), id);
  if (gpsfake.running() && gpsfake.Signal(SIGTERM)) gpsfake.Wait(30);

  // When the modes changed (s since the first frame): start-up, the outage.
  std::string modes, last;
  for (const auto& p : poses.poses()) {
    if (v1::Mode_Name(p.mode()) == last) continue;
    last = v1::Mode_Name(p.mode());
    modes += " " + last.substr(5) + "@" + std::to_string(static_cast<double>(p.t_ns() - s_first) * 1e-9).substr(0, 5);
  }
  // locaid-replay with GPS from where the session's first fix came (the
  // receiver came on then): the same start-up, the same outage.
  int64_t first_fix_ns = 0;
  for (const auto& p : poses.poses())
    if (p.gps_fixes_size() > 0 && first_fix_ns == 0) first_fix_ns = p.gps_fixes(0).t_ns();
  ASSERT_GT(first_fix_ns, 0) << "no fix reached the session";
  const double gps_on_s = static_cast<double>((first_fix_ns - s_first) - (oxts_first - t_first)) * 1e-9 - 0.05;
  const fs::path replay_yaml = dir_ / "replay.yaml";
  std::ofstream(replay_yaml) << "base: open-sky\noutages:\n  - {start_s: 0, duration_s: " << gps_on_s << "}\n"
                             << outage;
  double replay_rmse = 0, replay_end = 0;
  for (int seed = 1; seed <= 4; ++seed) {
    const CliResult r = RunShell(Replay() + " --drive " + ShellQuote(kDrive.string()) + " --no-imu --json --scenario " +
                                 ShellQuote(replay_yaml.string()) + " --seed " + std::to_string(seed));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    replay_rmse = std::max(replay_rmse, j["rmse_gps_m"].get<double>());
    replay_end = std::max(replay_end, j["outages"].back()["end_error_m"].get<double>());
  }

  TrackErrors session;
  bool outage_over = false;
  for (const auto& p : poses.poses()) {
    if (p.vo_health() == v1::VO_HEALTH_NO_IMAGES) break;
    if (p.mode() == v1::MODE_LOST) continue;
    const bool in_outage = p.mode() == v1::MODE_VO_ONLY;
    if (in_outage && outage_over) continue;  // one outage: the scenario's
    if (!in_outage && session.outage_end_m >= 0) outage_over = true;
    const auto [lat, lon] = TruthAt(dataset->oxts(), t_first + (p.t_ns() - s_first));
    session.Add(HorizontalM(lat, lon, p.latitude_deg(), p.longitude_deg()), in_outage, lat, lon);
  }
  std::cout << "[cameras, gpsd] rmse " << session.rmse() << " m over " << session.n << " frames (replay, worst of 4 "
            << "seeds: " << replay_rmse << " m); end of a " << session.outage_m << " m outage " << session.outage_end_m
            << " m (replay " << replay_end << " m); fixes " << stats.gps_fixes_in() << ", no-fix "
            << stats.gps_no_fix() << ", late " << stats.gps_fixes_late() << ", gpsd connects "
            << stats.gpsd().connects() << "; camera pairs " << stats.camera().pairs() << ", dropped late "
            << stats.camera().dropped_late() << "; GPS from " << gps_on_s << " s; modes" << modes << "\n";
  EXPECT_EQ(stats.last_input_error(), "") << "--no-imu: no notice of missing IMU samples";
  EXPECT_GE(stats.gpsd().connects(), 1u) << Slurp(dir_ / "gpsfake.err");
  EXPECT_GE(stats.gps_no_fix(), 80u) << "the 10 s outage, as gpsd's no-fix reports";
  EXPECT_GE(stats.gps_fixes_in(), 50u + stats.gps_no_fix());
  ASSERT_GT(session.n, 30);
  ASSERT_GT(session.outage_m, 50) << "the outage was seen (VO_ONLY)";
  EXPECT_LE(session.rmse(), 1.2 * replay_rmse);
  EXPECT_LE(session.outage_end_m, 1.2 * replay_end);
}

}  // namespace
}  // namespace locaid::server::testing
