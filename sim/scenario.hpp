// Sensor simulators: a scenario (GPS receiver, outages, IMU grade, speed
// sensor, camera faults) and the simulators that make, from the untouched
// reference unit (KITTI's OXTS RT3003), what the filter sees: a receiver's
// fixes, a MEMS IMU, a speed sensor. Its samples are the truth and never
// reaches the filter as is. The filter (fusion/) does not include this.
#pragma once

#include "fusion/types.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace locaid::sim {

// What the simulators make: the filter's own measurement types.
using fusion::GpsFix;
using fusion::ImuSample;
using fusion::SpeedSample;

// A GPS outage, relative to the drive start (time of the first sample seen).
struct OutageWindow {
  double start_s = 0;
  double duration_s = 0;
  // Place the window in the middle of the drive when its length is known
  // (PlaceOutagesForDrive); start_s is used until then (live sessions).
  bool centered = false;
};

// A camera fault over a window of sensor time from the first frame: what
// happens to the images before VO sees them (pipeline/camera_faults.hpp
// applies it). Data only: the fusion library never touches images.
enum class CameraFaultKind { kDark, kNoise, kBlur, kFrozen, kDrop, kLeftOnly, kRightOnly };
const char* ToString(CameraFaultKind kind);  // "dark", "noise", ... as in scenario YAML
struct CameraFaultWindow {
  double start_s = 0;
  double duration_s = 0;
  CameraFaultKind kind = CameraFaultKind::kDark;
  double gain = 0.06;          // kDark: image gain in (0, 1]
  double noise_dn = 3.0;       // kDark, kNoise: 1-sigma sensor noise, digital numbers
  double blur_sigma_px = 3.0;  // kBlur
};
// Why a camera fault's parameters are out of range, "" when they are fine:
// "gain: must be in (0, 1], got 2" (gain in (0, 1], noise_dn in [0, 255],
// blur_sigma_px in (0, 50]; times are not checked here).
std::string CameraFaultParameterProblem(const CameraFaultWindow& fault);

// A simulated vehicle speed sensor (CAN speed / wheel ticks), made from a
// reference unit's forward speed: reads (1 + scale_error) x the true speed
// plus white noise of sigma_mps, at rate_hz.
struct SpeedSensorSim {
  double rate_hz = 50.0;
  double sigma_mps = 0.05;
  double scale_error = 0.0;
};

enum class ImuGrade {
  kAsRecorded,  // OXTS accelerations / angular rates unchanged (RT3003 grade)
  kMems,        // + constant turn-on bias, bias random walk and white noise
};
const char* ToString(ImuGrade grade);

struct Scenario {
  std::string name = "open-sky";
  // GPS.
  double gps_rate_hz = 10.0;         // fixes per second (decimated from OXTS)
  double gps_sigma_h_m = 1.5;        // 1-sigma white horizontal noise per axis (E, N)
  double gps_sigma_v_m = 3.0;        // 1-sigma white vertical noise
  double gps_bias_sigma_m = 0.0;     // steady-state 1-sigma of a slow Gauss-Markov bias per axis
  double gps_bias_tau_s = 60.0;      // correlation time of that bias (random walk for large tau)
  double jump_probability = 0.0;     // per fix: probability that a multipath jump starts
  double jump_size_m = 0.0;          // horizontal size of a jump (random direction)
  double jump_duration_s = 0.0;      // how long a jump lasts (0: one fix)
  // The sigma the receiver states, as a multiple of the one it has (a
  // receiver that claims 1 m and delivers 3 m: 1/3). In (0, 100].
  double gps_stated_sigma_scale = 1.0;
  // Where the simulated receiver's antenna sits in the body (IMU) frame, m:
  // the degraded fix is of that point (needs the attitude, see Apply).
  Eigen::Vector3d gps_antenna_body_m = Eigen::Vector3d::Zero();
  // Measured fixes (a ROS 2 bag's, a client's): false, fused as recorded
  // (outages still apply); true, also through the receiver model above
  // (rate, noise, bias, jumps) on top of the recorded position, with the
  // model's sigma added to the recorded one.
  bool degrade_measured_gps = false;
  // IMU.
  ImuGrade imu_grade = ImuGrade::kAsRecorded;
  double imu_accel_bias_sigma_mps2 = 0.05;      // kMems: turn-on bias, 1-sigma per axis
  double imu_gyro_bias_sigma_radps = 0.002;     // kMems
  double imu_accel_noise_mps2_sqrt_hz = 0.01;   // kMems: white noise density
  double imu_gyro_noise_radps_sqrt_hz = 0.0005; // kMems
  // Outages relative to the drive start.
  std::vector<OutageWindow> outages;
  // Camera faults relative to the first frame (scenario key `camera:`).
  std::vector<CameraFaultWindow> camera_faults;
  // A simulated speed sensor (scenario key `speed:`); none when unset.
  std::optional<SpeedSensorSim> speed;
  uint64_t seed = 1;
};

// Throws std::invalid_argument "scenario NAME: field FIELD: reason" when a
// value is out of range (negative sigma, rate <= 0, probability outside [0, 1],
// outage with negative start or non-positive duration ...).
void ValidateScenario(const Scenario& scenario);
// The camera faults' part of ValidateScenario: "scenario NAME: field
// camera[0].gain: must be in (0, 1], got 2"; start_s in [0, 1e6],
// duration_s in (0, 1e6], parameters as CameraFaultParameterProblem.
void ValidateCameraFaults(const Scenario& scenario);

