// How far a track is from a KITTI drive's truth: the shared pieces of the
// accuracy tests that compare a live session with locaid-replay on the same
// drive (tests/server/camera_accuracy_test.cpp, tests/ros2/): a CSV read by
// column, the OXTS truth at a time, the horizontal RMSE while GPS is used and
// the error through and at the end of an outage.
#pragma once

#include "fusion/geodesy.hpp"
#include "kitti/dataset.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace locaid::test_support {

// A CSV with a header: column name -> values.
inline std::map<std::string, std::vector<std::string>> ReadCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::stringstream header(line);
  for (std::string name; std::getline(header, name, ',');) names.push_back(name);
  std::map<std::string, std::vector<std::string>> columns;
  while (std::getline(in, line)) {
    std::stringstream row(line);
    std::string cell;
    for (const auto& name : names) {
      if (!std::getline(row, cell, ',')) cell.clear();
      columns[name].push_back(cell);
    }
  }
  return columns;
}

inline double HorizontalM(double lat1, double lon1, double lat2, double lon2) {
  constexpr double kR = 6378137.0, kDeg = M_PI / 180;
  const double dn = (lat2 - lat1) * kDeg * kR, de = (lon2 - lon1) * kDeg * kR * std::cos(lat1 * kDeg);
  return std::hypot(dn, de);
}

// The excerpt's truth (OXTS) at drive time t_ns, interpolated.
inline std::pair<double, double> TruthAt(const std::vector<kitti::OxtsSample>& oxts, int64_t t_ns) {
  auto it = std::lower_bound(oxts.begin(), oxts.end(), t_ns, [](const auto& s, int64_t t) { return s.t_ns < t; });
  if (it == oxts.begin()) return {it->record.lat_deg, it->record.lon_deg};
  if (it == oxts.end()) return {oxts.back().record.lat_deg, oxts.back().record.lon_deg};
  const auto& a = *(it - 1);
  const double w = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(it->t_ns - a.t_ns);
  return {a.record.lat_deg + w * (it->record.lat_deg - a.record.lat_deg),
          a.record.lon_deg + w * (it->record.lon_deg - a.record.lon_deg)};
}

// A track's horizontal errors against the truth: RMSE while GPS was used,
// and at the end of the (one) outage, with the distance driven in it.
struct TrackErrors {
  double sum2 = 0;
  int n = 0;
  double outage_end_m = -1, outage_m = 0, outage_sum2 = 0;
  int outage_n = 0;
  double last_lat = 0, last_lon = 0;

  void Add(double err, bool in_outage, double truth_lat, double truth_lon) {
    if (in_outage) {
      outage_sum2 += err * err;
      ++outage_n;
      if (outage_end_m >= 0) outage_m += HorizontalM(last_lat, last_lon, truth_lat, truth_lon);
      last_lat = truth_lat;
      last_lon = truth_lon;
      outage_end_m = err;
    } else {
      sum2 += err * err;
      ++n;
    }
  }
  double rmse() const { return n ? std::sqrt(sum2 / n) : std::nan(""); }
  double outage_rmse() const { return outage_n ? std::sqrt(outage_sum2 / outage_n) : std::nan(""); }
};

// The frame of the drive nearest to drive time t_ns.
inline size_t NearestFrame(const kitti::StereoDataset& d, int64_t t_ns) {
  size_t k = 0;
  while (k + 1 < d.size() && std::llabs(d.time_ns(k + 1) - t_ns) < std::llabs(d.time_ns(k) - t_ns)) ++k;
  return k;
}

// locaid-replay's horizontal error at each frame it initialised on, with
// whether the frame was in an outage: its --out-csv (t_s from the drive time
// t_first_ns, est_e/est_n/est_u in the ENU frame of its first fix, the first
// row of its --out-fixes) put back on the globe by the filter's own ENU frame
// and measured against the truth as a session's lat/lon are (HorizontalM), so
// the two tracks' errors compare like for like. Frame of the drive ->
// (error, in outage).
inline std::map<size_t, std::pair<double, bool>> ReplayErrors(const kitti::StereoDataset& drive,
                                                               const std::filesystem::path& replay_csv,
                                                               const std::filesystem::path& fixes_csv,
                                                               int64_t t_first_ns) {
  auto fixes = ReadCsv(fixes_csv);
  auto rows = ReadCsv(replay_csv);
  std::map<size_t, std::pair<double, bool>> errors;
  if (fixes["lat_deg"].empty()) return errors;
  fusion::EnuFrame enu;
  enu.SetOrigin(std::stod(fixes["lat_deg"][0]), std::stod(fixes["lon_deg"][0]), std::stod(fixes["alt_m"][0]));
  for (size_t i = 0; i < rows["t_s"].size(); ++i) {
    if (rows["initialized"][i] != "1") continue;
    const int64_t t = t_first_ns + std::llround(std::stod(rows["t_s"][i]) * 1e9);
    const auto [lat, lon] = TruthAt(drive.oxts(), t);
    double est_lat = 0, est_lon = 0, est_alt = 0;
    enu.ToGeodetic({std::stod(rows["est_e"][i]), std::stod(rows["est_n"][i]), std::stod(rows["est_u"][i])}, est_lat,
                   est_lon, est_alt);
    errors[NearestFrame(drive, t)] = {HorizontalM(lat, lon, est_lat, est_lon), rows["in_outage"][i] == "1"};
  }
  return errors;
}

}  // namespace locaid::test_support
