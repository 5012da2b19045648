// locaid-vo: stereo visual odometry alone on a KITTI raw drive (sync or
// extract) or an odometry sequence; writes cam0 poses (world = cam0 at the
// first tracked frame).
//
//   locaid-vo --drive DIR --out-tum FILE [--out-kitti FILE] [--json] [VO flags]
//
// VO flags (vo/apps/vo_flags.hpp, shared with vo_bench): --method NAME,
// --max-frames N, --cpu-time, --window-keyframes N, --klt-guess full|rotation,
// --frame-step N.
//
// Frames whose images are missing are skipped (Track is not called; the next
// motion spans the gap) and listed on stderr and in the JSON. The TUM file has
// one line per tracked frame; the KITTI file one line per frame index, missing
// frames interpolated in time. Progress goes to stderr; --json prints one
// object on stdout with timings of the VO alone (image loading excluded).
#include "kitti/dataset.hpp"
#include "kitti/pose_io.hpp"
#include "vo/apps/vo_flags.hpp"
#include "vo/apps/drive_runner.hpp"
#include "vo/stereo_odometry.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <cstdio>
#include <exception>
#include <iostream>

int main(int argc, char** argv) {
  using namespace locaid;
  CLI::App app{"Stereo visual odometry on a KITTI drive"};
  std::string drive, out_tum, out_kitti;
  bool json = false;
  vo::VoFlags flags;
  app.add_option("--drive", drive, "raw drive folder or odometry sequence folder")->required();
  app.add_option("--out-tum", out_tum, "TUM pose file to write")->required();
  app.add_option("--out-kitti", out_kitti, "KITTI pose file to write (one line per tracked frame index)");
  vo::AddVoFlags(app, flags, vo::StereoOdometryMethods());
  app.add_flag("--json", json, "print a JSON summary on stdout");
  CLI11_PARSE(app, argc, argv);
  if (const std::string problem = vo::VoFlagsProblem(flags, {flags.method}); !problem.empty()) {
    std::cerr << "locaid-vo: " << problem << "\n";
    return 2;
  }

  cv::setNumThreads(1);
  try {
    const auto dataset = kitti::OpenDataset(drive);
    const vo::DriveRun run = vo::RunOnDataset(
        *dataset, vo::MakeDriveRunConfig(flags, flags.method), [](const vo::FrameResult& f, size_t total) {
          if (f.missing) {
            std::fprintf(stderr, "frame %zu: skipped (%s)\n", f.index, f.missing_reason.c_str());
          } else if (f.index % 50 == 0 || f.index + 1 == total ||
                     f.motion.status != vo::Status::kOk) {
            std::fprintf(stderr, "frame %zu/%zu: %s, %d inliers, %.1f ms\n", f.index + 1, total,
                         vo::ToString(f.motion.status), f.motion.inliers, f.motion.total_ms);
          }
        });

    std::vector<kitti::StampedPose> tum;
    for (const vo::FrameResult& f : run.frames)
      if (!f.missing) tum.push_back({f.tum_time_s, f.T_world_cam});
    kitti::WriteTumPoses(out_tum, tum);
    if (!out_kitti.empty()) kitti::WriteKittiPoses(out_kitti, vo::PosesPerFrame(run));

    const vo::TimingSummary s = vo::Summarize(run);
    std::fprintf(stderr, "%d frames tracked, %d missing, %d lost, %d degraded; VO %.2f ms median, %.2f ms p95\n",
                 s.frames, s.missing_frames, s.lost_frames, s.degraded_frames,
                 s.ms_per_frame_median, s.ms_per_frame_p95);
    if (json) {
      nlohmann::json j;
      j["drive"] = drive;
      j["method"] = flags.method;
      j["frame_step"] = flags.frame_step;
      vo::AddRunSummaryJson(j, s, flags);
      nlohmann::json missing = nlohmann::json::array();
      for (const vo::FrameResult& f : run.frames)
        if (f.missing) missing.push_back(f.index);
      j["missing_frames"] = missing;
      std::cout << j.dump(2) << std::endl;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "locaid-vo: %s\n", e.what());
    return 1;
  }
  return 0;
}
