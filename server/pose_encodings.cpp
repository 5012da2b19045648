#include "server/pose_encodings.hpp"

#include <google/protobuf/io/coded_stream.h>

#include <algorithm>
#include <string>

namespace locaid::server {

namespace v1 = locaid::v1;

grpc::Slice PoseEncodings::Get(const Hub::Item& item) {
  const uint64_t seq = item->sequence();
  const size_t slot = static_cast<size_t>(seq % kSlots);
  {
    std::lock_guard lock(mu_);
    if (items_[slot] == item) return slices_[slot];
  }
  const std::string bytes = item->SerializeAsString();
  grpc::Slice slice(bytes);
  std::lock_guard lock(mu_);
  if (seq + kSlots > newest_) {  // recent: cache it (a replay of old history does not evict live items)
    newest_ = std::max(newest_, seq);
    items_[slot] = item;
    slices_[slot] = slice;
  }
  return slice;
}

grpc::ByteBuffer EncodePoseForSubscriber(const grpc::Slice& encoded, uint64_t dropped) {
  if (dropped == 0) return grpc::ByteBuffer(&encoded, 1);
  using google::protobuf::io::CodedOutputStream;
  uint8_t tail[16];
  uint8_t* end = CodedOutputStream::WriteTagToArray(
      static_cast<uint32_t>(v1::PoseUpdate::kDroppedForSubscriberFieldNumber) << 3, tail);  // varint wire type
  end = CodedOutputStream::WriteVarint64ToArray(dropped, end);
  const grpc::Slice slices[2] = {encoded, grpc::Slice(tail, static_cast<size_t>(end - tail))};
  return grpc::ByteBuffer(slices, 2);
}

}  // namespace locaid::server
