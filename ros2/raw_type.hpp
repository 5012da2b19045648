// The "raw" Cyclone DDS type of ros2/dds.hpp: a ddsi_sertype whose samples
// are CDR bytes as they are (encapsulation header included), for any type
// name. Writing copies the caller's bytes into a serdata; receiving copies
// the RTPS fragments into one; nothing is (de)serialized or checked on the
// way, so every message reaches the reader, well-formed or not. Keyless, no
// type information (peers match on the type name). The same idea as the
// serdata of rmw_cyclonedds_cpp, without a type support behind it.
#pragma once

#include <cstddef>
#include <string_view>

struct ddsi_sertype;
struct ddsi_serdata;

namespace locaid::ros2::detail {

// What dds_write() takes for a raw topic.
struct RawSample {
  const char* data = nullptr;
  size_t size = 0;
};

// A new sertype for `dds_type_name` (one reference: the caller hands it to
// dds_create_topic_sertype, or unrefs it on failure).
ddsi_sertype* NewRawSertype(const char* dds_type_name);
// The bytes of a serdata of a raw sertype (as dds_takecdr returns them).
std::string_view RawBytes(const ddsi_serdata* serdata);

}  // namespace locaid::ros2::detail
