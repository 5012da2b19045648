// A measured road for a Route to follow (route mode, synth/route_file.hpp):
// the vehicle's track in the local ENU frame as C2 splines of the arc length
// along it.
#pragma once

#include "synth/spline.hpp"

namespace locaid::synth {

struct TrackGeometry {
  // Functions of the arc length s along the track (m): east and north of the
  // vehicle's reference point (the IMU) and the road surface height under it.
  UniformCubicSpline east, north, road_height;
  // The part a Route covers: its s = 0 is the track's s_begin.
  double s_begin = 0, s_end = 0;
  // The road's centre line lies this far left of the track: the track is the
  // middle of the right-hand lane (MotionConfig::lane_offset_m = -1.75).
  double center_shift_m = 1.75;
};

}  // namespace locaid::synth
