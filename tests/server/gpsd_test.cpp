// A live session on a real car's inputs (issue 20), end to end with the real
// tools: a synthetic drive's NMEA (locaid-nmea) played by Debian's gpsfake
// through a real gpsd, the real locaid-server reading that gpsd, and
// locaid-push pushing the drive's frames and IMU in real time. Checks the
// order of the modes through a scripted GPS gap and a gpsd stopped mid-run,
// and the fused error against the drive's ground truth beside
// locaid-replay's on the same scenario.
#include "free_port.hpp"
#include "test_support.hpp"

#include "needs_tool.hpp"

#include "fusion/geodesy.hpp"
#include "kitti/dataset.hpp"

#include <netinet/in.h>
#include <nlohmann/json.hpp>
#include <sys/socket.h>

#include <cmath>
#include <fstream>
#include <sstream>

namespace locaid::server::testing {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kUtc0 = 1767225600LL * 1000000000LL;  // 2026-01-01T00:00:00Z

std::string Which(const std::string& program) {
  FILE* p = ::popen(("command -v " + program + " 2>/dev/null").c_str(), "r");
  char buf[512] = {0};
  std::string path = p && std::fgets(buf, sizeof buf, p) ? buf : "";
  if (p) ::pclose(p);
  while (!path.empty() && std::isspace(static_cast<unsigned char>(path.back()))) path.pop_back();
  return path;
}


int Shell(const std::string& cmd) { return std::system(cmd.c_str()); }

// Keeps the NMEA epochs at or after `from_s` seconds past midnight UTC (GSA
// has no time: it goes with its epoch's GGA).
void CopyEpochsFrom(const fs::path& in, const fs::path& out, double from_s) {
  std::ifstream src(in);
  std::ofstream dst(out);
  double s = 0;
  for (std::string line; std::getline(src, line);) {
    if (line.rfind("$GPGSA", 0) != 0) {
      const auto comma = line.find(',');
      const std::string hhmmss = line.substr(comma + 1, 9);
      s = std::stod(hhmmss.substr(0, 2)) * 3600 + std::stod(hhmmss.substr(2, 2)) * 60 + std::stod(hhmmss.substr(4));
    }
    if (s >= from_s) dst << line << "\n";
  }
}

struct LivePose {
  double t_s = 0;  // since kUtc0
  std::string mode;
  double lat = 0, lon = 0;
};

std::vector<LivePose> ReadPoses(const fs::path& csv) {
  std::vector<LivePose> out;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    if (f.size() < 12) break;  // a line still being written
    out.push_back({static_cast<double>(std::stoll(f[0]) - kUtc0) * 1e-9, f[2], std::stod(f[6]), std::stod(f[7])});
  }
  return out;
}

// Consecutive poses of one mode: [from_s, to_s] on the sensor clock.
struct ModeRun {
  std::string mode;
  double from_s = 0, to_s = 0;
};

std::vector<ModeRun> ModeRuns(const std::vector<LivePose>& poses) {
  std::vector<ModeRun> runs;
  for (const auto& p : poses) {
    if (runs.empty() || runs.back().mode != p.mode) runs.push_back({p.mode, p.t_s, p.t_s});
    runs.back().to_s = p.t_s;
  }
  return runs;
}

std::string Describe(const std::vector<ModeRun>& runs) {
  std::ostringstream out;
  for (const auto& r : runs) out << "  " << r.mode << " " << r.from_s << " .. " << r.to_s << " s\n";
  return out.str();
}

