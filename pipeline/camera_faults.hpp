// The camera fault stage: what happens to a stereo pair between the source
// and VO. It applies the scenario's `camera:` windows (fusion::
// CameraFaultWindow) and faults injected at run time to each frame:
//
//   dark        both images x gain + Gaussian noise of noise_dn, rounded, clamped to 0..255
//   noise       + Gaussian noise of noise_dn
//   blur        Gaussian blur of blur_sigma_px
//   frozen      the last pair delivered before the fault started, repeated
//               with the new time stamps (a camera driver resending its buffer)
//   drop        both images missing (empty cv::Mat)
//   left_only   the right image missing
//   right_only  the left image missing
//
// Several active faults apply in the camera's order: blur (optics), dark and
// noise (sensor), then frozen, drop, left_only, right_only (driver). Times are
// sensor time relative to the first frame the stage sees; a window covers
// [start, start + duration). The noise is seeded from Scenario::seed:
// the same frames give the same images.
//
// Bounds: the stage holds one stereo pair for `frozen` (a reference to the
// last delivered pair, copied when a freeze starts; the copy lives while a
// freeze is active), and no other image. With no fault active a frame passes
// untouched (no copy, no cost).
//
// Threading: one thread (the session's or the replay's stepping thread).
#pragma once

#include "sim/scenario.hpp"
#include "vo/stereo_odometry.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

namespace locaid::pipeline {

// What a run-time request does with a fault (InjectCameraFault).
enum class CameraFaultAction {
  kStartNow,  // from the next frame on, for fault.duration_s (0 = until kStop)
  kStop,      // end every injected fault now (the scenario's stay)
  kWindow,    // [fault.start_s, fault.start_s + fault.duration_s) from the first frame
};

class CameraFaultStage {
 public:
  // Throws std::invalid_argument when the scenario is invalid.
  explicit CameraFaultStage(const sim::Scenario& scenario);

  // The frame with the faults active at frame.t_ns applied (in place).
  void Apply(vo::StereoFrame& frame);

  // Run-time faults. Throw std::invalid_argument for out-of-range parameters
  // (sim::CameraFaultParameterProblem) or times (start_s in [0, 1e6],
  // duration_s in (0, 1e6] for a window, [0, 1e6] for StartNow).
  void StartNow(const sim::CameraFaultWindow& fault, double duration_s);  // 0 = until Stop
  void Stop();  // ends every injected fault, active or scheduled
  void AddWindow(const sim::CameraFaultWindow& fault);
  // Any action above.
  void Inject(CameraFaultAction action, const sim::CameraFaultWindow& fault);

  // The scenario's windows and seed are replaced; the clock (first frame) and
  // the injected faults stay. Throws std::invalid_argument if invalid.
  void SetScenario(const sim::Scenario& scenario);

 private:
  static constexpr int64_t kForever = std::numeric_limits<int64_t>::max();
  // A fault over [start_ns, end_ns) relative to the first frame.
  struct Window {
    sim::CameraFaultWindow fault;
    int64_t start_ns = 0, end_ns = kForever;
  };
  static Window Relative(const sim::CameraFaultWindow& fault);
  std::vector<const sim::CameraFaultWindow*> ActiveAt(int64_t t_rel_ns) const;
  void AddNoise(cv::Mat& image, double gain, double sigma_dn);

  std::vector<Window> scenario_windows_;
  std::vector<Window> injected_;
  // StartNow requests waiting for the next frame: fault and duration.
  std::vector<std::pair<sim::CameraFaultWindow, double>> pending_now_;
  std::optional<int64_t> first_frame_ns_;
  cv::RNG rng_;
  // The pair last delivered (what a freeze repeats), and the frozen copy.
  cv::Mat last_left_, last_right_;
  std::optional<std::pair<cv::Mat, cv::Mat>> frozen_;
};

}  // namespace locaid::pipeline
