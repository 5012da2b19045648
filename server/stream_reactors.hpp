// The two streaming RPCs' reactors (gRPC callback API, one write in flight,
// woken by the session's hub): StreamPoses (raw pose bytes, serialized once
// per session; smoothing_lag_s > 0: a lag's hub, server/lagged_streams.hpp)
// and PushSensorData (frames and OXTS in, poses and rejections
// out). The handlers in service.cpp create them here.
#pragma once

#include "locaid/v1/localization.grpc.pb.h"
#include "server/service.hpp"
#include "server/session.hpp"

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace locaid::server {

grpc::ServerWriteReactor<grpc::ByteBuffer>* NewPoseWriter(ReactorHost* service,
                                                          std::shared_ptr<Session> session,
                                                          std::shared_ptr<PoseEncodings> encodings, bool from_start,
                                                          std::string peer, size_t queue_size,
                                                          double smoothing_lag_s = 0);
grpc::ServerBidiReactor<locaid::v1::PushRequest, locaid::v1::PushResponse>* NewPushReactor(
    ReactorHost* service, std::string peer);

}  // namespace locaid::server
