#include "sim/scenario.hpp"

#include <GeographicLib/LocalCartesian.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace locaid::sim {
namespace {

constexpr double kNsPerS = 1e9;

[[noreturn]] void Bad(const Scenario& s, const std::string& field, const std::string& why) {
  throw std::invalid_argument("scenario " + s.name + ": field " + field + ": " + why);
}

// A value as the user wrote it: 0.7, 5000, 1e+91 (std::to_string gives 0.700000).
std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

void RequireNonNegative(const Scenario& s, const char* field, double v) {
  if (!std::isfinite(v) || v < 0) Bad(s, field, "must be a finite number >= 0, got " + Num(v));
}

}  // namespace

const char* ToString(ImuGrade grade) {
  return grade == ImuGrade::kMems ? "mems" : "as-recorded";
}

const char* ToString(CameraFaultKind kind) {
  switch (kind) {
    case CameraFaultKind::kDark: return "dark";
    case CameraFaultKind::kNoise: return "noise";
    case CameraFaultKind::kBlur: return "blur";
    case CameraFaultKind::kFrozen: return "frozen";
    case CameraFaultKind::kDrop: return "drop";
    case CameraFaultKind::kLeftOnly: return "left_only";
    case CameraFaultKind::kRightOnly: return "right_only";
  }
  return "unknown";
}

std::string CameraFaultParameterProblem(const CameraFaultWindow& w) {
  std::ostringstream os;
  if (!(std::isfinite(w.gain) && w.gain > 0 && w.gain <= 1)) {
    os << "gain: must be in (0, 1], got " << w.gain;
  } else if (!(std::isfinite(w.noise_dn) && w.noise_dn >= 0 && w.noise_dn <= 255)) {
    os << "noise_dn: must be in [0, 255], got " << w.noise_dn;
  } else if (!(std::isfinite(w.blur_sigma_px) && w.blur_sigma_px > 0 && w.blur_sigma_px <= 50)) {
    // A Gaussian kernel of 6 sigma + 1 px: 50 px is already 301 px wide.
    os << "blur_sigma_px: must be in (0, 50], got " << w.blur_sigma_px;
  }
  return os.str();
}

void ValidateCameraFaults(const Scenario& s) {
  // Seconds become int64 nanoseconds, like the outages: bounded at 1e6 s.
  constexpr double kMaxS = 1e6;
  for (size_t i = 0; i < s.camera_faults.size(); ++i) {
    const CameraFaultWindow& w = s.camera_faults[i];
    const std::string f = "camera[" + std::to_string(i) + "]";
    if (!(std::isfinite(w.start_s) && w.start_s >= 0 && w.start_s <= kMaxS))
      Bad(s, f + ".start_s", "must be in [0, 1e6], got " + Num(w.start_s));
    if (!(std::isfinite(w.duration_s) && w.duration_s > 0 && w.duration_s <= kMaxS))
      Bad(s, f + ".duration_s", "must be in (0, 1e6] (end after start), got " + Num(w.duration_s));
    const std::string problem = CameraFaultParameterProblem(w);
    if (!problem.empty()) {
      const size_t colon = problem.find(':');
      Bad(s, f + "." + problem.substr(0, colon), problem.substr(colon + 2));
    }
  }
}

