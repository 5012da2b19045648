// The statuses every RPC answers with, in one place: how a request is refused
// (Invalid), how an input is echoed (Quoted), and the bound on any message
// (Bounded, applied by Reply and by every stream's Finish).
#pragma once

#include "locaid/v1/localization.pb.h"
#include "server/quoted.hpp"
#include "server/session.hpp"

#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <string>

namespace locaid::server {

// No status message is longer (a 1 MiB id echoed would trip the client's
// metadata limit and reach it as RESOURCE_EXHAUSTED instead of the real code).
inline constexpr size_t kMaxStatusMessageBytes = 1024;
// StartSessionRequest.playback_rate: 0 or within these (pacing divides by it).
inline constexpr double kMinPlaybackRate = 1e-3, kMaxPlaybackRate = 1e3;

grpc::Status Bounded(const grpc::Status& s);
grpc::Status Invalid(const std::string& msg);
// A path a request names on the server's file system (`field`, e.g.
// "kitti.path"): OK when it exists there, else INVALID_ARGUMENT naming the
// field: empty ("required"; `what` says what it should be), longer than
// PATH_MAX, or absent (a relative one: from which folder it was resolved).
grpc::Status RequireServerPath(const std::string& field, const std::string& path, const std::string& what);
// Controls of a session's pipeline apply only while it runs (or starts).
grpc::Status RequireActive(const Session& session, const char* rpc);
// Finishes a unary call with Bounded(status).
grpc::ServerUnaryReactor* Reply(grpc::CallbackServerContext* ctx, const grpc::Status& status);
// "locaid.v1.Localization": the service's name for grpc.health.v1.
const std::string& ServiceName();
// "s" + 12 random hex digits (48 bits from std::random_device): unique across
// server restarts, so an id kept from before a restart never names another
// session (ids counting from s1 did).
std::string RandomSessionId();

}  // namespace locaid::server
