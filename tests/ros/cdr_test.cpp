// CdrReader: both byte orders, alignment counted from the end of the
// encapsulation header, strings, sequences, and errors on every cut.
#include "error_of.hpp"
#include "ros/cdr.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>
#include <vector>

namespace locaid::ros {
namespace {

using test_support::ErrorOf;

std::string Bytes(std::initializer_list<int> bytes) {
  std::string out;
  for (const int b : bytes) out.push_back(static_cast<char>(b));
  return out;
}

// A plain-CDR encoder for the tests, written independently of the reader.
class CdrWriter {
 public:
  explicit CdrWriter(bool big_endian) : big_endian_(big_endian) { out_ = Bytes({0, big_endian ? 0 : 1, 0, 0}); }

  template <typename T>
  CdrWriter& Put(T value) {
    while ((out_.size() - 4) % sizeof(T) != 0) out_.push_back('\0');
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    if (big_endian_ != (std::endian::native == std::endian::big)) std::reverse(bytes, bytes + sizeof(T));
    out_.append(bytes, sizeof(T));
    return *this;
  }
  CdrWriter& PutString(const std::string& s) {
    Put<uint32_t>(static_cast<uint32_t>(s.size() + 1));
    out_ += s;
    out_.push_back('\0');
    return *this;
  }
  const std::string& bytes() const { return out_; }