// Waits until the pushed drive's poses reach sensor time t_s (bounded).
bool WaitSensorTime(const fs::path& csv, double t_s, double timeout_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < until) {
    const auto poses = ReadPoses(csv);
    if (!poses.empty() && poses.back().t_s >= t_s) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

TEST(GpsdSession, FusesARealGpsdThroughAGapAndAGpsdRestart) {
  const std::string gpsfake = Which("gpsfake");
  LOCAID_NEEDS_TOOL(!gpsfake.empty(),
                    "gpsfake not installed (deploy/install-deps.sh installs Debian's gpsd and gpsd-clients)");
  const ScopedTempDir dir("gpsd");
  const std::string bin = LOCAID_BIN_DIR;
  // 45 s drive; GPS at 1 Hz with a scripted 8 s gap at 12 s.
  ASSERT_EQ(Shell(bin + "/locaid-synth -q --out " + (dir / "d").string() +
                  " --frames 450 --width 320 --height 96 --seed 7"), 0);
  fs::path drive;
  for (const auto& e : fs::directory_iterator(dir / "d"))
    if (e.is_directory()) drive = e.path();
  std::ofstream(dir / "s.yaml") << "base: open-sky\ngps: {rate_hz: 1}\noutages:\n  - {start_s: 12, duration_s: 8}\nseed: 3\n";
  ASSERT_EQ(Shell(bin + "/locaid-nmea --drive " + drive.string() + " --scenario " + (dir / "s.yaml").string() +
                  " --start-utc 2026-01-01T00:00:00Z --out " + (dir / "all.nmea").string() + " 2>/dev/null"), 0);
  CopyEpochsFrom(dir / "all.nmea", dir / "tail.nmea", 31.0);  // what gpsd plays after its restart
  // The bound: what locaid-replay achieves offline on the same scenario. One
  // run's error at a gap's end depends on its GPS noise draw (0.4-5 m over
  // seeds on this drive), so the bound is replay's worst over 8 seeds.
  double replay_rmse = 0, replay_gap_end = 0;
  for (int seed = 1; seed <= 8; ++seed) {
    const fs::path json = dir / ("replay" + std::to_string(seed) + ".json");
    ASSERT_EQ(Shell(bin + "/locaid-replay --drive " + drive.string() + " --scenario " + (dir / "s.yaml").string() +
                    " --seed " + std::to_string(seed) + " --json > " + json.string() + " 2>/dev/null"), 0);
    const auto replay = nlohmann::json::parse(std::ifstream(json));
    replay_rmse = std::max(replay_rmse, replay["rmse_gps_m"].get<double>());
    replay_gap_end = std::max(replay_gap_end, replay["outages"][0]["end_error_m"].get<double>());
  }

  ServerProcess server(dir / "server");
  ASSERT_GT(server.port(), 0) << server.log();
  const std::string gpsd_port = std::to_string(test_support::FreeLoopbackPort());
  // gpsfake runs gpsd as its child and puts their control socket in $TMPDIR:
  // the test's folder here. SIGTERM, not ChildProcess's SIGKILL, ends it, so
  // it stops its gpsd (a killed gpsfake left gpsd running).
  const auto play = [&](const fs::path& nmea, const char* tag) {
    return std::make_unique<ChildProcess>(
        std::vector<std::string>{"/usr/bin/env", "TMPDIR=" + dir.path().string(), gpsfake, "-1", "-q", "-c",
                                 "0.3333", "-P", gpsd_port, nmea.string()},
        ChildProcess::Options{dir / (std::string(tag) + ".out"), dir / (std::string(tag) + ".err"), 0});
  };
  auto player = play(dir / "all.nmea", "gpsfake1");
  struct TerminateGpsfake {
    std::unique_ptr<ChildProcess>& player;
    ~TerminateGpsfake() {
      if (player && player->running() && player->Signal(SIGTERM)) player->Wait(30);
    }
  } terminate_gpsfake{player};
  const fs::path csv = dir / "live.csv";
  ChildProcess push({bin + "/locaid-push", "--server", "127.0.0.1:" + std::to_string(server.port()), "--drive",
                     drive.string(), "--gps", "gpsd", "--gpsd", "127.0.0.1:" + gpsd_port, "--start-utc",
                     "2026-01-01T00:00:00Z", "--out-csv", csv.string()},
                    {dir / "push.out", dir / "push.err", 0});
  // gpsd goes away at 27 s of the drive and comes back (from 31 s on) at 30 s.
  ASSERT_TRUE(WaitSensorTime(csv, 27.0, 60)) << Slurp(dir / "push.err");
  player->Signal(SIGTERM);
  ASSERT_TRUE(player->Wait(10));
  ASSERT_TRUE(WaitSensorTime(csv, 30.0, 20));
  player = play(dir / "tail.nmea", "gpsfake2");
  ASSERT_TRUE(push.Wait(60)) << Slurp(dir / "push.err");
  EXPECT_EQ(push.exit_code(), 0) << Slurp(dir / "push.err");
  const std::string id = Slurp(dir / "push.out").substr(0, Slurp(dir / "push.out").find('\n'));

  auto stub = v1::Localization::NewStub(server.NewChannel());
  const v1::SessionStats stats = GetStats(stub.get(), id);
  std::printf("[gpsd] fixes in %llu, late %llu, no-fix %llu; gpsd connects %llu, losses %llu; fix arrival->use "
              "median %.3f ms, max %.3f ms\n",
              static_cast<unsigned long long>(stats.gps_fixes_in()), static_cast<unsigned long long>(stats.gps_fixes_late()),
              static_cast<unsigned long long>(stats.gps_no_fix()), static_cast<unsigned long long>(stats.gpsd().connects()),
              static_cast<unsigned long long>(stats.gpsd().connection_losses()), stats.gpsd().fix_latency_median_ms(),
              stats.gpsd().fix_latency_max_ms());
  EXPECT_GE(stats.gpsd().connection_losses(), 1u);
  EXPECT_GE(stats.gpsd().connects(), 2u);
  EXPECT_GE(stats.gps_no_fix(), 7u);  // the scripted gap, reported by gpsd as mode 1
  EXPECT_EQ(stats.imu_samples(), 450u);

  // The modes' order on the sensor clock: fused; VO only from within the
  // scripted gap [12 s, 20 s) (once 1.5 periods and twice the fixes' lag
  // passed without a fix); fused again after it; VO only from after gpsd
  // went away (the test stops it once the poses reached 27 s); fused again
  // to the end. Where exactly a switch falls depends on how late the fixes
  // arrive (machine load), so only the order and the events' sides are
  // asserted; the switch delays are a benchmark figure.
  const auto poses = ReadPoses(csv);
  ASSERT_GE(poses.size(), 440u);
  const std::vector<ModeRun> runs = ModeRuns(poses);
  struct Expected {
    const char* mode;
    double from_min_s, from_max_s;  // the run starts in [from_min_s, from_max_s)
    const char* what;
  };
  const std::vector<Expected> expected = {
      {"MODE_GPS_FUSED", 0, 12, "fused before the scripted gap"},
      {"MODE_VO_ONLY", 12, 20, "VO only in the scripted gap"},
      {"MODE_GPS_FUSED", 20, 27, "fused again after the gap"},
      {"MODE_VO_ONLY", 27, 1e9, "VO only once gpsd went away"},
      {"MODE_GPS_FUSED", 30, 1e9, "fused again after gpsd came back"},
  };
  size_t at = 0;
  for (const Expected& e : expected) {
    while (at < runs.size() &&
           !(runs[at].mode == e.mode && runs[at].from_s >= e.from_min_s && runs[at].from_s < e.from_max_s)) {
      ++at;
    }
    ASSERT_LT(at, runs.size()) << "no run: " << e.what << "; the modes were:\n" << Describe(runs);
    ++at;
  }
  EXPECT_EQ(runs.back().mode, "MODE_GPS_FUSED") << "the drive ends fused; the modes were:\n" << Describe(runs);

  // Error against the drive's ground truth (OXTS at the frame time).
  const auto dataset = kitti::OpenDataset(drive);
  const auto& oxts = dataset->oxts();
  const int64_t t0 = oxts.front().t_ns;
  fusion::EnuFrame enu;
  enu.SetOrigin(oxts.front().record.lat_deg, oxts.front().record.lon_deg, oxts.front().record.alt_m);
  double sum2 = 0, gap_end = -1;
  int n = 0;
  size_t j = 0;
  for (const auto& p : poses) {
    const int64_t t = t0 + static_cast<int64_t>(std::llround(p.t_s * 1e9));
    while (j + 1 < oxts.size() && oxts[j + 1].t_ns <= t) ++j;
    const auto& a = oxts[j];
    const auto& b = oxts[std::min(j + 1, oxts.size() - 1)];
    const double w = b.t_ns > a.t_ns ? static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns) : 0.0;
    const Eigen::Vector3d truth = enu.ToEnu(a.record.lat_deg + w * (b.record.lat_deg - a.record.lat_deg),
                                            a.record.lon_deg + w * (b.record.lon_deg - a.record.lon_deg), 0);
    const double err = (enu.ToEnu(p.lat, p.lon, 0) - truth).head<2>().norm();
    if (p.mode == "MODE_GPS_FUSED") {
      sum2 += err * err;
      ++n;
    }
    if (p.t_s < 20.0) gap_end = err;  // the last pose of the scripted gap
  }
  const double rmse = std::sqrt(sum2 / std::max(1, n));
  // locaid-replay's worst on this scenario, with 25 % for what a live run
  // adds (NMEA's precision, late fixes, the fixes lost while gpsd was away).
  const double rmse_bound = 1.25 * replay_rmse, gap_bound = 1.25 * replay_gap_end;
  std::printf("[gpsd] fused horizontal RMSE %.3f m (replay worst of 8 seeds %.3f m, bound %.3f m); error at the "
              "gap's end %.3f m (replay worst %.3f m, bound %.3f m)\n",
              rmse, replay_rmse, rmse_bound, gap_end, replay_gap_end, gap_bound);
  EXPECT_LE(rmse, rmse_bound);
  EXPECT_LE(gap_end, gap_bound);
}

}  // namespace
}  // namespace locaid::server::testing
