#include "server/synthetic_drive.hpp"

#include <Eigen/Core>

namespace locaid::server {

Eigen::Isometry3d KittiRigTcam0Imu() {
  Eigen::Matrix<double, 3, 4> m;
  m << 0.000998747, -0.999990382, 0.004259378, -0.314076870,  //
      0.008416902, -0.004250821, -0.999955570, 0.719452036,   //
      0.999964049, 0.001034553, 0.008412575, -1.089082940;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(Eigen::Matrix3d(m.leftCols<3>())).normalized().toRotationMatrix();
  T.translation() = m.col(3);
  return T;
}

std::unique_ptr<kitti::StereoDataset> MakeSyntheticDrive(const std::string&, uint64_t, size_t,
                                                         const std::string&) {
  throw SyntheticError("the synthetic drive generator (kitti/synth/synth.hpp) is not available in this build");
}

}  // namespace locaid::server
