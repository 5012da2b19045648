// Regression tests for inputs found by fuzz/fuzz_timestamps (libFuzzer + UBSan).
//
// Crash 1: "9999-12-31 23:59:59.999999999" made ParseTimestamp overflow int64
// (signed overflow, undefined behaviour) instead of throwing kitti::Error.
// int64 nanoseconds since 1970 cover 1677-09-21 .. 2262-04-11, so whole years
// 1678..2261 are accepted and every other year is rejected by name.
#include "kitti/timestamps.hpp"

#include "kitti/types.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

namespace locaid::kitti {
namespace {

std::string ErrorOf(const std::string& line) {
  try {
    const int64_t t_ns = ParseTimestamp(line, "timestamps.txt:2");
    return "(no error, t_ns = " + std::to_string(t_ns) + ")";
  } catch (const Error& e) {
    return e.what();
  }
}

TEST(FuzzRegressionTimestamps, YearsBeyondInt64NanosecondsAreErrors) {
  for (const char* line : {"9999-12-31 23:59:59.999999999", "2262-04-12 00:00:00",
                           "2262-01-01 00:00:00", "1677-12-31 23:59:59", "0000-01-01 00:00:00"}) {
    const std::string error = ErrorOf(line);
    EXPECT_NE(error.find("timestamps.txt:2: year "), std::string::npos) << line << " -> " << error;
    EXPECT_NE(error.find("outside [1678, 2261]"), std::string::npos) << line << " -> " << error;
  }
}

TEST(FuzzRegressionTimestamps, ExtremeAcceptedYearsRoundTrip) {
  for (const char* line : {"2261-12-31 23:59:59.999999999", "1678-01-01 00:00:00.000000000"}) {
    const int64_t t_ns = ParseTimestamp(line, "x");
    EXPECT_EQ(FormatTimestamp(t_ns), line);
  }
  EXPECT_GT(ParseTimestamp("2261-12-31 23:59:59.999999999", "x"), 0);
  EXPECT_LT(ParseTimestamp("1678-01-01 00:00:00", "x"), 0);
}

TEST(FuzzRegressionTimestamps, FileWithFarFutureLineNamesTheLine) {
  const test_support::ScopedTempDir dir("fuzz_regression");
  const std::filesystem::path path = dir / "timestamps.txt";
  {
    std::ofstream out(path);
    out << "2011-09-26 14:05:35.499560704\n9999-12-31 23:59:59.999999999\n";
  }
  try {
    ReadTimestampsFile(path);
    ADD_FAILURE() << "far-future line accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string() + ":2: year 9999"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace locaid::kitti
