// locaid-replay --vo-cache: the VO results of a drive kept in a text file so
// filter experiments can rerun without VO, and replayed as an odometry.
//
// One frame per line: index t_ns t_prev_ns status inliers, T_prev_curr (3x4
// row major), covariance (6x6 upper triangle, row major). The header names
// the drive, method and frame range; a cache that does not match is an error.
#pragma once

#include "vo/stereo_odometry.hpp"

#include <cstdint>
#include <map>
#include <optional>
#include <string>

namespace locaid::pipeline {

// VO results by frame index (motion.t_ns is the frame's time).
using VoResults = std::map<int64_t, vo::RelativeMotion>;

std::string VoCacheHeader(const std::string& drive, const std::string& method, size_t frames);

// nullopt when `path` does not exist; throws std::runtime_error for another
// run's cache or a malformed line ("FILE:LINE: ...").
std::optional<VoResults> ReadVoCache(const std::string& path, const std::string& expected_header);
// Written to PATH.tmp, then renamed.
void WriteVoCache(const std::string& path, const std::string& header, const VoResults& results);

// The recorded results played back as an odometry: Track returns the motion
// recorded at the frame's time and throws std::runtime_error if there is none.
class RecordedOdometry final : public vo::StereoOdometry {
 public:
  explicit RecordedOdometry(const VoResults& results);
  vo::RelativeMotion Track(const vo::StereoFrame& frame) override;
  void Reset() override {}

 private:
  std::map<int64_t, vo::RelativeMotion> by_time_;
};

}  // namespace locaid::pipeline
