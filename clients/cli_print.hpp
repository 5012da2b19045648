// How the locaid CLI prints what the server answers: sessions
// (one line each) and session statistics (one figure a line).
#pragma once

#include "locaid/v1/localization.pb.h"

#include <grpcpp/grpcpp.h>

namespace locaid::clients {

const char* StateName(locaid::v1::SessionState s);
void PrintSession(const locaid::v1::Session& s);
void PrintStats(const locaid::v1::SessionStats& s);

}  // namespace locaid::clients
