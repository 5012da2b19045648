// The synthetic street world along a Route: road with markings, curbs,
// sidewalks, verges, building rows with facades, trees, hedges, fences, lamp
// poles, signs, parked cars (static, generated once in chunks along the
// route) and oncoming cars (moving, placed per frame).
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
};

}  // namespace locaid::synth
