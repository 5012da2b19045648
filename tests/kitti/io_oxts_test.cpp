#include "kitti/oxts.hpp"
#include "error_of.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace locaid::kitti {
namespace {

// A real line of the excerpt (oxts/data/0000000003.txt).
const std::string kRealLine =
    "49.032378698576 8.3428760305802 112.33502197266 0.039668 0.015909 1.5913123267949 "
    "4.3271053447799 -0.13110577168561 4.3302559016146 0.049276788067019 "
    "-0.027163118966863 0.40707561227517 -1.4396694397667 9.9295784896075 "
    "0.56588790855456 -1.8166342616773 9.8598887231794 0.03395818214106 "
    "-0.017821585759576 -0.37589617479019 0.027895328327921 -0.003488976655857 "
    "-0.37680103996804 0.32606901110041 0.035355339059327 4 8 4 4 0";

std::string ErrorOf(const std::string& line) {
  return locaid::test_support::ErrorOf<Error>([&] { ParseOxtsLine(line, "f.txt:1"); });
}

// Replaces token `i` (0-based) of kRealLine.
std::string WithField(int i, const std::string& value) {
  std::string out;
  size_t pos = 0;
  for (int k = 0; k < kOxtsFieldCount; ++k) {
    size_t end = kRealLine.find(' ', pos);
    if (end == std::string::npos) end = kRealLine.size();
    if (!out.empty()) out += ' ';
    out += (k == i) ? value : kRealLine.substr(pos, end - pos);
    pos = end + 1;
  }
  return out;
}

TEST(IoOxts, ParsesRealLine) {
  const OxtsRecord r = ParseOxtsLine(kRealLine, "x");
  EXPECT_DOUBLE_EQ(r.lat_deg, 49.032378698576);
  EXPECT_DOUBLE_EQ(r.lon_deg, 8.3428760305802);
  EXPECT_DOUBLE_EQ(r.yaw_rad, 1.5913123267949);
  EXPECT_DOUBLE_EQ(r.az_mps2, 9.9295784896075);
  EXPECT_DOUBLE_EQ(r.vel_accuracy_mps, 0.035355339059327);
  EXPECT_EQ(r.navstat, 4);
  EXPECT_EQ(r.numsats, 8);
  EXPECT_EQ(r.orimode, 0);
}

TEST(IoOxts, RejectsWrongFieldCount) {
  const std::string truncated = kRealLine.substr(0, kRealLine.rfind(' '));
  EXPECT_EQ(ErrorOf(truncated), "f.txt:1: 29 fields, expected 30");
  EXPECT_EQ(ErrorOf(kRealLine + " 7"), "f.txt:1: 31 fields, expected 30");
  EXPECT_EQ(ErrorOf(""), "f.txt:1: 0 fields, expected 30");
  // A line cut in the middle of a number still has the wrong count.
  EXPECT_NE(ErrorOf(kRealLine.substr(0, 40)).find("fields, expected 30"), std::string::npos);
}

TEST(IoOxts, RejectsNonNumbersNamingTheField) {
  EXPECT_EQ(ErrorOf(WithField(6, "abc")), "f.txt:1: field 7 (vn) is not a number: 'abc'");
  EXPECT_EQ(ErrorOf(WithField(2, "1.5x")), "f.txt:1: field 3 (alt) is not a number: '1.5x'");
  EXPECT_EQ(ErrorOf(WithField(12, "nan")), "f.txt:1: field 13 (ay) is NaN: 'nan'");
  EXPECT_EQ(ErrorOf(WithField(17, "-inf")), "f.txt:1: field 18 (wx) is infinite: '-inf'");
  EXPECT_EQ(ErrorOf(WithField(3, "1e999")), "f.txt:1: field 4 (roll) overflows a double: '1e999'");
  EXPECT_EQ(ErrorOf(WithField(4, "--1")), "f.txt:1: field 5 (pitch) is not a number: '--1'");
  EXPECT_EQ(ErrorOf(WithField(4, "+-1")), "f.txt:1: field 5 (pitch) is not a number: '+-1'");
  EXPECT_EQ(ErrorOf(WithField(4, "0x10")), "f.txt:1: field 5 (pitch) is not a number: '0x10'");
  // Underflow is a number (reads as 0 or a subnormal), not an error.
  EXPECT_EQ(ParseOxtsLine(WithField(3, "1e-400"), "x").roll_rad, 0.0);
  EXPECT_EQ(ParseOxtsLine(WithField(3, "+2.5"), "x").roll_rad, 2.5);
}

TEST(IoOxts, RejectsOutOfRangeLatLon) {
  EXPECT_EQ(ErrorOf(WithField(0, "90.5")), "f.txt:1: field 1 (lat) = 90.5 outside [-90, 90] deg");
  EXPECT_EQ(ErrorOf(WithField(1, "-180.01")),
            "f.txt:1: field 2 (lon) = -180.01 outside [-180, 180] deg");
  EXPECT_NO_THROW(ParseOxtsLine(WithField(0, "-90"), "x"));
  EXPECT_NO_THROW(ParseOxtsLine(WithField(1, "180"), "x"));
}

TEST(IoOxts, RejectsNonIntegralStatusFields) {
  EXPECT_EQ(ErrorOf(WithField(26, "8.5")), "f.txt:1: field 27 (numsats) must be an integer: '8.5'");
  EXPECT_EQ(ErrorOf(WithField(29, "0.1")), "f.txt:1: field 30 (orimode) must be an integer: '0.1'");
  EXPECT_EQ(ParseOxtsLine(WithField(25, "4.0"), "x").navstat, 4);
}

TEST(IoOxts, WriteRoundTripsExactly) {
  OxtsRecord r = ParseOxtsLine(kRealLine, "x");
  r.alt_m = 1.0 / 3.0;
  r.wu_radps = -1e-300;
  r.posmode = -2;
  const OxtsRecord back = ParseOxtsLine(WriteOxtsLine(r), "x");
  EXPECT_EQ(WriteOxtsLine(back), WriteOxtsLine(r));
  EXPECT_EQ(back.alt_m, r.alt_m);
  EXPECT_EQ(back.wu_radps, r.wu_radps);
  EXPECT_EQ(back.lat_deg, r.lat_deg);
  EXPECT_EQ(back.posmode, -2);
}

TEST(IoOxts, ReadFileNamesPathAndLine) {
  const test_support::ScopedTempDir dir("io_oxts");
  const auto good = dir / "0000000003.txt";
  std::ofstream(good) << kRealLine << "\n";
  EXPECT_DOUBLE_EQ(ReadOxtsFile(good).lat_deg, 49.032378698576);

  const auto bad = dir / "0000000004.txt";
  std::ofstream(bad) << WithField(6, "abc") << "\n";
  try {
    ReadOxtsFile(bad);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), bad.string() + ":1: field 7 (vn) is not a number: 'abc'");
  }
  const auto empty = dir / "0000000005.txt";
  std::ofstream(empty) << "\n";
  EXPECT_THROW(ReadOxtsFile(empty), Error);
  EXPECT_THROW(ReadOxtsFile(dir / "absent.txt"), Error);
}

}  // namespace
}  // namespace locaid::kitti
