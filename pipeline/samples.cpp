#include "pipeline/samples.hpp"

#include <algorithm>
#include <iterator>
#include <utility>

namespace locaid::pipeline {
namespace {

template <typename T, typename Time>
void MoveWhile(std::vector<T>& from, std::vector<T>& to, int64_t t_ns, Time time_of) {
  const auto end = std::find_if(from.begin(), from.end(), [&](const T& s) { return time_of(s) > t_ns; });
  to.insert(to.end(), std::make_move_iterator(from.begin()), std::make_move_iterator(end));
  from.erase(from.begin(), end);
}

}  // namespace

void SampleBatch::MoveUpTo(int64_t t_ns, SampleBatch& out) {
  auto t = [](const auto& s) { return s.t_ns; };
  MoveWhile(imu, out.imu, t_ns, t);
  MoveWhile(gps, out.gps, t_ns, [](const ArrivedFix& f) { return f.fix.t_ns; });
  MoveWhile(speed, out.speed, t_ns, t);
  MoveWhile(truth_imu, out.truth_imu, t_ns, t);
  MoveWhile(truth_poses, out.truth_poses, t_ns, t);
  if (receiver_has_fix) out.receiver_has_fix = std::exchange(receiver_has_fix, std::nullopt);
}

}  // namespace locaid::pipeline
