// CdrWriter: serializes a ROS 2 message body as plain little-endian CDR
// (XCDR1, the encoding rosbag2 stores and rmw implementations put on the
// wire): a 4-byte encapsulation header 00 01 00 00 (CDR_LE), then the
// fields in declaration order, each primitive aligned to its own size
// (8-byte alignment at most) counted from the end of the header. Strings are
// a uint32 length that includes the terminating NUL, the bytes and the NUL;
// an unbounded sequence is a uint32 element count followed by the elements;
// a fixed-size array (float64[36]) is its elements alone.
//
// A writer is a growing byte buffer; it never fails. Reuse one across
// messages with Reset() to keep its allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace locaid::output {

class CdrWriter {
 public:
  CdrWriter() { Reset(); }
  // Empties the buffer and writes the encapsulation header.
  void Reset();

  void Bool(bool v) { Uint8(v ? 1 : 0); }
  void Int8(int8_t v) { Put(v); }
  void Uint8(uint8_t v) { Put(v); }
  void Uint16(uint16_t v) { Put(v); }
  void Int32(int32_t v) { Put(v); }
  void Uint32(uint32_t v) { Put(v); }
  void Int64(int64_t v) { Put(v); }
  void Uint64(uint64_t v) { Put(v); }
  void Float64(double v) { Put(v); }
  void String(std::string_view s);
  // The element count of an unbounded sequence; the caller writes the elements.
  void SequenceLength(size_t count);

  // Header included.
  const std::string& data() const { return buffer_; }
  size_t size() const { return buffer_.size(); }

 private:
  static constexpr size_t kHeaderBytes = 4;
  void Align(size_t alignment);
  template <typename T>
  void Put(T v);

  std::string buffer_;
};

}  // namespace locaid::output
