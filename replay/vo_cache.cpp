#include "replay/vo_cache.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace locaid::pipeline {

std::string VoCacheHeader(const std::string& drive, const std::string& method, size_t frames) {
  return "locaid-vo-cache v3 method=" + method + " frames=" + std::to_string(frames) + " drive=" + drive;
}

std::optional<VoResults> ReadVoCache(const std::string& path, const std::string& expected_header) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::string header;
  std::getline(in, header);
  if (header != expected_header)
    throw std::runtime_error(path + ": VO cache written for another run (\"" + header + "\", expected \"" +
                             expected_header + "\"); delete it or pick another file");
  VoResults results;
  std::string line;
  size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ls(line);
    int64_t index = -1;
    int status = 0;
    vo::RelativeMotion m;
    ls >> index >> m.t_ns >> m.t_prev_ns >> status >> m.inliers;
    Eigen::Matrix<double, 3, 4> T;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) ls >> T(r, c);
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) {
        ls >> m.covariance(r, c);
        m.covariance(c, r) = m.covariance(r, c);
      }
    const bool in_order = results.empty() || index > results.rbegin()->first;
    if (!ls || index < 0 || !in_order || status < 0 || status > 2)
      throw std::runtime_error(path + ":" + std::to_string(line_no) + ": malformed VO cache line");
    m.status = static_cast<vo::Status>(status);
    m.T_prev_curr.matrix().topRows<3>() = T;
    results.emplace(index, m);
  }
  return results;
}

void WriteVoCache(const std::string& path, const std::string& header, const VoResults& results) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw std::runtime_error(tmp + ": cannot write");
    out << header << '\n' << std::setprecision(17);
    for (const auto& [index, m] : results) {
      out << index << ' ' << m.t_ns << ' ' << m.t_prev_ns << ' ' << static_cast<int>(m.status) << ' ' << m.inliers;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) out << ' ' << m.T_prev_curr.matrix()(r, c);
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) out << ' ' << m.covariance(r, c);
      out << '\n';
    }
    if (!out.flush()) throw std::runtime_error(tmp + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

RecordedOdometry::RecordedOdometry(const VoResults& results) {
  for (const auto& [index, m] : results) by_time_.emplace(m.t_ns, m);
}

vo::RelativeMotion RecordedOdometry::Track(const vo::StereoFrame& frame) {
  const auto it = by_time_.find(frame.t_ns);
  if (it == by_time_.end())
    throw std::runtime_error("VO cache: no result for the frame at t_ns " + std::to_string(frame.t_ns));
  return it->second;
}

}  // namespace locaid::pipeline
