// libFuzzer target: raw timestamps.txt lines/files and odometry times.txt
// (kitti/timestamps.hpp).
// Contract: ParseTimestamp / ReadTimestampsFile / ReadOdometryTimes return or
// throw kitti::Error; FormatTimestamp(ParseTimestamp(x)) parses back to the
// same t_ns; times.txt values are finite, >= 0 and non-decreasing.
#include "fuzz/fuzz_support.hpp"
#include "kitti/timestamps.hpp"
#include "kitti/types.hpp"

#include <cmath>
#include <vector>

namespace {

namespace kitti = locaid::kitti;

void CheckTimestamp(int64_t t_ns) {
  const std::string text = kitti::FormatTimestamp(t_ns);
  int64_t back = 0;
  try {
    back = kitti::ParseTimestamp(text, "round-trip");
  } catch (const kitti::Error& e) {
    locaid::fuzz::Fail(std::string("formatted timestamp does not parse: ") + e.what());
  }
  LOCAID_FUZZ_CHECK(back == t_ns, "round trip changed " + std::to_string(t_ns) + " -> " + text);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static locaid::fuzz::MemFile file;
  const std::string_view text = locaid::fuzz::AsText(data, size);
  try {
    CheckTimestamp(kitti::ParseTimestamp(text, "fuzz"));
  } catch (const kitti::Error&) {
  }
  const std::filesystem::path& path = file.Write(text);
  try {
    for (int64_t t_ns : kitti::ReadTimestampsFile(path)) CheckTimestamp(t_ns);
  } catch (const kitti::Error&) {
  }
  try {
    const std::vector<double> times_s = kitti::ReadOdometryTimes(path);
    for (size_t i = 0; i < times_s.size(); ++i) {
      LOCAID_FUZZ_CHECK(std::isfinite(times_s[i]) && times_s[i] >= 0, "bad time accepted");
      LOCAID_FUZZ_CHECK(i == 0 || times_s[i] >= times_s[i - 1], "decreasing times accepted");
    }
  } catch (const kitti::Error&) {
  }
  return 0;
}