void ValidateScenario(const Scenario& s) {
  if (!s.gps_antenna_body_m.allFinite() || s.gps_antenna_body_m.norm() > 10.0)
    Bad(s, "gps.antenna_body_m", "must be finite and within 10 m of the IMU");
  // FixSlot turns rate x time into an int64 slot: bounded (fuzz_scenario_yaml
  // found rate_hz: 1e91 overflowing it, undefined behaviour).
  constexpr double kMaxRateHz = 1000;
  if (!(std::isfinite(s.gps_rate_hz) && s.gps_rate_hz > 0 && s.gps_rate_hz <= kMaxRateHz))
    Bad(s, "gps.rate_hz", "must be in (0, 1000], got " + Num(s.gps_rate_hz));
  RequireNonNegative(s, "gps.sigma_h_m", s.gps_sigma_h_m);
  RequireNonNegative(s, "gps.sigma_v_m", s.gps_sigma_v_m);
  RequireNonNegative(s, "gps.bias_sigma_m", s.gps_bias_sigma_m);
  if (!(std::isfinite(s.gps_stated_sigma_scale) && s.gps_stated_sigma_scale > 0 && s.gps_stated_sigma_scale <= 100))
    Bad(s, "gps.stated_sigma_scale", "must be in (0, 100], got " + Num(s.gps_stated_sigma_scale));
  if (!(std::isfinite(s.gps_bias_tau_s) && s.gps_bias_tau_s > 0))
    Bad(s, "gps.bias_tau_s", "must be > 0, got " + Num(s.gps_bias_tau_s));
  if (!(s.jump_probability >= 0 && s.jump_probability <= 1))
    Bad(s, "gps.jump_probability", "must be in [0, 1], got " + Num(s.jump_probability));
  RequireNonNegative(s, "gps.jump_size_m", s.jump_size_m);
  RequireNonNegative(s, "gps.jump_duration_s", s.jump_duration_s);
  // Becomes int64 nanoseconds, like the outages below.
  if (s.jump_duration_s > 1e6)
    Bad(s, "gps.jump_duration_s", "must be in [0, 1e6], got " + Num(s.jump_duration_s));
  RequireNonNegative(s, "imu.accel_bias_sigma_mps2", s.imu_accel_bias_sigma_mps2);
  RequireNonNegative(s, "imu.gyro_bias_sigma_radps", s.imu_gyro_bias_sigma_radps);
  RequireNonNegative(s, "imu.accel_noise_mps2_sqrt_hz", s.imu_accel_noise_mps2_sqrt_hz);
  RequireNonNegative(s, "imu.gyro_noise_radps_sqrt_hz", s.imu_gyro_noise_radps_sqrt_hz);
  for (size_t i = 0; i < s.outages.size(); ++i) {
    const std::string f = "outages[" + std::to_string(i) + "]";
    // Seconds become int64 nanoseconds: bounded at 1e6 s (11.6 days).
    constexpr double kMaxS = 1e6;
    if (!(std::isfinite(s.outages[i].start_s) && s.outages[i].start_s >= 0 && s.outages[i].start_s <= kMaxS))
      Bad(s, f + ".start_s", "must be in [0, 1e6], got " + Num(s.outages[i].start_s));
    if (!(std::isfinite(s.outages[i].duration_s) && s.outages[i].duration_s > 0 && s.outages[i].duration_s <= kMaxS))
      Bad(s, f + ".duration_s", "must be in (0, 1e6] (end after start), got " +
                                    Num(s.outages[i].duration_s));
  }
  ValidateCameraFaults(s);
  if (s.speed) {
    if (!(std::isfinite(s.speed->rate_hz) && s.speed->rate_hz > 0 && s.speed->rate_hz <= kMaxRateHz))
      Bad(s, "speed.rate_hz", "must be in (0, 1000], got " + Num(s.speed->rate_hz));
    if (!(std::isfinite(s.speed->sigma_mps) && s.speed->sigma_mps > 0 && s.speed->sigma_mps <= 10))
      Bad(s, "speed.sigma_mps", "must be in (0, 10], got " + Num(s.speed->sigma_mps));
    if (!(std::isfinite(s.speed->scale_error) && std::abs(s.speed->scale_error) <= 0.5))
      Bad(s, "speed.scale_error", "must be in [-0.5, 0.5], got " + Num(s.speed->scale_error));
  }
}

std::vector<std::string> BuiltinScenarioNames() {
  return {"open-sky", "urban-canyon", "tunnel-30s", "intermittent"};
}

