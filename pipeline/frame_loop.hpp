// The one frame loop: source -> scenario stage -> camera faults -> estimator,
// one StepResult per Step(). A FrameSource (KITTI drive, synthetic drive,
// frames and samples a client pushes) yields frames and samples;
// the ScenarioStage (scenario_stage.hpp) makes the measurements and owns GPS
// availability; the CameraFaultStage (camera_faults.hpp) does to the images
// what the scenario's `camera:` list and injected faults say; the Estimator
// (the Localizer: VO + EKF) fuses them. Every session of the gRPC
// server runs one, and so does locaid-replay.
//
// Threading: Step() and Release() are called from one thread (the session's
// or the replay's); Cancel() and Wake() from any thread; the GPS controls
// from the stepping thread (a session posts them there).
#pragma once

#include "sim/scenario.hpp"
#include "fusion/types.hpp"
#include "pipeline/camera_faults.hpp"
#include "pipeline/frame_source.hpp"
#include "pipeline/localizer.hpp"
#include "pipeline/scenario_stage.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace locaid::pipeline {

// Ground truth at a pose's time (dataset sources).
struct TruthPose {
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  std::optional<Eigen::Isometry3d> T_enu_body;  // once the filter's ENU origin is known
};

struct StepResult {
  enum class Kind {
    kPose,     // `frame` holds the fused pose
    kSkipped,  // frame without both images: skipped (error says which)
    kCorrupt,  // frame could not be decoded / wrong size: skipped
    kIdle,     // nothing available yet (live input): call again
    kEnd,      // input exhausted
    kFused,    // samples between frames fused (live input): no pose
  };
  Kind kind = Kind::kIdle;
  int64_t frame_index = -1;
  int64_t t_ns = 0;  // sensor time of the frame (also for skipped frames)
  // kPose: the estimator's result. frame.gps_feeds lists every fix fused
  // since the previous pose.
  FrameResult frame;
  std::optional<TruthPose> truth;
  int oxts_bad_lines = 0;  // bad OXTS records met while producing this result
  std::string error;       // kSkipped / kCorrupt / bad OXTS: file and reason
  // Wall time spent on this frame (decode, VO, EKF), ms. < 0: the caller
  // measures the duration of Step() instead (right for file sources).
  double processing_ms = -1;
};

// A run as a session (or a replay) steps through it. FrameLoop is the real
// one; the server wraps it to build it on the session thread
// (server/deferred_run_loop.hpp), tests plug in fakes.
class RunLoop {
 public:
  virtual ~RunLoop() = default;
  virtual StepResult Step() = 0;
  // Unblocks a Step() waiting for input (live sources); Step then returns
  // kEnd. Thread-safe.
  virtual void Cancel() {}
  // Makes a Step() that waits for input return kIdle soon, so commands
  // posted to the session apply before the next frame. Thread-safe.
  virtual void Wake() {}
  // Frames in the input, 0 when unknown (live).
  virtual int64_t total_frames() const { return 0; }
  // False while the input is still being prepared (a synthetic drive
  // rendering). Any thread.
  virtual bool ready() const { return true; }
  // The stepping thread is done: free what the pipeline holds (files,
  // images). Called once, from the stepping thread, as it ends.
  virtual void Release() {}
  // GPS control, applied from the next frame on. Times are relative to the
  // first frame.
  virtual void StartOutageNow(double duration_s) = 0;  // 0 = until StopOutage
  virtual void StopOutage() = 0;
  virtual void AddOutageWindow(double start_s, double duration_s) = 0;
  // Camera faults, applied from the next frame on (CameraFaultStage::Inject;
  // times relative to the first frame). Throws std::invalid_argument for
  // out-of-range values.
  virtual void InjectCameraFault(CameraFaultAction action, const sim::CameraFaultWindow& fault) = 0;
  // Throws std::invalid_argument when the scenario is invalid.
  virtual void SetScenario(const sim::Scenario& scenario) = 0;
  // ENU origin once known.
  virtual bool origin(double* lat_deg, double* lon_deg, double* alt_m) const = 0;
  // Typed live input and GPS receiver counters. Any thread.
  virtual LiveInputStats input_stats() const { return {}; }
  // Who decodes each frame's two images (FrameSource::set_pair_runner);
  // nullptr: the stepping thread alone. From the stepping thread; `runner`
  // must outlive the steps.
  virtual void SetPairRunner(const PairRunner* /*runner*/) {}
};

class FrameLoop final : public RunLoop {
 public:
  // The camera faults are the scenario stage's scenario's (`camera:`).
  FrameLoop(std::unique_ptr<FrameSource> source, ScenarioStage scenario, std::unique_ptr<Estimator> estimator)
      : source_(std::move(source)),
        scenario_(std::move(scenario)),
        camera_faults_(scenario_.scenario()),
        estimator_(std::move(estimator)) {}

  // Reads the next item: its samples go through the scenario stage to
  // the estimator (so a fix reaches the filter before VO runs on the frame),
  // then a frame, with the active camera faults applied, is processed.
  StepResult Step() override;
  // A message for the user (e.g. OutageCoverageWarning) that the first pose's
  // result carries in `error` when it has no input error of its own.
  void set_notice(std::string notice) { notice_ = std::move(notice); }
  void Cancel() override { source_->Cancel(); }
  void Wake() override { source_->Wake(); }
  void SetPairRunner(const PairRunner* runner) override { source_->set_pair_runner(runner); }
  int64_t total_frames() const override { return source_->total_frames(); }
  void StartOutageNow(double duration_s) override { scenario_.StartOutageNow(duration_s); }
  void StopOutage() override { scenario_.StopOutage(); }
  void AddOutageWindow(double start_s, double duration_s) override { scenario_.AddOutageWindow(start_s, duration_s); }
  void InjectCameraFault(CameraFaultAction action, const sim::CameraFaultWindow& fault) override {
    camera_faults_.Inject(action, fault);
  }
  // Both stages take the new scenario (validated before either changes).
  void SetScenario(const sim::Scenario& scenario) override;
  bool origin(double* lat_deg, double* lon_deg, double* alt_m) const override;
  // The source's counters plus the arrival-to-use latency of received fixes.
  LiveInputStats input_stats() const override;

 private:
  // Records each received fix's time from arrival to use.
  void RecordFixLatency(const SampleBatch& samples);
  // The truth pose in the filter's ENU frame (no T_enu_body before it has an origin).
  TruthPose Truth(const fusion::TruthSample& sample) const;

  std::unique_ptr<FrameSource> source_;
  ScenarioStage scenario_;
  CameraFaultStage camera_faults_;
  std::unique_ptr<Estimator> estimator_;
  // Arrival-to-use times of the last kLatencyWindow received fixes, ms.
  static constexpr size_t kLatencyWindow = 256;
  mutable std::mutex latency_mu_;
  std::deque<double> fix_latency_ms_;
  bool had_frame_ = false;
  std::string notice_;
};

}  // namespace locaid::pipeline
