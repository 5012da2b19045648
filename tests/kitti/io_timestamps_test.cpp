#include "kitti/timestamps.hpp"
#include "error_of.hpp"

#include "kitti/types.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;

std::string ErrorOf(const std::string& line) {
  return locaid::test_support::ErrorOf<Error>([&] { ParseTimestamp(line, "ts.txt:4"); });
}

TEST(IoTimestamps, ParsesExactNanoseconds) {
  // 2011-09-26 14:05:35 UTC = 1317045935 s since the epoch (15243 days).
  EXPECT_EQ(ParseTimestamp("2011-09-26 14:05:35.500923136", "x"),
            1317045935LL * 1'000'000'000LL + 500923136LL);
  EXPECT_EQ(ParseTimestamp("1970-01-01 00:00:00.000000001", "x"), 1);
  EXPECT_EQ(ParseTimestamp("2012-02-29 23:59:59.5", "x"),
            (1330559999LL) * 1'000'000'000LL + 500'000'000LL);
  EXPECT_EQ(ParseTimestamp("  2011-09-26 14:05:35.500923136\r", "x"),
            ParseTimestamp("2011-09-26 14:05:35.500923136", "x"));
}

TEST(IoTimestamps, FormatRoundTrips) {
  for (const char* s : {"2011-09-26 14:05:35.500923136", "2000-02-29 00:00:00.000000000",
                        "1969-12-31 23:59:59.999999999", "2038-01-19 03:14:08.123456789"}) {
    EXPECT_EQ(FormatTimestamp(ParseTimestamp(s, "x")), s);
  }
}

TEST(IoTimestamps, RejectsMalformedLines) {
  const std::string want = "ts.txt:4: ";
  EXPECT_EQ(ErrorOf("2011-09-26 14:05"),
            want + "malformed date/time in timestamp '2011-09-26 14:05' (expected "
                   "'YYYY-MM-DD HH:MM:SS.fffffffff')");
  EXPECT_NE(ErrorOf("2011-13-26 14:05:35.5").find("ts.txt:4: month 13 out of range"),
            std::string::npos);
  EXPECT_NE(ErrorOf("2011-02-29 14:05:35.5").find("day 29 out of range"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 24:05:35.5").find("hour 24"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:60:35.5").find("minute 60"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:05:60.5").find("second 60"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:05:35.5009231361").find("10 fraction digits"),
            std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:05:35.").find("0 fraction digits"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:05:35.50x").find("fraction is not all digits"),
            std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26T14:05:35.5").find("malformed"), std::string::npos);
  EXPECT_NE(ErrorOf("").find("malformed"), std::string::npos);
  EXPECT_NE(ErrorOf("2011-09-26 14:05:35 x").find("unexpected text"), std::string::npos);
}

TEST(IoTimestamps, FileRoundTripAndLineNumbers) {
  const test_support::ScopedTempDir dir("io_timestamps");
  const std::vector<int64_t> t = {1317045935500923136LL, 1317045935602942464LL,
                                  1317045935706851072LL};
  WriteTimestampsFile(dir / "timestamps.txt", t);
  EXPECT_EQ(ReadTimestampsFile(dir / "timestamps.txt"), t);

  std::ofstream(dir / "bad.txt") << "2011-09-26 14:05:35.500923136\n2011-09-26 14:05:3\n";
  try {
    ReadTimestampsFile(dir / "bad.txt");
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "bad.txt").string() + ":2: malformed", 0), 0u)
        << e.what();
  }
  std::ofstream(dir / "hole.txt") << "2011-09-26 14:05:35.5\n\n2011-09-26 14:05:35.6\n";
  EXPECT_THROW(ReadTimestampsFile(dir / "hole.txt"), Error);
  std::ofstream(dir / "trailing.txt") << "2011-09-26 14:05:35.5\n\n\n";
  EXPECT_EQ(ReadTimestampsFile(dir / "trailing.txt").size(), 1u);
}

TEST(IoTimestamps, OdometryTimes) {
  const test_support::ScopedTempDir dir("io_timestamps");
  std::ofstream(dir / "times.txt") << "0.000000e+00\n1.037359e-01\n2.073381e-01\n";
  const auto t = ReadOdometryTimes(dir / "times.txt");
  ASSERT_EQ(t.size(), 3u);
  EXPECT_DOUBLE_EQ(t[1], 0.1037359);
  const auto err = [&](const std::string& content) -> std::string {
    std::ofstream(dir / "t.txt") << content;
    try {
      ReadOdometryTimes(dir / "t.txt");
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  };
  const std::string p = (dir / "t.txt").string();
  EXPECT_EQ(err("0.0\nabc\n"), p + ":2: time is not a number: 'abc'");
  EXPECT_EQ(err("0.0\nnan\n"), p + ":2: time is NaN: 'nan'");
  EXPECT_EQ(err("0.0\ninf\n"), p + ":2: time is infinite: 'inf'");
  EXPECT_EQ(err("0.0\n2e9\n"), p + ":2: time 2e9 s exceeds 1e9 s");
  EXPECT_EQ(err("-1\n"), p + ":1: negative time -1");
  EXPECT_NE(err("0.2\n0.1\n").find(":2: time 0.1 s goes back"), std::string::npos);
}

}  // namespace
}  // namespace locaid::kitti
