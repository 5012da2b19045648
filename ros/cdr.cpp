#include "ros/cdr.hpp"

#include <bit>
#include <cstdio>
#include <cstring>
#include <utility>

namespace locaid::ros {
namespace {

constexpr size_t kHeaderBytes = 4;  // encapsulation kind (2 bytes) + options (2 bytes)

template <typename T>
T ByteSwapped(T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

// A T from its bytes at p, byte-swapped when the message's order is not the host's.
template <typename T>
T Load(const char* p, bool swap) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return swap ? ByteSwapped(value) : value;
}

std::string KindName(uint16_t kind) {
  switch (kind) {
    case 0x0002: return "parameter-list CDR, big-endian (PL_CDR_BE)";
    case 0x0003: return "parameter-list CDR, little-endian (PL_CDR_LE)";
    case 0x0006: case 0x0007: return "XCDR2 plain CDR2";
    case 0x0008: case 0x0009: return "XCDR2 delimited CDR2";
    case 0x000A: case 0x000B: return "XCDR2 parameter-list CDR2";
    default: return "unknown";
  }
}

}  // namespace

CdrReader::CdrReader(std::string_view data) : data_(data) {
  if (data_.size() < kHeaderBytes) {
    throw CdrError("CDR: message of " + std::to_string(data_.size()) +
                   " bytes is shorter than the 4-byte encapsulation header");
  }
  const uint16_t kind = static_cast<uint16_t>(static_cast<uint8_t>(data_[0]) << 8 | static_cast<uint8_t>(data_[1]));
  if (kind != 0x0000 && kind != 0x0001) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "0x%04X", kind);
    throw CdrError(std::string("CDR: encapsulation kind ") + hex + " (" + KindName(kind) +
                   ") is not supported; only plain CDR: 0x0000 big-endian, 0x0001 little-endian");
  }
  big_endian_ = kind == 0x0000;
  swap_ = big_endian_ != (std::endian::native == std::endian::big);
  pos_ = kHeaderBytes;
}

// Primitives: aligned to their size from the end of the header, in the
// message's byte order.

#define LOCAID_CDR_PRIMITIVE(Name, Type, what)                                               \
  Type CdrReader::Name() {                                                                  \
    Align(sizeof(Type));                                                                    \
    return Load<Type>(Take(sizeof(Type), what), swap_);                                     \
  }
LOCAID_CDR_PRIMITIVE(U8, uint8_t, "uint8")
LOCAID_CDR_PRIMITIVE(I8, int8_t, "int8")
LOCAID_CDR_PRIMITIVE(U16, uint16_t, "uint16")
LOCAID_CDR_PRIMITIVE(I16, int16_t, "int16")
LOCAID_CDR_PRIMITIVE(U32, uint32_t, "uint32")
LOCAID_CDR_PRIMITIVE(I32, int32_t, "int32")
LOCAID_CDR_PRIMITIVE(U64, uint64_t, "uint64")
LOCAID_CDR_PRIMITIVE(I64, int64_t, "int64")
LOCAID_CDR_PRIMITIVE(F32, float, "float32")
LOCAID_CDR_PRIMITIVE(F64, double, "float64")
#undef LOCAID_CDR_PRIMITIVE

bool CdrReader::Bool() { return *Take(1, "bool") != 0; }

// uint32 length including the NUL, then the bytes. Length 0 (some writers'
// empty string) and a missing NUL are tolerated.
std::string CdrReader::String() {
  Align(4);
  const size_t at = pos_;
  const uint32_t length = Load<uint32_t>(Take(4, "string length"), swap_);
  if (length > remaining()) {
    throw CdrError("CDR: string at offset " + std::to_string(at) + " states " + std::to_string(length) +
                   " bytes, " + std::to_string(remaining()) + " left");
  }
  std::string_view text(Take(length, "string"), length);
  if (!text.empty() && text.back() == '\0') text.remove_suffix(1);
  return std::string(text);
}

// An element is at least one byte even when the caller says 0 (a ROS 2 message
// without fields still has one uint8 member), so `count` can always be reserved.
uint32_t CdrReader::SequenceLength(size_t min_element_bytes) {
  Align(4);
  const size_t at = pos_;
  const uint32_t count = Load<uint32_t>(Take(4, "sequence length"), swap_);
  const size_t min_bytes = min_element_bytes == 0 ? 1 : min_element_bytes;
  if (count > remaining() / min_bytes) {
    throw CdrError("CDR: sequence at offset " + std::to_string(at) + " states " + std::to_string(count) +
                   " elements of at least " + std::to_string(min_bytes) + " bytes, " + std::to_string(remaining()) +
                   " bytes left");
  }
  return count;
}

std::string_view CdrReader::Bytes(size_t n) { return {Take(n, "byte array"), n}; }

void CdrReader::F64Array(double* out, size_t n) {
  if (n == 0) return;  // an empty array is not aligned (Fast-CDR aligns only when there are elements)
  Align(8);
  if (n > remaining() / 8) {
    throw CdrError("CDR: float64 array of " + std::to_string(n) + " at offset " + std::to_string(pos_) + " needs " +
                   std::to_string(n) + " x 8 bytes, " + std::to_string(remaining()) + " left");
  }
  const char* p = Take(n * 8, "float64 array");
  for (size_t i = 0; i < n; ++i) out[i] = Load<double>(p + 8 * i, swap_);
}

// Padding that runs past the end stops at the end: the read after it reports.
void CdrReader::Align(size_t n) {
  const size_t pad = (n - (pos_ - kHeaderBytes) % n) % n;
  pos_ = pad > remaining() ? data_.size() : pos_ + pad;
}

const char* CdrReader::Take(size_t n, const char* what) {
  if (n > remaining()) {
    throw CdrError(std::string("CDR: ") + what + " at offset " + std::to_string(pos_) + " needs " +
                   std::to_string(n) + (n == 1 ? " byte, " : " bytes, ") + std::to_string(remaining()) + " left");
  }
  const char* p = data_.data() + pos_;
  pos_ += n;
  return p;
}

}  // namespace locaid::ros
