#include "vo/apps/drive_runner.hpp"

#include "kitti/types.hpp"
#include "vo/stereo_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <exception>
#include <Eigen/Geometry>
#include <vector>

namespace locaid::vo {
namespace {

double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::floor(q * (v.size() - 1) + 0.5)));
  return v[k];
}

}  // namespace

DriveRun RunOnDataset(const kitti::StereoDataset& dataset, const DriveRunConfig& config,
                      const DriveProgress& progress) {
  DriveRun run;
  run.method = config.method;
  DefaultConfig default_config;
  if (config.window_keyframes >= 0) default_config.window_keyframes = config.window_keyframes;
  if (config.klt_guess_translation) default_config.klt_guess_translation = *config.klt_guess_translation;
  const auto vo = MakeStereoOdometry(config.method, dataset.camera(), config.clock, default_config);
  size_t n = dataset.size();
  if (config.max_frames > 0) n = std::min(n, config.max_frames);
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  bool started = false;
  const size_t step = std::max<size_t>(config.frame_step, 1);
  for (size_t i = 0; i < n; i += step) {
    FrameResult fr;
    fr.index = i;
    fr.t_ns = dataset.time_ns(i);
    fr.tum_time_s = dataset.tum_time_s(i);
    StereoFrame frame;
    frame.t_ns = fr.t_ns;
    if (!dataset.has_stereo(i)) {
      fr.missing = true;
      fr.missing_reason = "image missing";
    } else {
      try {
        const kitti::StereoImages images = dataset.Load(i);
        frame.left = images.left;
        frame.right = images.right;
      } catch (const std::exception& e) {
        fr.missing = true;
        fr.missing_reason = e.what();
      }
    }
    if (!fr.missing) {
      const double cpu0 = ThreadCpuMs();
      fr.motion = vo->Track(frame);
      fr.track_cpu_ms = ThreadCpuMs() - cpu0;
      if (started) T_world_cam = T_world_cam * fr.motion.T_prev_curr;
      started = true;
    }
    fr.T_world_cam = T_world_cam;
    run.frames.push_back(fr);
    if (progress) progress(run.frames.back(), n);
  }
  return run;
}

std::vector<Eigen::Isometry3d> PosesPerFrame(const DriveRun& run) {
  std::vector<Eigen::Isometry3d> poses;
  for (const FrameResult& f : run.frames) poses.push_back(f.T_world_cam);
  for (size_t i = 0; i < run.frames.size(); ++i) {
    if (!run.frames[i].missing) continue;
    size_t a = i, b = i;
    while (a > 0 && run.frames[a].missing) --a;
    while (b < run.frames.size() && run.frames[b].missing) ++b;
    if (run.frames[a].missing || b >= run.frames.size()) continue;  // hold
    const double span = static_cast<double>(run.frames[b].t_ns - run.frames[a].t_ns);
    const double s = span > 0 ? (run.frames[i].t_ns - run.frames[a].t_ns) / span : 0.0;
    const Eigen::Isometry3d T_a_b = poses[a].inverse() * poses[b];
    poses[i] = poses[a] * ScaleMotion(T_a_b, std::clamp(s, 0.0, 1.0));
  }
  return poses;
}

TimingSummary Summarize(const DriveRun& run) {
  TimingSummary s;
  std::vector<double> totals, cpu;
  std::map<std::string, std::vector<double>> stages;
  for (const FrameResult& f : run.frames) {
    if (f.missing) {
      ++s.missing_frames;
      continue;
    }
    ++s.frames;
    if (f.motion.status == Status::kLost) ++s.lost_frames;
    if (f.motion.status == Status::kDegraded) ++s.degraded_frames;
    totals.push_back(f.motion.total_ms);
    cpu.push_back(f.track_cpu_ms);
    for (const auto& [name, ms] : f.motion.timings) stages[name].push_back(ms);
  }
  s.ms_per_frame_median = Percentile(totals, 0.5);
  s.ms_per_frame_p95 = Percentile(totals, 0.95);
  s.cpu_ms_per_frame_median = Percentile(cpu, 0.5);
  s.cpu_ms_per_frame_p95 = Percentile(cpu, 0.95);
  double sum = 0;
  for (double t : totals) sum += t;
  s.ms_per_frame_mean = totals.empty() ? 0 : sum / totals.size();
  for (auto& [name, v] : stages) {
    // Stages that did not run on a frame count as 0 ms there.
    v.resize(totals.size(), 0.0);
    s.stage_median_ms[name] = Percentile(v, 0.5);
  }
  return s;
}

}  // namespace locaid::vo
