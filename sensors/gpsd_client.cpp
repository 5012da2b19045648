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
  const bool gst = std::isfinite(r.gst_lat_m) && std::isfinite(r.gst_lon_m) && r.gst_lat_m > 0 && r.gst_lon_m > 0;
  const bool per_axis = std::isfinite(r.epx_m) && std::isfinite(r.epy_m) && r.epx_m > 0 && r.epy_m > 0;
  if (gst) fix.sigma_h_m = std::max(r.gst_lat_m, r.gst_lon_m);
  else if (per_axis) fix.sigma_h_m = std::max(r.epx_m, r.epy_m) / k95OneD;
  else fix.sigma_h_m = Finite(r.eph_m, kDefaultSigmaH * k95Radius2d) / k95Radius2d;
  fix.sigma_v_m = gst && std::isfinite(r.gst_alt_m) && r.gst_alt_m > 0 ? r.gst_alt_m
                                                                         : Finite(r.epv_m, kDefaultSigmaV * k95OneD) / k95OneD;
  // As for pushed fixes (docs/api.md): a stated error beyond 10 km is a
  // corrupt report; clamped so the filter's variances cannot overflow.
  constexpr double kMaxSigmaM = 1e4;
  fix.sigma_h_m = std::min(fix.sigma_h_m, kMaxSigmaM);
  fix.sigma_v_m = std::min(fix.sigma_v_m, kMaxSigmaM);
  return fix;
}

struct GpsdClient::Impl {
  struct gps_data_t data{};
  std::string where;
  // The newest GST report: 1-sigma lat, lon, alt errors and its time.
  int64_t gst_t_ns = 0;
  double gst[3] = {NAN, NAN, NAN};
};

namespace {
int64_t Ns(const timespec& t) { return static_cast<int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec; }
constexpr int64_t kGstMaxAgeNs = 5'000'000'000LL;
}  // namespace

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
    if (n == 0) continue;
    if (impl_->data.set & GST_SET) {
      const struct gst_t& g = impl_->data.gst;
      impl_->gst_t_ns = Ns(g.utctime);
      impl_->gst[0] = g.lat_err_deviation;
      impl_->gst[1] = g.lon_err_deviation;
      impl_->gst[2] = g.alt_err_deviation;
      continue;
    }
    // A TPV carries the mode; SKY, DEVICE, VERSION... do not.
    if (!(impl_->data.set & MODE_SET)) continue;
    const struct gps_fix_t& f = impl_->data.fix;
    // Without a time the report cannot be paired with frames (gpsd's first
    // report of a device may lack it): skipped.
    if (!(impl_->data.set & TIME_SET) || f.time.tv_sec <= 0) continue;
    GpsdReport r;
    r.mode = f.mode;
    r.status = f.status;
    r.t_ns = Ns(f.time);
    if (impl_->gst_t_ns != 0 && std::abs(r.t_ns - impl_->gst_t_ns) <= kGstMaxAgeNs) {
      r.gst_lat_m = impl_->gst[0];
      r.gst_lon_m = impl_->gst[1];
      r.gst_alt_m = impl_->gst[2];
    }
    r.lat_deg = f.latitude;
    r.lon_deg = f.longitude;
    r.alt_hae_m = f.altHAE;
    r.epx_m = f.epx;
    r.epy_m = f.epy;
    r.epv_m = f.epv;
    r.eph_m = f.eph;
    reports.push_back(r);
  }
  // A closed socket is readable: gps_read then fails and throws above.
  return reports;
}

}  // namespace locaid::sensors
