// How the command-line clients reach a server: address, optional TLS trust
// and bearer token (the flags every client takes).
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace locaid::connection {

struct Connection {
  std::string server = "127.0.0.1:50051";
  std::string token;       // bearer token, or
  std::string token_file;  // a file holding it (keeps it out of argv)
  std::string tls_ca;      // PEM to trust; enables TLS
};

// Reads token_file into token (surrounding whitespace dropped); throws
// std::runtime_error naming the file when it cannot be read or is empty.
void ResolveToken(Connection& c);
std::shared_ptr<grpc::Channel> MakeChannel(const Connection& c);
// Deadline (0 = none) and the token on a call.
void Prepare(const Connection& c, grpc::ClientContext* ctx, double timeout_s);
// The status code's name as gRPC spells it ("NOT_FOUND"), "?" for others.
const char* StatusCodeName(grpc::StatusCode code);

}  // namespace locaid::connection
