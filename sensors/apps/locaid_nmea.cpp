// locaid-nmea: a drive's OXTS, degraded by a GPS scenario, as the NMEA 0183
// a consumer receiver prints: one epoch per receiver period on an even grid
// (the true position interpolated to it), GGA, RMC and GST per fix, and GGA
// quality 0, a no-fix GSA and RMC status V per epoch inside an outage. Any
// KITTI or synthetic drive can so be replayed through a real gpsd (gpsfake).
//
//   locaid-nmea --drive DIR [--scenario NAME|FILE] [--seed N] [--start-utc 2024-05-17T12:00:00Z] --out F.nmea
#include "sim/scenario.hpp"
#include "kitti/dataset.hpp"
#include "kitti/oxts_pose.hpp"
#include "sensors/nmea.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/run_assembly.hpp"
#include "pipeline/scenario_yaml.hpp"

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
    // The drive as a run reads it, frames without their images.
    const pipeline::DatasetFrameSource drive(kitti::OpenDataset(drive_dir), 0, -1, /*load_images=*/false);
    const auto& oxts = drive.dataset().oxts();
    if (oxts.empty()) throw std::runtime_error(drive_dir + ": no OXTS records");
    pipeline::RunOptions options;
    options.scenario = pipeline::LoadScenario(scenario_arg);
    if (seed >= 0) options.scenario.seed = static_cast<uint64_t>(seed);
    // Outages placed on the drive (centered) span its frames, as every run
    // places them (pipeline::PlaceRun): a recording's OXTS may run on past them.
    const sim::Scenario scenario = pipeline::PlaceRun(drive, options).scenario;
    const int64_t t0 = oxts.front().t_ns;
    const int64_t utc0 = start_utc.empty() ? t0 : sensors::ParseIso8601Utc(start_utc);
    sim::GpsReceiverSim gps(scenario);
    std::ofstream out(out_path, std::ios::binary);
    if (!out) throw std::runtime_error(out_path + ": cannot write");
    int fixes = 0, outage_epochs = 0;
    // One epoch per receiver period on the drive's clock (t0 + k / rate), as
    // a receiver reports on its UTC grid: the true position is interpolated
    // to the epoch, so that the sentences' times are evenly spaced (a player
    // pacing per sentence, gpsfake -c, then keeps the receiver's time line).
    const auto period_ns = static_cast<int64_t>(std::llround(1e9 / scenario.gps_rate_hz));
    size_t j = 0;
    for (int64_t t = t0; t <= oxts.back().t_ns; t += period_ns) {
      while (j + 1 < oxts.size() && oxts[j + 1].t_ns <= t) ++j;
      const kitti::OxtsRecord& a = oxts[j].record;
      const kitti::OxtsRecord& b = oxts[std::min(j + 1, oxts.size() - 1)].record;
      const int64_t span = oxts[std::min(j + 1, oxts.size() - 1)].t_ns - oxts[j].t_ns;
      const double w = span > 0 ? static_cast<double>(t - oxts[j].t_ns) / static_cast<double>(span) : 0.0;
      const double lat = a.lat_deg + w * (b.lat_deg - a.lat_deg), lon = a.lon_deg + w * (b.lon_deg - a.lon_deg);
      const double alt = a.alt_m + w * (b.alt_m - a.alt_m);
      const kitti::OxtsRecord& r = w < 0.5 ? a : b;  // attitude and velocity of the nearer record
      const Eigen::Matrix3d R_enu_imu = kitti::OxtsAttitude(r.roll_rad, r.pitch_rad, r.yaw_rad);
      sensors::NmeaFix nmea;
      nmea.utc_ns = utc0 + (t - t0);
      if (const auto fix = gps.Apply(t, lat, lon, alt, &R_enu_imu)) {
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
      } else if (gps.InOutage(t)) {
        // No fix: what a receiver prints each epoch while it has none; three
        // sentences as in a fix epoch, for the same pacing.
        out << sensors::GgaSentence(nmea) << sensors::GsaSentence(nmea) << sensors::RmcSentence(nmea);
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