Scenario BuiltinScenario(const std::string& name) {
  Scenario s;
  s.name = name;
  if (name == "open-sky") {
    s.gps_rate_hz = 10; s.gps_sigma_h_m = 1.5; s.gps_sigma_v_m = 3.0;
    s.gps_bias_sigma_m = 0.0;
  } else if (name == "urban-canyon") {
    s.gps_rate_hz = 1; s.gps_sigma_h_m = 3.0; s.gps_sigma_v_m = 5.0;
    s.gps_bias_sigma_m = 0.0;
    s.jump_probability = 0.03; s.jump_size_m = 20.0; s.jump_duration_s = 0.0;
  } else if (name == "tunnel-30s") {
    s.gps_rate_hz = 10; s.gps_sigma_h_m = 1.5; s.gps_sigma_v_m = 3.0;
    s.outages = {{60.0, 30.0, true}};  // middle of the drive once its length is known
  } else if (name == "intermittent") {
    s.gps_rate_hz = 5; s.gps_sigma_h_m = 3.0; s.gps_sigma_v_m = 5.0;
    for (double t = 30; t < 3600; t += 40) s.outages.push_back({t, 5.0});
  } else {
    std::string known;
    for (const auto& n : BuiltinScenarioNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown scenario '" + name + "' (built-in: " + known +
                                "; or a path to a .yaml file)");
  }
  return s;
}

Scenario PlaceOutagesForDrive(Scenario s, double drive_duration_s) {
  for (auto& o : s.outages) {
    if (o.centered) {
      o.start_s = std::max(0.0, 0.5 * (drive_duration_s - o.duration_s));
      o.centered = false;
    }
  }
  return s;
}

std::string OutageCoverageWarning(const Scenario& s, double drive_duration_s) {
  if (drive_duration_s <= 0) return "";
  // The first moment GPS is not in an outage: windows are merged as they
  // chain from t = 0 (the filter starts from its first fix).
  const double period_s = s.gps_rate_hz > 0 ? 1.0 / s.gps_rate_hz : 0.0;
  double gps_from_s = 0;
  for (bool moved = true; moved;) {
    moved = false;
    for (const auto& o : s.outages) {
      if (o.start_s <= gps_from_s + 1e-9 && o.start_s + o.duration_s > gps_from_s) {
        gps_from_s = o.start_s + o.duration_s;
        moved = true;
      }
    }
  }
  if (gps_from_s <= period_s) return "";
  char text[256];
  if (gps_from_s >= drive_duration_s) {
    std::snprintf(text, sizeof(text),
                  "scenario %s: its outages cover the whole %.1f s drive: the filter never gets a GPS fix to "
                  "start from, so every pose is LOST (use a longer drive or a shorter outage)",
                  s.name.c_str(), drive_duration_s);
  } else {
    std::snprintf(text, sizeof(text),
                  "scenario %s: an outage covers the drive's first %.1f s: the filter has no GPS fix to start "
                  "from until then, so those poses are LOST", s.name.c_str(), gps_from_s);
  }
  return text;
}

// ---------------------------------------------------------------- GpsReceiverSim

GpsReceiverSim::GpsReceiverSim(Scenario scenario) : scenario_(std::move(scenario)), rng_(scenario_.seed) {
  ValidateScenario(scenario_);
}

bool GpsReceiverSim::InOutage(int64_t t_ns) const {
  if (forced_outage_) return true;
  for (const auto& [a, b] : runtime_outages_)
    if (t_ns >= a && t_ns < b) return true;
  if (!drive_start_ns_) return false;
  const double t_s = static_cast<double>(t_ns - *drive_start_ns_) / kNsPerS;
  for (const auto& o : scenario_.outages)
    if (t_s >= o.start_s && t_s < o.start_s + o.duration_s) return true;
  return false;
}

void GpsReceiverSim::ScheduleOutage(int64_t start_ns, int64_t end_ns) {
  if (end_ns <= start_ns)
    throw std::invalid_argument("outage end (" + std::to_string(end_ns) +
                                " ns) must be after its start (" + std::to_string(start_ns) + " ns)");
  runtime_outages_.emplace_back(start_ns, end_ns);
}

int64_t FixSlot(int64_t t_since_start_ns, double rate_hz) {
  const double periods = static_cast<double>(t_since_start_ns) / kNsPerS * rate_hz;
  return static_cast<int64_t>(std::floor(periods + 0.5));
}

std::optional<GpsFix> GpsReceiverSim::Apply(int64_t t_ns, double lat, double lon, double alt,
                                         const Eigen::Matrix3d* R_enu_body) {
  if (!drive_start_ns_) SetDriveStart(t_ns);
  if (!bias_initialized_) {
    bias_initialized_ = true;
    std::normal_distribution<double> n01;
    for (int i = 0; i < 3; ++i) bias_enu_m_[i] = scenario_.gps_bias_sigma_m * n01(rng_);
  }
  // Bias: first-order Gauss-Markov, advanced on every sample.
  {
    const double dt = static_cast<double>(t_ns - last_bias_ns_) / kNsPerS;
    last_bias_ns_ = t_ns;
    if (dt > 0 && scenario_.gps_bias_sigma_m > 0) {
      const double phi = std::exp(-dt / scenario_.gps_bias_tau_s);
      const double q = scenario_.gps_bias_sigma_m * std::sqrt(1 - phi * phi);
      std::normal_distribution<double> n01;
      for (int i = 0; i < 3; ++i) bias_enu_m_[i] = phi * bias_enu_m_[i] + q * n01(rng_);
    }
  }
  const int64_t slot = FixSlot(t_ns - *drive_start_ns_, scenario_.gps_rate_hz);
  if (last_fix_slot_ && slot <= *last_fix_slot_) return std::nullopt;
  if (InOutage(t_ns)) return std::nullopt;
  last_fix_slot_ = slot;

  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  // Multipath jumps.
  if (jump_active_ && t_ns >= jump_end_ns_) jump_active_ = false;
  Eigen::Vector2d jump = Eigen::Vector2d::Zero();
  if (jump_active_) {
    jump = jump_en_m_;
  } else if (scenario_.jump_probability > 0 && u01(rng_) < scenario_.jump_probability) {
    const double a = 2 * M_PI * u01(rng_);
    jump_en_m_ = scenario_.jump_size_m * Eigen::Vector2d(std::cos(a), std::sin(a));
    jump = jump_en_m_;
    if (scenario_.jump_duration_s > 0) {
      jump_active_ = true;
      jump_end_ns_ = t_ns + static_cast<int64_t>(scenario_.jump_duration_s * kNsPerS);
    }
  }
  const Eigen::Vector3d err(scenario_.gps_sigma_h_m * n01(rng_) + bias_enu_m_.x() + jump.x(),
                            scenario_.gps_sigma_h_m * n01(rng_) + bias_enu_m_.y() + jump.y(),
                            scenario_.gps_sigma_v_m * n01(rng_) + bias_enu_m_.z());
  const Eigen::Vector3d antenna =
      R_enu_body ? Eigen::Vector3d(*R_enu_body * scenario_.gps_antenna_body_m) : Eigen::Vector3d::Zero();
  GeographicLib::LocalCartesian lc(lat, lon, alt);
  GpsFix fix;
  fix.t_ns = t_ns;
  lc.Reverse(err.x() + antenna.x(), err.y() + antenna.y(), err.z() + antenna.z(), fix.lat_deg, fix.lon_deg,
             fix.alt_m);
  // The receiver claims its white noise plus the bias it cannot see (times
  // the scenario's misstatement).
  fix.sigma_h_m = scenario_.gps_stated_sigma_scale * std::hypot(scenario_.gps_sigma_h_m, scenario_.gps_bias_sigma_m);
  fix.sigma_v_m = scenario_.gps_stated_sigma_scale * std::hypot(scenario_.gps_sigma_v_m, scenario_.gps_bias_sigma_m);
  return fix;
}

// ---------------------------------------------------------------- ImuDegrader

ImuDegrader::ImuDegrader(const Scenario& scenario) : scenario_(scenario), rng_(scenario.seed ^ 0x9e3779b97f4a7c15ULL) {
  if (scenario_.imu_grade == ImuGrade::kMems) {
    std::normal_distribution<double> n01;
    for (int i = 0; i < 3; ++i) {
      accel_bias_mps2_[i] = scenario_.imu_accel_bias_sigma_mps2 * n01(rng_);
      gyro_bias_radps_[i] = scenario_.imu_gyro_bias_sigma_radps * n01(rng_);
    }
  }
}

ImuSample ImuDegrader::Apply(const ImuSample& in) {
  if (scenario_.imu_grade == ImuGrade::kAsRecorded) return in;
  double dt = 0.01;
  if (last_ns_ && in.t_ns > *last_ns_) dt = static_cast<double>(in.t_ns - *last_ns_) / kNsPerS;
  last_ns_ = in.t_ns;
  dt = std::clamp(dt, 1e-3, 1.0);
  std::normal_distribution<double> n01;
  ImuSample out = in;
  const double sa = scenario_.imu_accel_noise_mps2_sqrt_hz / std::sqrt(dt);
  const double sg = scenario_.imu_gyro_noise_radps_sqrt_hz / std::sqrt(dt);
  for (int i = 0; i < 3; ++i) {
    out.accel_mps2[i] += accel_bias_mps2_[i] + sa * n01(rng_);
    out.gyro_radps[i] += gyro_bias_radps_[i] + sg * n01(rng_);
  }
  return out;
}

SpeedSimulator::SpeedSimulator(const Scenario& scenario)
    : sensor_(scenario.speed), rng_(scenario.seed ^ 0x5bd1e9955bd1e995ULL) {}

std::vector<SpeedSample> SpeedSimulator::Apply(int64_t t_ns, double v_mps) {
  std::vector<SpeedSample> out;
  if (!sensor_ || !std::isfinite(v_mps) || (last_ && t_ns <= last_->first)) return out;
  const auto period_ns = static_cast<int64_t>(std::llround(kNsPerS / sensor_->rate_hz));
  constexpr int64_t kMaxGapNs = 1'000'000'000;
  std::normal_distribution<double> n01;
  auto reading = [&](int64_t t, double v) {
    out.push_back({t, (1.0 + sensor_->scale_error) * v + sensor_->sigma_mps * n01(rng_), sensor_->sigma_mps});
  };
  if (!last_ || t_ns - last_->first > kMaxGapNs) {
    // The first sample, or after a gap: a reading now, the grid restarts here.
    reading(t_ns, v_mps);
    next_ns_ = t_ns + period_ns;
  } else {
    const auto [t0, v0] = *last_;
    for (; next_ns_ <= t_ns; next_ns_ += period_ns) {
      const double a = static_cast<double>(next_ns_ - t0) / static_cast<double>(t_ns - t0);
      reading(next_ns_, v0 + a * (v_mps - v0));
    }
  }
  last_ = {t_ns, v_mps};
  return out;
}

}  // namespace locaid::sim
