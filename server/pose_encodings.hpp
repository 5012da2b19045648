// The wire bytes of a session's poses: each pose serialized once and shared
// by every StreamPoses subscriber of the session.
#pragma once

#include "server/session.hpp"

#include <grpcpp/grpcpp.h>

#include <array>
#include <cstdint>
#include <mutex>

namespace locaid::server {

// The poses of one session serialized once and shared by all its pose
// streams (a grpc::Slice is reference counted, so N subscribers cost one
// serialization and N reference increments instead of N proto copies and N
// serializations). Thread-safe.
class PoseEncodings {
 public:
  // The serialized bytes of `item` (dropped_for_subscriber unset). The last
  // kSlots sequence numbers are cached; older items (a from-start replay)
  // are serialized on each call and not cached.
  grpc::Slice Get(const Hub::Item& item);

  static constexpr size_t kSlots = 64;

 private:
  std::mutex mu_;
  uint64_t newest_ = 0;
  std::array<Hub::Item, kSlots> items_;
  std::array<grpc::Slice, kSlots> slices_;
};

// The wire bytes of one subscriber's PoseUpdate: `encoded` (a serialized
// PoseUpdate without dropped_for_subscriber) shared as is, followed, when
// `dropped` > 0, by the few bytes of field dropped_for_subscriber.
grpc::ByteBuffer EncodePoseForSubscriber(const grpc::Slice& encoded, uint64_t dropped);

}  // namespace locaid::server
