#include "pipeline/camera_faults.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace locaid::pipeline {
namespace {

using sim::CameraFaultKind;

constexpr double kMaxSeconds = 1e6;  // seconds become int64 nanoseconds (as outages)

int64_t Nanoseconds(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

void CheckFault(const sim::CameraFaultWindow& fault) {
  const std::string problem = sim::CameraFaultParameterProblem(fault);
  if (!problem.empty()) throw std::invalid_argument(std::string("camera fault ") + ToString(fault.kind) + ": " + problem);
}

void CheckSeconds(const char* what, double v, bool zero_ok) {
  if (std::isfinite(v) && (zero_ok ? v >= 0 : v > 0) && v <= kMaxSeconds) return;
  std::ostringstream os;
  os << "camera fault: " << what << " must be in " << (zero_ok ? "[0" : "(0") << ", 1e6] s, got " << v;
  throw std::invalid_argument(os.str());
}

// The seed of the image noise: the scenario's, kept apart from its GPS / IMU streams.
cv::RNG SeededRng(uint64_t seed) { return cv::RNG(seed * 0x9E3779B97F4A7C15ULL + 0x63616d657261ULL); }

}  // namespace

CameraFaultStage::CameraFaultStage(const sim::Scenario& scenario) { SetScenario(scenario); }

CameraFaultStage::Window CameraFaultStage::Relative(const sim::CameraFaultWindow& fault) {
  Window w{fault, Nanoseconds(fault.start_s), 0};
  w.end_ns = w.start_ns + Nanoseconds(fault.duration_s);
  return w;
}

void CameraFaultStage::SetScenario(const sim::Scenario& scenario) {
  sim::ValidateCameraFaults(scenario);
  scenario_windows_.clear();
  for (const sim::CameraFaultWindow& f : scenario.camera_faults) scenario_windows_.push_back(Relative(f));
  rng_ = SeededRng(scenario.seed);
}

void CameraFaultStage::StartNow(const sim::CameraFaultWindow& fault, double duration_s) {
  CheckFault(fault);
  CheckSeconds("duration_s", duration_s, true);
  pending_now_.emplace_back(fault, duration_s);
}

void CameraFaultStage::Stop() {
  injected_.clear();
  pending_now_.clear();
}

void CameraFaultStage::AddWindow(const sim::CameraFaultWindow& fault) {
  CheckFault(fault);
  CheckSeconds("start_s", fault.start_s, true);
  CheckSeconds("duration_s", fault.duration_s, false);
  injected_.push_back(Relative(fault));
}

void CameraFaultStage::Inject(CameraFaultAction action, const sim::CameraFaultWindow& fault) {
  switch (action) {
    case CameraFaultAction::kStartNow: StartNow(fault, fault.duration_s); return;
    case CameraFaultAction::kStop: Stop(); return;
    case CameraFaultAction::kWindow: AddWindow(fault); return;
  }
}

std::vector<const sim::CameraFaultWindow*> CameraFaultStage::ActiveAt(int64_t t_rel_ns) const {
  std::vector<const sim::CameraFaultWindow*> active;
  for (const auto* list : {&scenario_windows_, &injected_})
    for (const Window& w : *list)
      if (w.start_ns <= t_rel_ns && t_rel_ns < w.end_ns) active.push_back(&w.fault);
  return active;
}

void CameraFaultStage::AddNoise(cv::Mat& image, double gain, double sigma_dn) {
  if (image.empty()) return;
  cv::Mat f;
  image.convertTo(f, CV_32F, gain);
  if (sigma_dn > 0) {
    cv::Mat noise(f.size(), f.type());
    rng_.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(sigma_dn));
    f += noise;
  }
  cv::Mat out;
  f.convertTo(out, image.type());  // rounds to nearest and saturates to 0..255
  image = out;                     // a new buffer: the source's image is not written
}

void CameraFaultStage::Apply(vo::StereoFrame& frame) {
  if (!first_frame_ns_) first_frame_ns_ = frame.t_ns;
  const int64_t t_rel = frame.t_ns - *first_frame_ns_;
  for (auto& [fault, duration_s] : std::exchange(pending_now_, {})) {
    Window w{fault, t_rel, duration_s > 0 ? t_rel + Nanoseconds(duration_s) : kForever};
    injected_.push_back(w);
  }
  const std::vector<const sim::CameraFaultWindow*> active = ActiveAt(t_rel);
  const auto has = [&](CameraFaultKind kind) {
    return std::any_of(active.begin(), active.end(), [kind](const auto* f) { return f->kind == kind; });
  };
  if (!has(CameraFaultKind::kFrozen)) frozen_.reset();
  if (!active.empty()) {
    // Optics, then sensor, then driver.
    for (const auto* f : active) {
      if (f->kind != CameraFaultKind::kBlur) continue;
      for (cv::Mat* image : {&frame.left, &frame.right}) {
        if (image->empty()) continue;
        cv::Mat out;
        cv::GaussianBlur(*image, out, cv::Size(0, 0), f->blur_sigma_px);
        *image = out;
      }
    }
    for (const auto* f : active) {
      if (f->kind != CameraFaultKind::kDark && f->kind != CameraFaultKind::kNoise) continue;
      const double gain = f->kind == CameraFaultKind::kDark ? f->gain : 1.0;
      AddNoise(frame.left, gain, f->noise_dn);
      AddNoise(frame.right, gain, f->noise_dn);
    }
    if (has(CameraFaultKind::kFrozen)) {
      if (!frozen_) frozen_.emplace(last_left_.clone(), last_right_.clone());
      frame.left = frozen_->first;
      frame.right = frozen_->second;
    }
    if (has(CameraFaultKind::kDrop) || has(CameraFaultKind::kRightOnly)) frame.left = cv::Mat();
    if (has(CameraFaultKind::kDrop) || has(CameraFaultKind::kLeftOnly)) frame.right = cv::Mat();
  }
  // Held by reference: sources hand over a new pair each frame, nobody writes it.
  last_left_ = frame.left;
  last_right_ = frame.right;
  // Expired injected windows go.
  injected_.erase(std::remove_if(injected_.begin(), injected_.end(), [t_rel](const Window& w) { return w.end_ns <= t_rel; }),
                  injected_.end());
}

}  // namespace locaid::pipeline
