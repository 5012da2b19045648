// InjectOutageRequest translated into the command a session runs on its
// thread, with every value checked here.
#pragma once

#include "locaid/v1/localization.pb.h"
#include "server/session.hpp"

#include <grpcpp/grpcpp.h>

namespace locaid::server {

// OK and `out` set, or INVALID_ARGUMENT naming the field and the rule
// (times finite, |start_s| and duration_s at most 1e6 s; WINDOW: start_s >= 0,
// duration_s > 0; a known action).
grpc::Status OutageCommandFromProto(const locaid::v1::InjectOutageRequest& req, Session::Command* out);

}  // namespace locaid::server
