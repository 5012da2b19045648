#include "ros/messages.hpp"

#include "ros/cdr.hpp"

#include <cmath>

namespace locaid::ros {
namespace {

Header ReadHeader(CdrReader& r) {
  Header h;
  const int32_t sec = r.I32();
  const uint32_t nanosec = r.U32();
  h.stamp_ns = static_cast<int64_t>(sec) * 1'000'000'000 + nanosec;
  h.frame_id = r.String();
  return h;
}

Eigen::Vector3d ReadVector3(CdrReader& r) {
  Eigen::Vector3d v;
  r.F64Array(v.data(), 3);
  return v;
}

Eigen::Quaterniond ReadQuaternion(CdrReader& r) {
  const double x = r.F64(), y = r.F64(), z = r.F64(), w = r.F64();
  return Eigen::Quaterniond(w, x, y, z);
}

template <size_t N>
std::array<double, N> ReadF64Array(CdrReader& r) {
  std::array<double, N> a{};
  r.F64Array(a.data(), N);
  return a;
}

std::string_view ReadByteSequence(CdrReader& r) { return r.Bytes(r.SequenceLength(1)); }

// A unit quaternion from a message; a zero quaternion (what a driver with no
// orientation often sends) becomes the identity.
Eigen::Quaterniond Normalized(const Eigen::Quaterniond& q) {
  const double n = q.norm();
  return n > 1e-9 && std::isfinite(n) ? Eigen::Quaterniond(q.coeffs() / n) : Eigen::Quaterniond::Identity();
}

}  // namespace

Header DecodeHeader(std::string_view cdr) {
  CdrReader r(cdr);
  return ReadHeader(r);
}

Image DecodeImage(std::string_view cdr) {
  CdrReader r(cdr);
  Image m;
  m.header = ReadHeader(r);
  m.height = r.U32();
  m.width = r.U32();
  m.encoding = r.String();
  m.big_endian = r.U8() != 0;
  m.step = r.U32();
  m.data = ReadByteSequence(r);
  return m;
}

CompressedImage DecodeCompressedImage(std::string_view cdr) {
  CdrReader r(cdr);
  CompressedImage m;
  m.header = ReadHeader(r);
  m.format = r.String();
  m.data = ReadByteSequence(r);
  return m;
}

CameraInfo DecodeCameraInfo(std::string_view cdr) {
  CdrReader r(cdr);
  CameraInfo m;
  m.header = ReadHeader(r);
  m.height = r.U32();
  m.width = r.U32();
  m.distortion_model = r.String();
  m.d.resize(r.SequenceLength(8));
  r.F64Array(m.d.data(), m.d.size());
  m.k = ReadF64Array<9>(r);
  m.r = ReadF64Array<9>(r);
  m.p = ReadF64Array<12>(r);
  m.binning_x = r.U32();
  m.binning_y = r.U32();
  m.roi_x_offset = r.U32();
  m.roi_y_offset = r.U32();
  m.roi_height = r.U32();
  m.roi_width = r.U32();
  m.roi_do_rectify = r.Bool();
  return m;
}

Imu DecodeImu(std::string_view cdr) {
  CdrReader r(cdr);
  Imu m;
  m.header = ReadHeader(r);
  m.orientation = Normalized(ReadQuaternion(r));
  m.orientation_covariance = ReadF64Array<9>(r);
  m.angular_velocity = ReadVector3(r);
  m.angular_velocity_covariance = ReadF64Array<9>(r);
  m.linear_acceleration = ReadVector3(r);
  m.linear_acceleration_covariance = ReadF64Array<9>(r);
  return m;
}

NavSatFix DecodeNavSatFix(std::string_view cdr) {
  CdrReader r(cdr);
  NavSatFix m;
  m.header = ReadHeader(r);
  m.status = r.I8();
  m.service = r.U16();
  m.latitude = r.F64();
  m.longitude = r.F64();
  m.altitude = r.F64();
  m.position_covariance = ReadF64Array<9>(r);
  m.position_covariance_type = r.U8();
  return m;
}

std::vector<TransformStamped> DecodeTfMessage(std::string_view cdr) {
  CdrReader r(cdr);
  // Smallest TransformStamped: header (4 + 4 + 4) + child (4) + 7 doubles.
  const uint32_t n = r.SequenceLength(16 + 7 * 8);
  std::vector<TransformStamped> out(n);
  for (auto& t : out) {
    t.header = ReadHeader(r);
    t.child_frame_id = r.String();
    const Eigen::Vector3d translation = ReadVector3(r);
    const Eigen::Quaterniond rotation = Normalized(ReadQuaternion(r));
    t.T_parent_child.linear() = rotation.toRotationMatrix();
    t.T_parent_child.translation() = translation;
  }
  return out;
}

TwistStamped DecodeTwistStamped(std::string_view cdr) {
  CdrReader r(cdr);
  TwistStamped m;
  m.header = ReadHeader(r);
  m.linear = ReadVector3(r);
  m.angular = ReadVector3(r);
  return m;
}

bool DecodeAny(std::string_view type, std::string_view cdr) {
  if (type == kImage) {
    (void)DecodeImage(cdr);
  } else if (type == kCompressedImage) {
    (void)DecodeCompressedImage(cdr);
  } else if (type == kCameraInfo) {
    (void)DecodeCameraInfo(cdr);
  } else if (type == kImu) {
    (void)DecodeImu(cdr);
  } else if (type == kNavSatFix) {
    (void)DecodeNavSatFix(cdr);
  } else if (type == kTfMessage) {
    (void)DecodeTfMessage(cdr);
  } else if (type == kTwistStamped) {
    (void)DecodeTwistStamped(cdr);
  } else {
    return false;
  }
  return true;
}

}  // namespace locaid::ros
