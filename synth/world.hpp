// The synthetic street world along a Route: road with markings, curbs,
// sidewalks, verges, building rows with facades, trees, hedges, fences, lamp
// poles, signs, parked cars (static, generated once in chunks along the
// route) and oncoming cars (moving, placed per frame).
//
// A Route that follows a measured track (route mode) may come near itself:
// streets side by side, crossings, and places it drives again (loops). There
// nothing the world puts beside the road reaches past half the way to another
// part of the route (clearance), and of two chunks that lie on one place
// (roads within kConflictM of each other, further apart than kLocalM along
// the route) Collect draws only the one nearer the camera along the route,
// so a place driven again shows one road and one set of buildings.
#pragma once

#include "synth/motion.hpp"
#include "synth/renderer.hpp"
#include "synth/texture.hpp"

#include <cstdint>
#include <vector>

namespace locaid::synth {

struct WorldConfig {
  double segment_m = kRoadBlockLength / 20;  // ground strip step (2.048 m)
  double view_ahead_m = 200;                 // route distance drawn ahead of the camera
  double view_behind_m = 30;
  double oncoming_spacing_m = 110;           // mean spacing of oncoming cars
};

class World {
 public:
  World(const Route& route, const std::vector<MipTexture>& textures, uint64_t seed,
        double duration_s, const WorldConfig& config = {});

  // Polygons to draw for a camera at route position s_cam at time t.
  // Pointers stay valid until the next call.
  void Collect(double s_cam, double t, const Eigen::Vector3d& cam_pos_enu,
               std::vector<const Poly*>& out);

  size_t num_static_polys() const;

  static constexpr double kConflictM = 12.5;  // route mode: roads this close overlap
  static constexpr double kLocalM = 40;       // route mode: nearer than this along the route is one road

 private:
  struct Mover { double s0, speed_mps, length_m, shade; int style; };
  const Route& route_;
  const std::vector<MipTexture>& tex_;
  WorldConfig cfg_;
  double chunk_m_;
  std::vector<std::vector<Poly>> chunks_;
  std::vector<Mover> movers_;
  std::vector<Poly> dynamic_;
  double ground_floor_z_ = 0;
  // Route mode: the chunks each chunk overlaps, and each chunk's lowest road.
  std::vector<std::vector<int>> conflicts_;
  std::vector<double> chunk_floor_z_;
  std::vector<char> drawn_;
  void FindConflicts();
};

}  // namespace locaid::synth
