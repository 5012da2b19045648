#include "pipeline/oxts_adapter.hpp"

#include "kitti/oxts_pose.hpp"

namespace locaid::pipeline {

fusion::ImuSample OxtsImu(int64_t t_ns, const kitti::OxtsRecord& r) {
  fusion::ImuSample imu;
  imu.t_ns = t_ns;
  imu.accel_mps2 = {r.ax_mps2, r.ay_mps2, r.az_mps2};
  imu.gyro_radps = {r.wx_radps, r.wy_radps, r.wz_radps};
  return imu;
}

fusion::TruthSample OxtsTruthSample(int64_t t_ns, const kitti::OxtsRecord& r) {
  return {t_ns, r.lat_deg, r.lon_deg, r.alt_m, kitti::OxtsAttitude(r.roll_rad, r.pitch_rad, r.yaw_rad),
          Eigen::Vector3d(r.vf_mps, r.vl_mps, r.vu_mps)};
}

void AppendOxts(const kitti::OxtsSample& s, SampleBatch& batch) {
  batch.truth_imu.push_back(OxtsImu(s.t_ns, s.record));
  batch.truth_poses.push_back(OxtsTruthSample(s.t_ns, s.record));
}

fusion::TruthSample OxtsTruthAt(int64_t t_ns, const kitti::OxtsSample& a, const kitti::OxtsSample& b) {
  const double w =
      b.t_ns > a.t_ns ? static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns) : 0.0;
  fusion::TruthSample truth = OxtsTruthSample(t_ns, w < 0.5 ? a.record : b.record);
  truth.lat_deg = a.record.lat_deg + w * (b.record.lat_deg - a.record.lat_deg);
  truth.lon_deg = a.record.lon_deg + w * (b.record.lon_deg - a.record.lon_deg);
  truth.alt_m = a.record.alt_m + w * (b.record.alt_m - a.record.alt_m);
  return truth;
}

}  // namespace locaid::pipeline
