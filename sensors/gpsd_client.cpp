#include "sensors/gpsd_client.hpp"

#include <gps.h>

#include <cerrno>
#include <cmath>
#include <stdexcept>

namespace locaid::sensors {
namespace {

constexpr double kDefaultSigmaH = 5.0, kDefaultSigmaV = 10.0;
// gpsd's estimates are 95 % figures: 2-D radius (chi, 2 dof) and 1-D.
constexpr double k95Radius2d = 2.4477, k95OneD = 1.96;

double Finite(double v, double fallback) { return std::isfinite(v) && v > 0 ? v : fallback; }

}  // namespace

std::optional<fusion::GpsFix> FixFromGpsd(const GpsdReport& r) {
  if (r.mode < MODE_2D || r.t_ns == 0 || !std::isfinite(r.lat_deg) || !std::isfinite(r.lon_deg)) return std::nullopt;
  fusion::GpsFix fix;
  fix.t_ns = r.t_ns;
  fix.lat_deg = r.lat_deg;
  fix.lon_deg = r.lon_deg;
  fix.has_altitude = r.mode >= MODE_3D && std::isfinite(r.alt_hae_m);
  fix.alt_m = fix.has_altitude ? r.alt_hae_m : 0.0;
  // Per-axis estimates when gpsd has them (epx/epy are 1-D 95 % figures),
  // else its horizontal radius.
  const bool per_axis = std::isfinite(r.epx_m) && std::isfinite(r.epy_m) && r.epx_m > 0 && r.epy_m > 0;
  fix.sigma_h_m = per_axis ? std::max(r.epx_m, r.epy_m) / k95OneD : Finite(r.eph_m, kDefaultSigmaH * k95Radius2d) / k95Radius2d;
  fix.sigma_v_m = Finite(r.epv_m, kDefaultSigmaV * k95OneD) / k95OneD;
  if (std::isfinite(r.speed_mps) && std::isfinite(r.track_deg)) {
    const double track = r.track_deg * M_PI / 180.0;  // from north, clockwise
    const double climb = std::isfinite(r.climb_mps) ? r.climb_mps : 0.0;
    fix.v_enu_mps = Eigen::Vector3d(r.speed_mps * std::sin(track), r.speed_mps * std::cos(track), climb);
    fix.sigma_v_enu_mps = Finite(r.eps_mps, 0.5 * k95OneD) / k95OneD;
  }
  return fix;
}

struct GpsdClient::Impl {
  struct gps_data_t data{};
  std::string where;
};

GpsdClient::GpsdClient(const std::string& host, uint16_t port) : impl_(std::make_unique<Impl>()) {
  impl_->where = "gpsd at " + host + ":" + std::to_string(port);
  const std::string port_text = std::to_string(port);
  errno = 0;
  if (gps_open(host.c_str(), port_text.c_str(), &impl_->data) != 0) {
    const int err = errno;
    throw std::runtime_error(impl_->where + ": cannot connect (" + gps_errstr(err) + ")");
  }
  if (gps_stream(&impl_->data, WATCH_ENABLE | WATCH_JSON, nullptr) != 0) {
    gps_close(&impl_->data);
    throw std::runtime_error(impl_->where + ": cannot enable the JSON watch");
  }
}

GpsdClient::~GpsdClient() {
  gps_stream(&impl_->data, WATCH_DISABLE, nullptr);
  gps_close(&impl_->data);
}

std::vector<GpsdReport> GpsdClient::Read(std::chrono::milliseconds timeout) {
  std::vector<GpsdReport> reports;
  auto wait_us = static_cast<int>(std::chrono::duration_cast<std::chrono::microseconds>(timeout).count());
  // Drain what is buffered: libgps hands over one JSON object per gps_read.
  while (gps_waiting(&impl_->data, wait_us)) {
    wait_us = 0;
    impl_->data.set = 0;
    const int n = gps_read(&impl_->data, nullptr, 0);
    if (n < 0) throw std::runtime_error(impl_->where + ": connection lost");
    if (n == 0 || !(impl_->data.set & MODE_SET)) continue;  // not a TPV (SKY, DEVICE, VERSION...)
    const struct gps_fix_t& f = impl_->data.fix;
    GpsdReport r;
    r.mode = f.mode;
    r.status = f.status;
    if ((impl_->data.set & TIME_SET) && f.time.tv_sec > 0)
      r.t_ns = static_cast<int64_t>(f.time.tv_sec) * 1000000000LL + f.time.tv_nsec;
    r.lat_deg = f.latitude;
    r.lon_deg = f.longitude;
    r.alt_hae_m = f.altHAE;
    r.epx_m = f.epx;
    r.epy_m = f.epy;
    r.epv_m = f.epv;
    r.eph_m = f.eph;
    r.speed_mps = f.speed;
    r.track_deg = f.track;
    r.climb_mps = f.climb;
    r.eps_mps = f.eps;
    reports.push_back(r);
  }
  // A closed socket is readable: gps_read then fails and throws above.
  return reports;
}

}  // namespace locaid::sensors