 private:
  bool big_endian_;
  std::string out_;
};

// The fields of a made-up message covering every reader method, in order.
std::string EncodeSample(bool big_endian) {
  CdrWriter w(big_endian);
  w.Put<int32_t>(-7).Put<uint32_t>(123456789u).PutString("base_link");
  w.Put<double>(3.25).Put<uint8_t>(1).Put<uint16_t>(0xBEEF).Put<int8_t>(-3).Put<int16_t>(-300);
  w.Put<uint64_t>(0x0102030405060708ull).Put<int64_t>(-9'000'000'000ll).Put<float>(1.5f);
  w.Put<uint32_t>(3).Put<double>(1.0).Put<double>(-2.0).Put<double>(0.5);  // float64[] of 3
  w.Put<uint32_t>(5);
  return w.bytes() + "\x01\x02\x03\x04\x05";  // uint8[] of 5: no alignment
}

void ReadSample(CdrReader& r) {
  EXPECT_EQ(r.I32(), -7);
  EXPECT_EQ(r.U32(), 123456789u);
  EXPECT_EQ(r.String(), "base_link");
  EXPECT_EQ(r.F64(), 3.25);
  EXPECT_TRUE(r.Bool());
  EXPECT_EQ(r.U16(), 0xBEEF);
  EXPECT_EQ(r.I8(), -3);
  EXPECT_EQ(r.I16(), -300);
  EXPECT_EQ(r.U64(), 0x0102030405060708ull);
  EXPECT_EQ(r.I64(), -9'000'000'000ll);
  EXPECT_EQ(r.F32(), 1.5f);
  const uint32_t n = r.SequenceLength(8);
  ASSERT_EQ(n, 3u);
  std::vector<double> values(n);
  r.F64Array(values.data(), n);
  EXPECT_EQ(values, (std::vector<double>{1.0, -2.0, 0.5}));
  const uint32_t bytes = r.SequenceLength(1);
  ASSERT_EQ(bytes, 5u);
  EXPECT_EQ(r.Bytes(bytes), "\x01\x02\x03\x04\x05");
}

TEST(CdrReader, ReadsBothByteOrders) {
  for (const bool big_endian : {false, true}) {
    SCOPED_TRACE(big_endian ? "big-endian" : "little-endian");
    const std::string data = EncodeSample(big_endian);
    CdrReader r(data);
    EXPECT_EQ(r.big_endian(), big_endian);
    EXPECT_EQ(r.offset(), 4u);
    ReadSample(r);
    EXPECT_EQ(r.remaining(), 0u);
  }
}

// Written out by hand: string "a" (length 2 with the NUL) ends at offset 10;
// a float64 is then aligned to 8 from offset 4, so it sits at 12..20.
TEST(CdrReader, AlignsAfterAStringFromTheEndOfTheHeader) {
  const std::string le = Bytes({0, 1, 0, 0, 2, 0, 0, 0, 'a', 0, 0xEE, 0xEE, 0, 0, 0, 0, 0, 0, 0xF0, 0x3F, 9, 0xEE, 0x34, 0x12});
  CdrReader r(le);
  EXPECT_EQ(r.String(), "a");
  EXPECT_EQ(r.offset(), 10u);
  EXPECT_EQ(r.F64(), 1.0);
  EXPECT_EQ(r.offset(), 20u);
  EXPECT_EQ(r.U8(), 9);
  EXPECT_EQ(r.U16(), 0x1234);  // offset 21 -> 22
  EXPECT_EQ(r.remaining(), 0u);
}

TEST(CdrReader, BigEndianLiteral) {
  const std::string be = Bytes({0, 0, 0, 0, 0, 0, 0, 2, 'a', 0, 0, 0, 0x3F, 0xF0, 0, 0, 0, 0, 0, 0});
  CdrReader r(be);
  EXPECT_TRUE(r.big_endian());
  EXPECT_EQ(r.String(), "a");
  EXPECT_EQ(r.F64(), 1.0);
  EXPECT_EQ(r.remaining(), 0u);
}

// Fast-CDR aligns an array only when it has elements: an empty float64[]
// leaves the next field right after its count.
TEST(CdrReader, EmptyFloat64ArrayIsNotAligned) {
  const std::string data = Bytes({0, 1, 0, 0, 0, 0, 0, 0, 7});
  CdrReader r(data);
  double unused = 0;
  ASSERT_EQ(r.SequenceLength(8), 0u);
  r.F64Array(&unused, 0);
  EXPECT_EQ(r.U8(), 7);
}

TEST(CdrReader, StringsOfLengthZeroAndWithoutNulAreTolerated) {
  const std::string data = Bytes({0, 1, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0, 'a', 'b', 'c', 0, 2, 0, 0, 0, 'x', 'y'});
  CdrReader r(data);
  EXPECT_EQ(r.String(), "");
  EXPECT_EQ(r.String(), "abc");  // ... and a NUL beyond the stated length is the next field's
  EXPECT_EQ(r.offset(), 15u);
  EXPECT_EQ(r.U8(), 0);
  EXPECT_EQ(r.String(), "xy");
}

TEST(CdrReader, ErrorsNameTheFieldTheOffsetAndTheBytesLeft) {
  const std::string data = Bytes({0, 1, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9});
  CdrReader r(data);
  EXPECT_EQ(r.U64(), 0x0807060504030201u);
  EXPECT_EQ(ErrorOf<CdrError>([&] { r.F64(); }), "CDR: float64 at offset 12 needs 8 bytes, 3 left");
  EXPECT_EQ(ErrorOf<CdrError>([&] { r.String(); }), "CDR: string length at offset 12 needs 4 bytes, 3 left");
  EXPECT_EQ(ErrorOf<CdrError>([&] { r.Bytes(4); }), "CDR: byte array at offset 12 needs 4 bytes, 3 left");
  const std::string lying = Bytes({0, 1, 0, 0, 0x10, 0, 0, 0, 'a', 'b'});
  CdrReader s(lying);
  EXPECT_EQ(ErrorOf<CdrError>([&] { s.String(); }), "CDR: string at offset 4 states 16 bytes, 2 left");
}

TEST(CdrReader, EveryCutOfAMessageThrowsCdrError) {
  for (const bool big_endian : {false, true}) {
    const std::string data = EncodeSample(big_endian);
    for (size_t n = 0; n < data.size(); ++n) {
      SCOPED_TRACE("cut at " + std::to_string(n));
      const std::string error = ErrorOf<CdrError>([&] {
        CdrReader r(std::string_view(data).substr(0, n));
        ReadSample(r);
      });
      EXPECT_EQ(error.rfind("CDR: ", 0), 0u) << error;
      if (n >= 4) {
        EXPECT_NE(error.find(" at offset "), std::string::npos) << error;
      }
    }
  }
}

TEST(CdrReader, HugeSequenceCountIsRefusedBeforeAnyAllocation) {
  const std::string data = Bytes({0, 1, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 1, 2, 3, 4, 5, 6, 7, 8});
  for (const size_t min_bytes : {size_t{0}, size_t{1}, size_t{8}, size_t{1} << 62}) {
    CdrReader r(data);
    const std::string error = ErrorOf<CdrError>([&] { r.SequenceLength(min_bytes); });
    EXPECT_NE(error.find("sequence at offset 4 states 4294967295 elements"), std::string::npos) << error;
  }
  std::vector<double> one(1);
  CdrReader huge(data);
  EXPECT_NE(ErrorOf<CdrError>([&] { huge.F64Array(one.data(), size_t{1} << 61); }).find("float64 array"),
            std::string::npos);
  CdrReader array(data);
  array.F64Array(one.data(), 1);  // aligned to 8 from offset 4: bytes 4..12
  EXPECT_EQ(array.offset(), 12u);
  const std::string count_fits = Bytes({0, 1, 0, 0, 2, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16});
  CdrReader fits(count_fits);
  EXPECT_EQ(fits.SequenceLength(8), 2u);
}

TEST(CdrReader, RefusesEncapsulationsOtherThanPlainCdr) {
  EXPECT_NE(ErrorOf<CdrError>([] { CdrReader r(Bytes({0, 1, 0})); }).find("shorter than the 4-byte"),
            std::string::npos);
  const std::string pl = ErrorOf<CdrError>([] { CdrReader r(Bytes({0, 3, 0, 0, 1, 2, 3, 4})); });
  EXPECT_NE(pl.find("0x0003"), std::string::npos) << pl;
  EXPECT_NE(pl.find("PL_CDR_LE"), std::string::npos) << pl;
  EXPECT_NE(ErrorOf<CdrError>([] { CdrReader r(Bytes({0, 7, 0, 0})); }).find("XCDR2"), std::string::npos);
  EXPECT_NE(ErrorOf<CdrError>([] { CdrReader r(Bytes({1, 0, 0, 0})); }).find("0x0100"), std::string::npos);
  EXPECT_EQ(ErrorOf<CdrError>([] { CdrReader r(Bytes({0, 1, 9, 9})); }), "(no error)");  // options ignored
}

}  // namespace
}  // namespace locaid::ros
