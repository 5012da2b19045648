// How fast the MCAP recording of a session is written, and how large it is:
// N poses of a moving car (one GPS fix each, ground truth, covariance), every
// Foxglove channel as `locaid subscribe --format mcap` writes it, zstd chunks
// and uncompressed. Prints JSON (docs/benchmarks.md, "MCAP recording").
//
//   build/bin/mcap_write_bench [--poses 20000] [--zstd-level 3] [--out-dir /tmp]
#include "output/mcap_recording.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>

namespace {

namespace v1 = locaid::v1;

v1::PoseUpdate Pose(int k) {
  const double t = 0.1 * k, yaw = 0.02 * t;
  v1::PoseUpdate p;
  p.set_session_id("s0123456789ab");
  p.set_sequence(static_cast<uint64_t>(k));
  p.set_frame_index(k);
  p.set_t_ns(1'700'000'000'000'000'000LL + static_cast<int64_t>(k) * 100'000'000LL);
  p.mutable_position_enu_m()->set_x(100 * std::sin(yaw));
  p.mutable_position_enu_m()->set_y(100 * (1 - std::cos(yaw)));
  p.mutable_position_enu_m()->set_z(0.1 * std::sin(t));
  p.mutable_orientation_enu_body()->set_w(std::cos(yaw / 2));
  p.mutable_orientation_enu_body()->set_z(std::sin(yaw / 2));
  p.set_latitude_deg(49.0 + 1e-6 * k);
  p.set_longitude_deg(8.4 + 1e-6 * k);
  p.set_altitude_m(110);
  for (int i = 0; i < 36; ++i) p.add_covariance(i % 7 == 0 ? 0.25 + 1e-4 * (k % 50) : 1e-3);
  p.set_mode(v1::MODE_GPS_FUSED);
  p.set_vo_status(v1::VO_STATUS_OK);
  p.set_vo_inliers(300 + k % 40);
  p.set_gps_used(static_cast<uint32_t>(k));
  auto* g = p.add_gps_fixes();
  g->set_t_ns(p.t_ns() - 20'000'000);
  g->set_latitude_deg(p.latitude_deg() + 1e-5);
  g->set_longitude_deg(p.longitude_deg() - 1e-5);
  g->set_altitude_m(111);
  g->set_sigma_horizontal_m(1.5);
  g->set_sigma_vertical_m(3);
  g->set_used(true);
  g->set_nis(1.2);
  g->set_gate(13.8);
  p.set_has_truth(true);
  *p.mutable_truth_position_enu_m() = p.position_enu_m();
  *p.mutable_truth_orientation_enu_body() = p.orientation_enu_body();
  p.set_truth_latitude_deg(p.latitude_deg());
  p.set_truth_longitude_deg(p.longitude_deg());
  p.set_truth_altitude_m(110);
  p.set_horizontal_error_m(0.4);
  return p;
}

nlohmann::json Run(const std::vector<v1::PoseUpdate>& poses, const std::filesystem::path& file, bool zstd,
                   int zstd_level) {
  locaid::record::McapOptions options;
  options.zstd = zstd;
  options.zstd_level = zstd_level;
  const auto t0 = std::chrono::steady_clock::now();
  locaid::output::McapRecording recording(file, options);
  for (const auto& p : poses) recording.Add(p);
  recording.Close();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto bytes = std::filesystem::file_size(file);
  return {{"compression", zstd ? "zstd-" + std::to_string(zstd_level) : "none"},
          {"poses", poses.size()},
          {"messages", recording.messages()},
          {"seconds", s},
          {"poses_per_s", static_cast<double>(poses.size()) / s},
          {"bytes", bytes},
          {"bytes_per_pose", static_cast<double>(bytes) / static_cast<double>(poses.size())}};
}

}  // namespace

int main(int argc, char** argv) {
  int n = 20000;
  int zstd_level = locaid::record::McapOptions{}.zstd_level;  // what the recorders use
  std::string out_dir = std::filesystem::temp_directory_path().string();
  CLI::App app{"mcap_write_bench: MCAP recording speed and size per pose"};
  app.add_option("--poses", n, "poses to write")->check(CLI::Range(1, 10'000'000))->capture_default_str();
  app.add_option("--zstd-level", zstd_level, "zstd compression level of the compressed run")
      ->check(CLI::Range(1, 19))
      ->capture_default_str();
  app.add_option("--out-dir", out_dir, "where the files go (deleted afterwards)")->check(CLI::ExistingDirectory);
  CLI11_PARSE(app, argc, argv);
  std::vector<v1::PoseUpdate> poses;
  poses.reserve(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) poses.push_back(Pose(k));
  nlohmann::json out = nlohmann::json::array();
  for (bool zstd : {true, false}) {
    const auto file = std::filesystem::path(out_dir) / (std::string("mcap_write_bench_") + (zstd ? "zstd" : "none") + ".mcap");
    out.push_back(Run(poses, file, zstd, zstd_level));
    std::filesystem::remove(file);
  }
  std::cout << out.dump(2) << "\n";
  return 0;
}
