// SessionPipeline = FrameSource + FrameEstimator. The estimator is the
// Localizer (VO -> EKF) in the server; tests and benchmarks may plug another.
#pragma once

#include "core/stereo_camera.hpp"
#include "server/frame_source.hpp"
#include "server/gps_receiver.hpp"
#include "fusion/geodesy.hpp"
#include "pipeline/localizer.hpp"
#include "server/session_pipeline.hpp"

#include <atomic>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <utility>

namespace locaid::server {

struct Estimate {
  fusion::FusedPose pose;
  std::vector<FixSeen> gps_fixes;  // fixes fed with this frame
  int vo_inliers = 0;
  vo::Status vo_status = vo::Status::kLost;
  bool in_outage = false;
};

class FrameEstimator {
 public:
  virtual ~FrameEstimator() = default;
  virtual Estimate Process(const vo::StereoFrame& frame, std::span<const kitti::OxtsSample> oxts) = 0;
  // Typed live input (IMU samples, fixes), fused as it comes, before the
  // frame it arrived with. Estimators without typed input ignore it.
  virtual std::vector<FixSeen> FuseSensors(const pipeline::SensorBatch& /*batch*/) { return {}; }
  virtual void ScheduleOutage(int64_t start_ns, int64_t end_ns) = 0;
  virtual void StartOutageNow() = 0;
  virtual void StopOutageNow() = 0;
  virtual void SetScenario(const fusion::Scenario& scenario) = 0;
  virtual bool origin(double* lat_deg, double* lon_deg, double* alt_m) const = 0;
};

struct EstimatorSetup {
  StereoCamera camera;
  Eigen::Isometry3d T_cam0_imu = Eigen::Isometry3d::Identity();
  fusion::Scenario scenario;
  std::string vo_method = "default";
  Eigen::Vector3d gps_antenna_body_m = Eigen::Vector3d::Zero();  // lever arm (LiveSource)
};
// Throws std::invalid_argument (unknown VO method, bad scenario).
using EstimatorFactory = std::function<std::unique_ptr<FrameEstimator>(const EstimatorSetup&)>;

// The production estimator: pipeline::Localizer (pipeline_adapter.cpp).
std::unique_ptr<FrameEstimator> MakeLocalizerEstimator(const EstimatorSetup& setup);

// Scenario from a built-in name or YAML text, validated; throws
// std::invalid_argument with the reason (pipeline_adapter.cpp).
fusion::Scenario ScenarioFromName(const std::string& name);
fusion::Scenario ScenarioFromYaml(const std::string& yaml);
fusion::Scenario PlaceScenarioOutages(fusion::Scenario scenario, double drive_duration_s);

class SourcePipeline : public SessionPipeline {
 public:
  SourcePipeline(std::unique_ptr<FrameSource> source, std::unique_ptr<FrameEstimator> estimator)
      : source_(std::move(source)), estimator_(std::move(estimator)) {}

  StepResult Step() override;
  void Cancel() override { source_->Cancel(); }
  void Wake() override { source_->Wake(); }
  int64_t total_frames() const override { return source_->total_frames(); }
  void StartOutageNow(double duration_s) override;
  void StopOutage() override { estimator_->StopOutageNow(); }
  void AddOutageWindow(double start_s, double duration_s) override;
  void SetScenario(const fusion::Scenario& scenario) override { estimator_->SetScenario(scenario); }
  bool origin(double* lat_deg, double* lon_deg, double* alt_m) const override {
    return estimator_->origin(lat_deg, lon_deg, alt_m);
  }
  LiveInputStats input_stats() const override;
  // The truth pose in the filter's ENU frame (null before it has an origin).
  std::optional<TruthPose> Truth(const kitti::OxtsRecord& oxts) const;
  // A GPS receiver feeding the (live) source; stopped before the source goes.
  void set_receiver(std::unique_ptr<GpsdReceiver> receiver) { receiver_ = std::move(receiver); }

 private:
  // Fuses typed data, then records each fix's time from arrival to use.
  void FuseTyped(const SourceItem& item);

