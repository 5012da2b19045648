#include "synth/world.hpp"

#include "synth/random.hpp"
#include "synth/world_parts.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

namespace locaid::synth {

using parts::AddCar;
using parts::Builder;
using parts::CenterSamples;
using parts::kPi;

World::World(const Route& route, const std::vector<MipTexture>& textures, uint64_t seed,
             double duration_s, const WorldConfig& config)
    : route_(route), tex_(textures), cfg_(config) {
  chunk_m_ = cfg_.segment_m * 8;
  const double L = route.length_m();
  chunks_.resize(static_cast<int>(std::ceil(L / chunk_m_)) + 1);
  Rng rng(seed, 5);
  ground_floor_z_ = parts::BuildStaticWorld(route, textures, chunks_, chunk_m_, cfg_.segment_m, rng);
  // Oncoming traffic on the left lane.
  const double span = L + 15.0 * duration_s;
  for (double s0 = rng.Uniform(60, 150); s0 < span; s0 += rng.Uniform(0.4, 1.6) * cfg_.oncoming_spacing_m) {
    movers_.push_back({s0, rng.Uniform(7, 14), rng.Uniform(4.0, 5.0), rng.Uniform(0.25, 1.35),
                       rng.Chance(0.15) ? 2 : rng.Int(0, 1)});
  }
  if (route.follows_track()) FindConflicts();
}

void World::FindConflicts() {
  const int n = static_cast<int>(chunks_.size());
  conflicts_.assign(static_cast<size_t>(n), {});
  chunk_floor_z_.assign(static_cast<size_t>(n), 1e9);
  drawn_.assign(static_cast<size_t>(n), 0);
  // What a chunk holds starts in it and reaches up to kReachM further (a building's width).
  constexpr double kReachM = 25;
  const CenterSamples cs(route_, 1.0);
  auto for_chunks_at = [&](double s, auto f) {
    const int hi = std::clamp(static_cast<int>(s / chunk_m_), 0, n - 1);
    for (int c = std::max(0, static_cast<int>((s - kReachM) / chunk_m_) - 1); c <= hi; ++c)
      if (s >= c * chunk_m_ && s <= (c + 1) * chunk_m_ + kReachM) f(c);
  };
  for (int i = 0; i < cs.size(); ++i) {
    double& floor_z = chunk_floor_z_[static_cast<size_t>(std::clamp(static_cast<int>(cs.s(i) / chunk_m_), 0, n - 1))];
    floor_z = std::min(floor_z, route_.Elevation(cs.s(i)));
    cs.Near(cs.p(i), kConflictM, [&](int j) {
      if (std::abs(cs.s(j) - cs.s(i)) <= kLocalM) return;
      for_chunks_at(cs.s(i), [&](int a) {
        for_chunks_at(cs.s(j), [&](int b) {
          if (a != b) conflicts_[static_cast<size_t>(a)].push_back(b);
        });
      });
    });
  }
  for (auto& c : conflicts_) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }
}

void World::Collect(double s_cam, double t, const Eigen::Vector3d& cam_pos_enu,
                    std::vector<const Poly*>& out) {
  out.clear();
  const int c0 = std::max(0, static_cast<int>((s_cam - cfg_.view_behind_m) / chunk_m_));
  const int c1 = std::min(static_cast<int>(chunks_.size()) - 1,
                          static_cast<int>((s_cam + cfg_.view_ahead_m) / chunk_m_));
  const bool track = route_.follows_track();
  double floor_z = ground_floor_z_;
  if (track) {
    // The chunk under the camera and those ahead, nearest first, then those
    // behind (out of its view); one that lies on the place of a chunk drawn
    // already is left out.
    auto distance = [&](int c) {
      const double start = c * chunk_m_, end = start + chunk_m_;
      return end > s_cam ? std::max(0.0, start - s_cam) : cfg_.view_ahead_m + (s_cam - end);
    };
    std::vector<int> order(static_cast<size_t>(std::max(0, c1 - c0 + 1)));
    std::iota(order.begin(), order.end(), c0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return distance(a) < distance(b); });
    std::fill(drawn_.begin(), drawn_.end(), 0);
    floor_z = 1e9;
    for (int c : order) {
      bool free = true;
      for (int other : conflicts_[static_cast<size_t>(c)]) free = free && !drawn_[static_cast<size_t>(other)];
      drawn_[static_cast<size_t>(c)] = free;
      if (free) floor_z = std::min(floor_z, chunk_floor_z_[static_cast<size_t>(c)]);
    }
    if (floor_z > 1e8) floor_z = ground_floor_z_;
  }
  for (int c = c0; c <= c1; ++c)
    if (!track || drawn_[static_cast<size_t>(c)])
      for (const Poly& p : chunks_[c]) out.push_back(&p);
  dynamic_.clear();
  Builder b{tex_, &dynamic_};
  for (const Mover& m : movers_) {
    const double s = m.s0 - m.speed_mps * t;
    if (s < s_cam - 10 || s > s_cam + cfg_.view_ahead_m || s < 1 || s > route_.length_m() - 1) continue;
    if (track && !drawn_[static_cast<size_t>(std::clamp(static_cast<int>(s / chunk_m_), 0,
                                                         static_cast<int>(chunks_.size()) - 1))])
      continue;
    AddCar(b, route_.Point(s, 1.75, 0), route_.Heading(s) + kPi, m.length_m, static_cast<float>(m.shade), m.style);
  }
  // Fallback ground far below the route: fills holes to the horizon.
  const double R = 2000, z = floor_z - 0.6;
  const Eigen::Vector3d o(cam_pos_enu.x() - R, cam_pos_enu.y() - R, z);
  b.Rect(o, Eigen::Vector3d(2 * R, 0, 0), Eigen::Vector3d(0, 2 * R, 0), std::fmod(o.x(), 10.24),
         std::fmod(o.y(), 10.24), 1, kTexGrass, 0.8f, Eigen::Vector3d::UnitZ());
  dynamic_.back().background = true;
  for (const Poly& p : dynamic_) out.push_back(&p);
}

size_t World::num_static_polys() const {
  size_t n = 0;
  for (const auto& c : chunks_) n += c.size();
  return n;
}

}  // namespace locaid::synth
