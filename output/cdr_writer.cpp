#include "output/cdr_writer.hpp"

#include <bit>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace locaid::output {

static_assert(std::endian::native == std::endian::little, "CdrWriter writes host order: little-endian hosts only");

void CdrWriter::Reset() {
  buffer_.clear();
  buffer_.append("\x00\x01\x00\x00", kHeaderBytes);  // CDR_LE, options 0
}

void CdrWriter::Align(size_t alignment) {
  const size_t offset = buffer_.size() - kHeaderBytes;
  const size_t padding = (alignment - offset % alignment) % alignment;
  buffer_.append(padding, '\0');
}

template <typename T>
void CdrWriter::Put(T v) {
  Align(sizeof(T));
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  buffer_.append(bytes, sizeof(T));
}

void CdrWriter::String(std::string_view s) {
  if (s.size() >= std::numeric_limits<uint32_t>::max()) throw std::length_error("CdrWriter: string too long");
  Uint32(static_cast<uint32_t>(s.size() + 1));
  buffer_.append(s);
  buffer_.push_back('\0');
}

void CdrWriter::SequenceLength(size_t count) {
  if (count > std::numeric_limits<uint32_t>::max()) throw std::length_error("CdrWriter: sequence too long");
  Uint32(static_cast<uint32_t>(count));
}

template void CdrWriter::Put<int8_t>(int8_t);
template void CdrWriter::Put<uint8_t>(uint8_t);
template void CdrWriter::Put<uint16_t>(uint16_t);
template void CdrWriter::Put<int32_t>(int32_t);
template void CdrWriter::Put<uint32_t>(uint32_t);
template void CdrWriter::Put<int64_t>(int64_t);
template void CdrWriter::Put<uint64_t>(uint64_t);
template void CdrWriter::Put<double>(double);

}  // namespace locaid::output
