// CdrReader: decodes one CDR-encoded message (OMG XCDR1 "plain CDR", what
// ROS 2's rmw implementations and rosbag2 write): a 4-byte encapsulation
// header (0x00 0x00 big-endian, 0x00 0x01 little-endian, then two option
// bytes), then the fields, each primitive aligned to its own size (at most 8)
// counted from the end of the header. Strings are a uint32 length including
// the terminating NUL, then the bytes; sequences a uint32 element count, then
// the elements; fixed arrays just the elements.
//
// Every read checks the bytes left: a truncated or lying message throws
// CdrError naming the field offset, never reads past the data or allocates
// from an untrusted count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace locaid::ros {

class CdrError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CdrReader {
 public:
  // Reads the encapsulation header; throws CdrError when `data` is shorter
  // than 4 bytes or its kind is not plain CDR (BE or LE).
  explicit CdrReader(std::string_view data);

  bool Bool();
  uint8_t U8();
  int8_t I8();
  uint16_t U16();
  int16_t I16();
  uint32_t U32();
  int32_t I32();
  uint64_t U64();
  int64_t I64();
  float F32();
  double F64();
  std::string String();
  // A sequence's element count; throws when count * min_element_bytes is
  // more than the bytes left (so a caller can reserve `count`); 0 counts as 1.
  uint32_t SequenceLength(size_t min_element_bytes);
  // n raw bytes (the payload of a uint8[] / byte[]); no alignment.
  std::string_view Bytes(size_t n);
  // n doubles (a float64[N] array or the elements of a float64[] sequence).
  void F64Array(double* out, size_t n);

  bool big_endian() const { return big_endian_; }
  size_t offset() const { return pos_; }  // from the start of the data, header included
  size_t remaining() const { return data_.size() - pos_; }

 private:
  void Align(size_t n);
  const char* Take(size_t n, const char* what);

  std::string_view data_;
  size_t pos_ = 0;
  bool big_endian_ = false;
  bool swap_ = false;  // the message's byte order is not the host's
};

}  // namespace locaid::ros
