// StartSessionRequest.bag: a ROS 2 bag on the server's file system, every
// field checked and the bag opened (pipeline::BagFrameSource), or the status
// that says why not.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "pipeline/frame_source.hpp"
#include "server/service.hpp"

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace locaid::server {

// OK with `out` the bag's frames, run->localizer.ekf the antenna lever arm
// from /tf_static and the process model (the IMU one when the bag has an
// IMU topic), and `name` "bag:PATH". INVALID_ARGUMENT naming the
// field for a bad request: path missing, longer than PATH_MAX or not on the
// server; a tolerance outside [0, 1000] ms or a window outside [0, 60000] ms;
// a topic name that is neither empty, "none" (imu, gps, speed only) nor
// starts with '/'. FAILED_PRECONDITION "cannot open bag: ..." when the bag
// cannot be read (not MCAP, no messages) or its topics do not fit (a named
// topic missing or of another type, several candidates, no camera_info, no
// /tf_static to the IMU). The whole bag is scanned first when
// run->scenario has outages placed on the drive's middle (they need its
// length), else its first 5 s.
grpc::Status OpenBagSource(const locaid::v1::BagSource& bag, pipeline::RunOptions* run,
                           std::unique_ptr<pipeline::FrameSource>* out, std::string* name);

}  // namespace locaid::server
