// A session's run loop built on the session thread (see DeferredRunLoop).
#pragma once

#include "pipeline/frame_loop.hpp"

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

namespace locaid::server {

// Builds its run loop on the session thread at the first Step (slow inputs
// such as rendering a synthetic drive do not block the RPC); controls given
// before that are replayed onto it. A throwing factory fails the session.
class DeferredRunLoop : public pipeline::RunLoop {
 public:
  // The factory gets the cancel flag Cancel() sets (e.g. to stop a render).
  using Factory = std::function<std::unique_ptr<pipeline::RunLoop>(const std::atomic<bool>& cancel)>;
  // on_release runs once the session's run loop has ended (Release), e.g. to
  // delete the drive it rendered.
  DeferredRunLoop(Factory factory, int64_t total_frames, std::function<void()> on_release = {})
      : factory_(std::move(factory)), total_(total_frames), on_release_(std::move(on_release)) {}
  ~DeferredRunLoop() override { Release(); }
  void Release() override {
    std::unique_ptr<pipeline::RunLoop> done;
    {
      std::lock_guard lock(inner_mu_);
      done = std::move(inner_);
    }
    done.reset();
    if (on_release_) std::exchange(on_release_, nullptr)();
  }

  // Step and Release run on the session thread; Cancel on any thread.
  pipeline::StepResult Step() override {
    if (!ready_) {
      std::unique_ptr<pipeline::RunLoop> made = factory_(cancel_);
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
  void StartOutageNow(double d) override { Do([d](pipeline::RunLoop& p) { p.StartOutageNow(d); }); }
  void StopOutage() override { Do([](pipeline::RunLoop& p) { p.StopOutage(); }); }
  void AddOutageWindow(double s, double d) override { Do([s, d](pipeline::RunLoop& p) { p.AddOutageWindow(s, d); }); }
  void InjectCameraFault(pipeline::CameraFaultAction a, const sim::CameraFaultWindow& f) override {
    Do([a, f](pipeline::RunLoop& p) { p.InjectCameraFault(a, f); });
  }
  void SetPairRunner(const PairRunner* r) override { Do([r](pipeline::RunLoop& p) { p.SetPairRunner(r); }); }
  void SetScenario(const sim::Scenario& sc) override { Do([sc](pipeline::RunLoop& p) { p.SetScenario(sc); }); }
  bool origin(double* a, double* b, double* c) const override {
    std::lock_guard lock(inner_mu_);
    return inner_ && inner_->origin(a, b, c);
  }
  pipeline::LiveInputStats input_stats() const override {
    std::lock_guard lock(inner_mu_);
    return inner_ ? inner_->input_stats() : pipeline::LiveInputStats{};
  }

 private:
  void Do(std::function<void(pipeline::RunLoop&)> op) {
    if (inner_) op(*inner_);
    else pending_.push_back(std::move(op));
  }
  Factory factory_;
  int64_t total_;
  std::function<void()> on_release_;
  std::atomic<bool> cancel_{false}, ready_{false};
  mutable std::mutex inner_mu_;  // inner_ between Cancel (any thread) and Step / Release
  std::unique_ptr<pipeline::RunLoop> inner_;
  std::vector<std::function<void(pipeline::RunLoop&)>> pending_;
};

}  // namespace locaid::server
