// locaid-nmea: a drive's OXTS, degraded by a GPS scenario, as the NMEA 0183
// a consumer receiver prints (GGA, RMC, GST per fix; GGA quality 0 and RMC
// status V once per fix slot inside an outage), so any KITTI or synthetic
// drive can be replayed through a real gpsd (gpsfake).
//
//   locaid-nmea --drive DIR [--scenario NAME|FILE] [--seed N] [--start-utc 2024-05-17T12:00:00Z] --out F.nmea
#include "fusion/scenario.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts_pose.hpp"
#include "sensors/nmea.hpp"
#include "server/pipeline/scenario_yaml.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <fstream>
#include <iostream>
#include <optional>

using namespace locaid;

int main(int argc, char** argv) {
  CLI::App app{"locaid-nmea: a drive's degraded GPS as NMEA 0183 (GGA, RMC, GST) for gpsd / gpsfake"};
  std::string drive_dir, scenario_arg = "open-sky", start_utc, out_path;
  int64_t seed = -1;
  app.add_option("--drive", drive_dir, "drive folder (raw sync/extract, or synthetic)")->required();
  app.add_option("--scenario", scenario_arg, "built-in scenario name or YAML file (default open-sky)");
  app.add_option("--seed", seed, "override the scenario seed");
  app.add_option("--start-utc", start_utc,
                 "UTC time of the drive's first OXTS record, YYYY-MM-DDTHH:MM:SS[.fff]Z (default: the drive's "
                 "own time stamps, Unix UTC for KITTI raw and synthetic drives)");
  app.add_option("--out", out_path, "NMEA file to write")->required();
  CLI11_PARSE(app, argc, argv);
  try {
    const auto dataset = kitti::OpenDataset(drive_dir);
    const auto& oxts = dataset->oxts();
    if (oxts.empty()) throw std::runtime_error(drive_dir + ": no OXTS records");
    fusion::Scenario scenario = pipeline::LoadScenario(scenario_arg);
    if (seed >= 0) scenario.seed = static_cast<uint64_t>(seed);
    const double duration_s = static_cast<double>(oxts.back().t_ns - oxts.front().t_ns) * 1e-9;
    scenario = fusion::PlaceOutagesForDrive(scenario, duration_s);
    const int64_t t0 = oxts.front().t_ns;
    const int64_t utc0 = start_utc.empty() ? t0 : sensors::ParseIso8601Utc(start_utc);
    fusion::GpsScenario gps(scenario);
    std::ofstream out(out_path, std::ios::binary);
    if (!out) throw std::runtime_error(out_path + ": cannot write");
    int fixes = 0, outage_epochs = 0;
    std::optional<int64_t> last_outage_slot;
    for (const auto& s : oxts) {
      const kitti::OxtsRecord& r = s.record;
      const Eigen::Matrix3d R_enu_imu = kitti::OxtsAttitude(r.roll_rad, r.pitch_rad, r.yaw_rad);
      sensors::NmeaFix nmea;
      nmea.utc_ns = utc0 + (s.t_ns - t0);
      if (const auto fix = gps.Apply(s.t_ns, r.lat_deg, r.lon_deg, r.alt_m, &R_enu_imu)) {
        nmea.valid = true;
        nmea.lat_deg = fix->lat_deg;
        nmea.lon_deg = fix->lon_deg;
        nmea.alt_m = fix->alt_m;
        nmea.speed_mps = std::hypot(r.ve_mps, r.vn_mps);
        nmea.course_deg = std::fmod(std::atan2(r.ve_mps, r.vn_mps) * 180.0 / M_PI + 360.0, 360.0);
        nmea.sigma_lat_m = nmea.sigma_lon_m = fix->sigma_h_m;
        nmea.sigma_alt_m = fix->sigma_v_m;
        out << sensors::GgaSentence(nmea) << sensors::RmcSentence(nmea) << sensors::GstSentence(nmea);
        ++fixes;
      } else if (gps.InOutage(s.t_ns)) {
        // No fix: what a receiver prints once per epoch while it has none.
        const int64_t slot = fusion::FixSlot(s.t_ns - t0, scenario.gps_rate_hz);
        if (last_outage_slot && slot <= *last_outage_slot) continue;
        last_outage_slot = slot;
        out << sensors::GgaSentence(nmea) << sensors::RmcSentence(nmea);
        ++outage_epochs;
      }
    }
    out.flush();
    if (!out) throw std::runtime_error(out_path + ": write failed");
    std::cerr << "locaid-nmea: " << fixes << " fixes, " << outage_epochs << " no-fix epochs (scenario "
              << scenario.name << ") -> " << out_path << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "locaid-nmea: " << e.what() << "\n";
    return 1;
  }
}