  std::unique_ptr<FrameSource> source_;
  std::unique_ptr<FrameEstimator> estimator_;
  std::unique_ptr<GpsdReceiver> receiver_;  // after source_: destroyed first
  // Arrival-to-use times of the last kLatencyWindow received fixes, ms.
  static constexpr size_t kLatencyWindow = 256;
  mutable std::mutex latency_mu_;
  std::deque<double> fix_latency_ms_;
  std::optional<int64_t> first_t_ns_;
  int64_t last_t_ns_ = 0;
  std::vector<std::pair<double, double>> early_windows_;  // before the first frame
  // OXTS samples that came with skipped / corrupt items: given to the
  // estimator with the next good frame instead of being lost.
  std::vector<kitti::OxtsSample> carried_oxts_;
  std::vector<FixSeen> fixes_seen_;  // typed fixes fused since the last pose
  mutable std::optional<fusion::EnuFrame> enu_;  // the filter's ENU frame, for the truth
};

}  // namespace locaid::server

namespace locaid::server {

// Builds its pipeline on the session thread at the first Step (slow inputs
// such as rendering a synthetic drive do not block the RPC); controls given
// before that are replayed onto it. A throwing factory fails the session.
class DeferredPipeline : public SessionPipeline {
 public:
  // The factory gets the cancel flag Cancel() sets (e.g. to stop a render).
  using Factory = std::function<std::unique_ptr<SessionPipeline>(const std::atomic<bool>& cancel)>;
  // on_release runs once the session's pipeline has ended (Release), e.g. to
  // delete the drive it rendered.
  DeferredPipeline(Factory factory, int64_t total_frames, std::function<void()> on_release = {})
      : factory_(std::move(factory)), total_(total_frames), on_release_(std::move(on_release)) {}
  ~DeferredPipeline() override { Release(); }
  void Release() override {
    std::unique_ptr<SessionPipeline> done;
    {
      std::lock_guard lock(inner_mu_);
      done = std::move(inner_);
    }
    done.reset();
    if (on_release_) std::exchange(on_release_, nullptr)();
  }

  // Step and Release run on the session thread; Cancel on any thread.
  StepResult Step() override {
    if (!ready_) {
      std::unique_ptr<SessionPipeline> made = factory_(cancel_);
      for (auto& op : pending_) op(*made);
      pending_.clear();
      std::lock_guard lock(inner_mu_);
      inner_ = std::move(made);
      ready_ = true;
    }
    return inner_->Step();
  }
  void Cancel() override {
    cancel_ = true;
    std::lock_guard lock(inner_mu_);
    if (inner_) inner_->Cancel();
  }
  bool ready() const override { return ready_; }
  int64_t total_frames() const override { return total_; }
  void StartOutageNow(double d) override { Do([d](SessionPipeline& p) { p.StartOutageNow(d); }); }
  void StopOutage() override { Do([](SessionPipeline& p) { p.StopOutage(); }); }
  void AddOutageWindow(double s, double d) override { Do([s, d](SessionPipeline& p) { p.AddOutageWindow(s, d); }); }
  void SetScenario(const fusion::Scenario& sc) override { Do([sc](SessionPipeline& p) { p.SetScenario(sc); }); }
  bool origin(double* a, double* b, double* c) const override {
    std::lock_guard lock(inner_mu_);
    return inner_ && inner_->origin(a, b, c);
  }
  LiveInputStats input_stats() const override {
    std::lock_guard lock(inner_mu_);
    return inner_ ? inner_->input_stats() : LiveInputStats{};
  }

 private:
  void Do(std::function<void(SessionPipeline&)> op) {
    if (inner_) op(*inner_);
    else pending_.push_back(std::move(op));
  }
  Factory factory_;
  int64_t total_;
  std::function<void()> on_release_;
  std::atomic<bool> cancel_{false}, ready_{false};
  mutable std::mutex inner_mu_;  // inner_ between Cancel (any thread) and Step / Release
  std::unique_ptr<SessionPipeline> inner_;
  std::vector<std::function<void(SessionPipeline&)>> pending_;
};

}  // namespace locaid::server
