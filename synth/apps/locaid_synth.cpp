// locaid-synth: render a synthetic KITTI raw *sync* drive (stereo + OXTS +
// calibration + ground truth) with locaid's own software renderer.
//
//   locaid-synth --out DIR [--frames N | --length-m M] [--seed S] [--width W --height H]
//                [--speed-min V --speed-max V] [--radius-min R --radius-max R]
//                [--rate-hz HZ] [--anisotropic] [--quiet]
//   locaid-synth --out DIR --route POSES [--times TIMES] [--route-start-frame K]
//                [--frames N | --length-m M] ...       (follow a real KITTI drive)
#include "synth/synth.hpp"

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>

int main(int argc, char** argv) {
  namespace synth = locaid::synth;
  synth::SynthConfig cfg;
  std::string out;
  bool quiet = false;
  CLI::App app{"Render a synthetic KITTI raw sync drive (stereo PNGs, OXTS, calib, ground truth)."};
  app.add_option("--out", out, "date folder to write (created; the drive goes into DIR/<date>_drive_NNNN_sync)")
      ->required();
  app.add_option("--frames", cfg.frames, "number of stereo frames (with --route: at most)")->check(CLI::Range(2, 1000000));
  app.add_option("--length-m", cfg.length_m, "drive this distance instead of --frames (metres; with --route: at most)")
      ->check(CLI::Range(1.0, 100000.0));
  app.add_option("--seed", cfg.seed, "random seed (same seed -> identical files)");
  app.add_option("--width", cfg.width, "image width (px)")->check(CLI::Range(64, 4096));
  app.add_option("--height", cfg.height, "image height (px)")->check(CLI::Range(48, 4096));
  app.add_option("--date", cfg.date, "date folder / timestamp date, YYYY_MM_DD");
  app.add_option("--drive", cfg.drive_number, "drive number")->check(CLI::Range(0, 9999));
  app.add_option("--noise", cfg.noise_sigma_dn, "sensor noise sigma (grey levels)")->check(CLI::Range(0.0, 50.0));
  app.add_option("--png-level", cfg.png_compression, "PNG zlib level 0..9, -1 = fast (SUB filter, level 1, RLE)")->check(CLI::Range(-1, 9));
  app.add_option("--rate-hz", cfg.frame_rate_hz, "camera and OXTS rate (Hz; KITTI: 10)")->check(CLI::Range(1.0, 100.0));
  auto* route = app.add_option(
      "--route", cfg.route_poses,
      "follow a real drive: a KITTI odometry ground-truth poses file (poses/NN.txt; 12 numbers a line, "
      "T_world_cam0). The vehicle drives a smooth fit of it (within a few cm; stops hold still), which is the "
      "drive's ground truth; OXTS are its exact derivatives. Without --frames/--length-m: up to the last pose");
  app.add_option("--times", cfg.route_times, "with --route: the poses' times (sequences/NN/times.txt, s); default 10 Hz")
      ->needs(route);
  app.add_option("--route-start-frame", cfg.route_start_frame,
                 "with --route: the first pose used (image 0 is at its time; default 0)")
      ->check(CLI::NonNegativeNumber)
      ->needs(route);
  const char* kNotWithRoute = "; not with --route";
  app.add_option("--speed-min", cfg.speed_min_mps,
                 std::string("lowest planned speed (m/s; wins over the curve limit)") + kNotWithRoute)
      ->check(CLI::Range(1.0, 60.0))
      ->excludes(route);
  app.add_option("--speed-max", cfg.speed_max_mps, std::string("highest planned speed (m/s)") + kNotWithRoute)
      ->check(CLI::Range(1.0, 60.0))
      ->excludes(route);
  app.add_option("--radius-min", cfg.curve_radius_min_m, std::string("sharpest curve radius (m)") + kNotWithRoute)
      ->check(CLI::Range(10.0, 10000.0))
      ->excludes(route);
  app.add_option("--radius-max", cfg.curve_radius_max_m, std::string("widest curve radius (m)") + kNotWithRoute)
      ->check(CLI::Range(10.0, 10000.0))
      ->excludes(route);
  app.add_flag("--anisotropic", cfg.anisotropic_filtering,
               "anisotropic texture filtering: the road stays sharp sideways into the distance (about 2x slower; "
               "other bytes than without)");
  app.add_flag("--quiet,-q", quiet, "no progress output");
  CLI11_PARSE(app, argc, argv);
  if (!cfg.route_poses.empty() && app.count("--frames") == 0) cfg.frames = 0;  // up to the last pose

  cv::setNumThreads(1);
  const bool tty = isatty(STDERR_FILENO) != 0;
  const auto start = std::chrono::steady_clock::now();
  int last_print = 0;
  auto progress = [&](int frame, int total) {
    if (quiet || frame == 0) return;  // frame 0: a set-up step
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double fps = el > 0 ? frame / el : 0;
    const double eta = fps > 0 ? (total - frame) / fps : 0;
    if (tty) {
      std::fprintf(stderr, "\rframe %d/%d  %.1f fps  ETA %.0f s   ", frame, total, fps, eta);
      if (frame == total) std::fprintf(stderr, "\n");
    } else if (frame == total || frame - last_print >= std::max(50, total / 10)) {
      std::fprintf(stderr, "frame %d/%d  %.1f fps  ETA %.0f s\n", frame, total, fps, eta);
      last_print = frame;
    }
  };
  try {
    const synth::SynthSummary s = synth::GenerateDrive(cfg, out, progress);
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!quiet)
      std::printf(
          "wrote %s: %d stereo frames %dx%d, %.1f s, %.1f m, speed %.1f..%.1f m/s, %.2f s wall (%.1f frames/s)\n",
          s.drive_dir.string().c_str(), s.frames, s.camera.width, s.camera.height, s.duration_s, s.distance_m,
          s.min_speed_mps, s.max_speed_mps, el, s.frames / el);
    if (!quiet && s.route_first_pose >= 0)
      std::printf("route: poses %d..%d of %s%s\n", s.route_first_pose, s.route_last_pose, cfg.route_poses.string().c_str(),
                  s.route_cut ? " (the poses end there, before the frames or length asked for)" : "");
  } catch (const std::exception& e) {
    if (tty && !quiet) std::fprintf(stderr, "\n");
    std::fprintf(stderr, "locaid-synth: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
