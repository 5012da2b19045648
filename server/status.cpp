#include "server/status.hpp"

#include "locaid/v1/localization.grpc.pb.h"

#include <climits>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <random>

namespace locaid::server {

namespace v1 = locaid::v1;
using grpc::Status;
using grpc::StatusCode;

Status Bounded(const Status& s) {
  if (s.error_message().size() <= kMaxStatusMessageBytes) return s;
  return {s.error_code(), s.error_message().substr(0, kMaxStatusMessageBytes) + "... (message cut)"};
}

Status Invalid(const std::string& msg) { return {StatusCode::INVALID_ARGUMENT, msg}; }

Status RequireServerPath(const std::string& field, const std::string& path, const std::string& what) {
  if (path.empty()) return Invalid(field + ": required (" + what + ")");
  if (path.size() > PATH_MAX) {
    return Invalid(field + ": " + std::to_string(path.size()) + " bytes, longer than PATH_MAX (" +
                   std::to_string(PATH_MAX) + ")");
  }
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) return Status::OK;
  // A relative path is the server's, not the client's: say from where.
  const std::string from = std::filesystem::path(path).is_relative()
                               ? " (a relative path is resolved from the server's working directory " +
                                     Quoted(std::filesystem::current_path(ec).string()) + ")"
                               : "";
  return Invalid(field + " " + Quoted(path) + ": does not exist on the server" + from);
}

Status RequireActive(const Session& session, const char* rpc) {
  const auto state = session.state();
  if (state == v1::SESSION_STATE_RUNNING || state == v1::SESSION_STATE_STARTING) return Status::OK;
  return {StatusCode::FAILED_PRECONDITION, std::string(rpc) + ": session '" + session.id() + "' is " +
                                               v1::SessionState_Name(state) + "; only a running session takes it"};
}

grpc::ServerUnaryReactor* Reply(grpc::CallbackServerContext* ctx, const Status& status) {
  auto* reactor = ctx->DefaultReactor();
  reactor->Finish(Bounded(status));
  return reactor;
}

const std::string& ServiceName() {
  static const std::string name = v1::Localization::service_full_name();
  return name;
}

std::string RandomSessionId() {
  static std::mutex mu;
  static std::random_device device;
  std::lock_guard lock(mu);
  const uint64_t bits = (static_cast<uint64_t>(device()) << 32 | device()) & 0xffffffffffffULL;
  char buf[16];
  std::snprintf(buf, sizeof(buf), "s%012llx", static_cast<unsigned long long>(bits));
  return buf;
}

}  // namespace locaid::server
