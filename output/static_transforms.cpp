#include "output/static_transforms.hpp"

namespace locaid::output {

const StaticTransform& BaseLinkToCam0() {
  // The inverse of the server's KittiRigTcam0Imu() (server/synthetic_drive.cpp),
  // written out so this library needs neither the server nor Eigen;
  // tests/foxglove/channels_test.cpp checks the two agree.
  static const StaticTransform transform{
      {1.0833019773216199, -0.30988882632423487, 0.72991979273276453},
      {-0.4992086420530803, 0.49657270863582642, -0.5029076904109222, 0.50128847150433264}};
  return transform;
}

}  // namespace locaid::output