// Built-in scenarios: "open-sky" (1.5 m at 10 Hz), "urban-canyon" (3 m at
// 1 Hz, multipath jumps), "tunnel-30s" (open-sky GPS with one 30 s outage in
// the middle of the drive: use ScenarioForDrive or set the window yourself),
// "intermittent" (3 m at 5 Hz, 5 s outages every 40 s).
std::vector<std::string> BuiltinScenarioNames();
// Throws std::invalid_argument for an unknown name (listing the known ones).
Scenario BuiltinScenario(const std::string& name);
// Scenarios whose outage depends on the drive length ("tunnel-30s": middle of
// the drive) are placed with this; others are returned unchanged.
Scenario PlaceOutagesForDrive(Scenario scenario, double drive_duration_s);
// What a user must be told before running `scenario` (outages placed) on a
// drive of this length: "" when nothing, else why the filter will have no GPS
// to start from, e.g. "scenario outage [0, 30) s covers the whole 30.0 s
// drive: the filter never gets a GPS fix to start from, every pose is LOST".
std::string OutageCoverageWarning(const Scenario& scenario, double drive_duration_s);

// Decimation slot of a sample t_since_start_ns after the drive start: the
// nearest whole number of GPS periods (slot k covers [k - 1/2, k + 1/2)
// periods). GpsReceiverSim emits at most one fix per slot.
int64_t FixSlot(int64_t t_since_start_ns, double rate_hz);

// Degrades OXTS fixes into GpsFix: decimation to gps_rate_hz, white noise,
// bias, multipath jumps, scheduled and run-time outages. Seeded, repeatable.
class GpsReceiverSim {
 public:
  explicit GpsReceiverSim(Scenario scenario);

  // Feed every OXTS position in time order; returns a degraded fix when one is
  // due and GPS is not in an outage. The first call fixes the drive start.
  // R_enu_body (the true attitude) places the antenna; without it the fix is
  // of the given point whatever gps_antenna_body_m says.
  std::optional<GpsFix> Apply(int64_t t_ns, double lat_deg, double lon_deg, double alt_m,
                              const Eigen::Matrix3d* R_enu_body = nullptr);
  // Whether t_ns lies in a scheduled or run-time outage.
  bool InOutage(int64_t t_ns) const;

  // Run-time outages (absolute times, same clock as Apply).
  void ScheduleOutage(int64_t start_ns, int64_t end_ns);
  void SetForcedOutage(bool on) { forced_outage_ = on; }
  bool forced_outage() const { return forced_outage_; }

  const Scenario& scenario() const { return scenario_; }
  std::optional<int64_t> drive_start_ns() const { return drive_start_ns_; }
  // Sets the drive start explicitly (else: the first Apply).
  void SetDriveStart(int64_t t_ns) { drive_start_ns_ = t_ns; last_bias_ns_ = t_ns; }

 private:
  Scenario scenario_;
  std::mt19937_64 rng_;
  std::optional<int64_t> drive_start_ns_;
  // Decimation: the time since the drive start is cut into gps_rate_hz slots
  // centred on multiples of the period; the first sample in each slot gives
  // the fix. Locked to that grid, so sample-time jitter of up to half a period
  // neither drops a fix nor adds one.
  std::optional<int64_t> last_fix_slot_;
  int64_t last_bias_ns_ = 0;
  Eigen::Vector3d bias_enu_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector2d jump_en_m_ = Eigen::Vector2d::Zero();
  int64_t jump_end_ns_ = 0;
  bool jump_active_ = false;
  bool bias_initialized_ = false;
  std::vector<std::pair<int64_t, int64_t>> runtime_outages_;
  bool forced_outage_ = false;
};

// A simulated vehicle speed sensor (Scenario::speed) made from a reference
// unit's forward speed: readings on a rate_hz grid, the speed interpolated
// between truth samples (never across a gap of more than 1 s), read
// (1 + scale_error) x high, plus white noise of sigma_mps. Seeded, repeatable.
class SpeedSimulator {
 public:
  // Nothing comes out when the scenario has no speed sensor.
  explicit SpeedSimulator(const Scenario& scenario);
  // Feed each true forward speed in time order; returns the readings
  // due in (previous sample, t_ns].
  std::vector<SpeedSample> Apply(int64_t t_ns, double forward_speed_mps);

 private:
  std::optional<SpeedSensorSim> sensor_;
  std::mt19937_64 rng_;
  std::optional<std::pair<int64_t, double>> last_;  // previous truth sample
  int64_t next_ns_ = 0;                              // next reading on the grid
};

// Degrades IMU samples to MEMS grade (identity for kAsRecorded). Seeded.
class ImuDegrader {
 public:
  explicit ImuDegrader(const Scenario& scenario);
  ImuSample Apply(const ImuSample& sample);
  const Eigen::Vector3d& accel_bias_mps2() const { return accel_bias_mps2_; }
  const Eigen::Vector3d& gyro_bias_radps() const { return gyro_bias_radps_; }

 private:
  Scenario scenario_;
  std::mt19937_64 rng_;
  Eigen::Vector3d accel_bias_mps2_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_radps_ = Eigen::Vector3d::Zero();
  std::optional<int64_t> last_ns_;
};

}  // namespace locaid::sim
