#include "server/push_requests.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <sstream>
#include <utility>

namespace locaid::server {
namespace {

namespace v1 = locaid::v1;

// Defaults of the API for what a receiver does not state (1-sigma).
constexpr double kDefaultSigmaH = 5.0, kDefaultSigmaV = 10.0, kDefaultSigmaVel = 0.5;

std::string Number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

bool Vec(const v1::Vector3& v, Eigen::Vector3d* out) {
  *out = Eigen::Vector3d(v.x(), v.y(), v.z());
  return out->allFinite();
}

// Largest stated 1-sigma / noise density accepted: beyond these a value is
// corrupt, and its square (the filter works in variances) must stay far
// from overflow. docs/api.md lists them.
constexpr double kMaxSigmaPositionM = 1e4, kMaxSigmaVelocityMps = 1e3;
constexpr double kMaxAccelNoise = 10.0, kMaxGyroNoise = 1.0;  // per sqrt(Hz)

// 0 (or, where nan_is_unstated, NaN) = not stated: `fallback`; otherwise
// finite, > 0 and <= max.
std::string Sigma(const char* field, double v, double fallback, double max, bool nan_is_unstated, double* out) {
  if (v == 0 || (nan_is_unstated && std::isnan(v))) {
    *out = fallback;
    return "";
  }
  if (!std::isfinite(v) || v < 0) return std::string(field) + ": must be > 0 (or 0 for the default), got " + Number(v);
  if (v > max) return std::string(field) + ": must be <= " + Number(max) + ", got " + Number(v);
  *out = v;
  return "";
}

}  // namespace

std::string ImuItemFromProto(const v1::ImuSample& in, pipeline::LiveItem* out) {
  out->kind = pipeline::LiveItem::Kind::kImu;
  out->t_ns = in.t_ns();
  out->imu.t_ns = in.t_ns();
  if (!Vec(in.accel_mps2(), &out->imu.accel_mps2)) return "accel_mps2: not finite";
  if (!Vec(in.gyro_radps(), &out->imu.gyro_radps)) return "gyro_radps: not finite";
  // A car's IMU saturates long before these: larger values are corrupt.
  if (out->imu.accel_mps2.norm() > 2000) return "accel_mps2: |a| = " + Number(out->imu.accel_mps2.norm()) + " > 2000";
  if (out->imu.gyro_radps.norm() > 100) return "gyro_radps: |w| = " + Number(out->imu.gyro_radps.norm()) + " > 100";
  if (auto e = Sigma("accel_noise_mps2_sqrt_hz", in.accel_noise_mps2_sqrt_hz(), 0, kMaxAccelNoise, false,
                     &out->imu.accel_noise_mps2_sqrt_hz);
      !e.empty())
    return e;
  return Sigma("gyro_noise_radps_sqrt_hz", in.gyro_noise_radps_sqrt_hz(), 0, kMaxGyroNoise, false,
               &out->imu.gyro_noise_radps_sqrt_hz);
}

std::string SpeedItemFromProto(const v1::SpeedSample& in, pipeline::LiveItem* out) {
  out->kind = pipeline::LiveItem::Kind::kSpeed;
  out->t_ns = in.t_ns();
  out->speed.t_ns = in.t_ns();
  // 100 m/s = 360 km/h: beyond that a car's speed reading is corrupt.
  if (!std::isfinite(in.speed_mps()) || std::abs(in.speed_mps()) > 100)
    return "speed_mps: must be finite and within 100 m/s, got " + Number(in.speed_mps());
  out->speed.speed_mps = in.speed_mps();
  return Sigma("sigma_mps", in.sigma_mps(), 0, 10, false, &out->speed.sigma_mps);
}

std::string GpsItemFromProto(const v1::GpsFix& in, pipeline::LiveItem* out) {
  out->kind = pipeline::LiveItem::Kind::kGps;
  out->t_ns = in.t_ns();
  fusion::GpsFix& f = out->gps;
  f.t_ns = in.t_ns();
  if (in.fix_type() == v1::GPS_FIX_NONE) {
    out->gps_no_fix = true;  // position fields are ignored
    return "";
  }
  if (!v1::GpsFixType_IsValid(in.fix_type())) return "fix_type: unknown value " + std::to_string(in.fix_type());
  const double lat = in.latitude_deg(), lon = in.longitude_deg(), alt = in.altitude_m();
  if (!std::isfinite(lat) || lat < -90 || lat > 90) return "latitude_deg: must be in [-90, 90], got " + Number(lat);
  if (!std::isfinite(lon) || lon < -180 || lon > 180) return "longitude_deg: must be in [-180, 180], got " + Number(lon);
  f.lat_deg = lat;
  f.lon_deg = lon;
  f.has_altitude = in.fix_type() != v1::GPS_FIX_2D;
  if (f.has_altitude && (!std::isfinite(alt) || alt < -1000 || alt > 100000))
    return "altitude_m: must be in [-1000, 100000], got " + Number(alt);
  f.alt_m = f.has_altitude ? alt : 0.0;
  if (auto e = Sigma("sigma_horizontal_m", in.sigma_horizontal_m(), kDefaultSigmaH, kMaxSigmaPositionM, true,
                     &f.sigma_h_m);
      !e.empty())
    return e;
  if (auto e = Sigma("sigma_vertical_m", in.sigma_vertical_m(), kDefaultSigmaV, kMaxSigmaPositionM, true, &f.sigma_v_m);
      !e.empty())
    return e;
  if (in.covariance_enu_m2_size() != 0) {
    if (in.covariance_enu_m2_size() != 9)
      return "covariance_enu_m2: expected 0 or 9 values, got " + std::to_string(in.covariance_enu_m2_size());
    Eigen::Matrix3d C;
    for (int i = 0; i < 9; ++i) C(i / 3, i % 3) = in.covariance_enu_m2(i);
    // NaN entries (a driver that does not know) mean "not stated": the
    // sigmas (or their defaults) apply, never a NaN in the filter.
    if (!C.hasNaN()) {
      constexpr double kMaxVariance = kMaxSigmaPositionM * kMaxSigmaPositionM;
      if (!C.allFinite() || C.cwiseAbs().maxCoeff() > kMaxVariance)
        return "covariance_enu_m2: every value must be finite with |value| <= " + Number(kMaxVariance) + " m^2";
      // Entry by entry against the largest: isApprox's squared norms
      // underflow to 0 for denormal entries (fuzz_push_requests).
      if ((C - C.transpose()).cwiseAbs().maxCoeff() > 1e-9 * C.cwiseAbs().maxCoeff())
        return "covariance_enu_m2: not symmetric";
      // Cholesky, not the smallest eigenvalue: the eigensolver returned a
      // positive one for a zero U variance with a 1e-135 E-U term
      // (fuzz_push_requests), so a fix with a zero variance was accepted.
      if (Eigen::LLT<Eigen::Matrix3d>(C).info() != Eigen::Success) return "covariance_enu_m2: not positive definite";
      f.cov_enu_m2 = C;
    }
  }
  if (in.has_velocity()) {
    Eigen::Vector3d v;
    if (!Vec(in.velocity_enu_mps(), &v) || v.norm() > 200) return "velocity_enu_mps: must be finite, |v| <= 200 m/s";
    f.v_enu_mps = v;
    if (auto e = Sigma("sigma_velocity_mps", in.sigma_velocity_mps(), kDefaultSigmaVel, kMaxSigmaVelocityMps, true,
                       &f.sigma_v_enu_mps);
        !e.empty())
      return e;
  }
  return "";
}

FrameTranslation FrameItemFromProto(v1::StereoFrame* in, const StereoCamera& camera) {
  FrameTranslation t;
  if (in->encoding() != v1::IMAGE_ENCODING_PNG && in->encoding() != v1::IMAGE_ENCODING_GRAY8) {
    t.rejected = "encoding: must be IMAGE_ENCODING_PNG or IMAGE_ENCODING_GRAY8";
    return t;
  }
  t.item.kind = pipeline::LiveItem::Kind::kFrame;
  t.item.t_ns = in->t_ns();
  t.item.png = in->encoding() == v1::IMAGE_ENCODING_PNG;
  if (t.item.png) {
    t.fatal = pipeline::PngSizeMismatch(in->left(), camera, "left");
    if (t.fatal.empty()) t.fatal = pipeline::PngSizeMismatch(in->right(), camera, "right");
    if (!t.fatal.empty()) return t;
  }
  t.item.left = std::move(*in->mutable_left());
  t.item.right = std::move(*in->mutable_right());
  return t;
}

pipeline::LiveItem OxtsItemFromProto(const v1::OxtsRecord& in) {
  pipeline::LiveItem item;
  item.kind = pipeline::LiveItem::Kind::kOxts;
  item.t_ns = in.t_ns();
  item.oxts_line = in.line();
  return item;
}

}  // namespace locaid::server
