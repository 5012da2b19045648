#include "synth/world_parts.hpp"

#include "synth/world.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace locaid::synth::parts {

void AddCar(Builder& b, const Eigen::Vector3d& o, double heading, double length, float shade, int style) {
  const Eigen::Vector3d f(std::cos(heading), std::sin(heading), 0), l(-std::sin(heading), std::cos(heading), 0);
  const double L2 = length / 2;
  const double roof = style == 2 ? 1.85 : 1.45;  // van / car
  b.Box(o, f, l, -L2, L2, -0.9, 0.9, 0.3, 0.95, kTexCarBody, shade, style * 1.7);
  if (style == 2)
    b.Box(o, f, l, -L2, L2 - 1.0, -0.85, 0.85, 0.95, roof, kTexCarBody, shade * 0.95f, 0.7);
  else
    b.Box(o, f, l, -L2 + 0.7, L2 - 1.4, -0.78, 0.78, 0.95, roof, kTexGlass, 1.0f);
  for (double sx : {-1.0, 1.0})
    for (double sy : {-1.0, 1.0}) {
      const double cx = sx * (L2 - 0.85), cy = sy * 0.79;
      b.Box(o, f, l, cx - 0.31, cx + 0.31, cy - 0.11, cy + 0.11, 0.0, 0.62, kTexTire, 1.0f);
    }
}


namespace {

// Where a world along a route may be built and what goes where: the road's
// directions, how far from the centre line each side may reach, the zones
// (urban or green), the chunk a polygon at route position s goes to. Its
// Build* functions draw one part of the world each, in the order of the
// random numbers a seed gives.
class WorldBuilder {
 public:
  WorldBuilder(const Route& route, const std::vector<MipTexture>& textures, std::vector<std::vector<Poly>>& chunks,
               double chunk_m, double segment_m, Rng& rng)
      : route_(route), textures_(textures), chunks_(chunks), chunk_m_(chunk_m), segment_m_(segment_m), rng_(rng),
        b_{textures, nullptr}, length_m_(route.length_m()), track_(route.follows_track()) {
    // Route mode: how far from the centre line each side may be built before
    // it meets (half the way to) another part of the route: samples every
    // metre; a road nearer than 4 m is the same street, driven again (Collect
    // draws one of the two).
    if (track_) {
      const CenterSamples cs(route_, 1.0);
      for (auto& c : clearance_) c.assign(static_cast<size_t>(cs.size()), 1e9);
      for (int i = 0; i < cs.size(); ++i) {
        const Eigen::Vector2d n(-cs.t(i).y(), cs.t(i).x());
        cs.Near(cs.p(i), 120.0, [&](int j) {
          if (std::abs(j - i) <= 8) return;
          const Eigen::Vector2d w = cs.p(j) - cs.p(i);
          const double lat = w.dot(n);
          if (std::abs(w.dot(cs.t(i))) > 3 || std::abs(lat) < 4) return;
          double& c = clearance_[lat > 0 ? 1 : 0][static_cast<size_t>(i)];
          c = std::min(c, 0.5 * std::abs(lat));
        });
      }
    }
  }


  // Road, curbs, sidewalks and verges, segment by segment; the lowest road
  // elevation.
  double BuildGround() {
    double floor_z = 1e9;
    const int n_seg = static_cast<int>(length_m_ / segment_m_);
    const int seg_per_block = static_cast<int>(std::lround(kRoadBlockLength / segment_m_));
    int variant = 0;
    for (int i = 0; i < n_seg; ++i) {
      const double sa = i * segment_m_, sb = sa + segment_m_;
      b_.out = ChunkOf(sa);
      floor_z = std::min(floor_z, route_.Elevation(sa));
      if (i % seg_per_block == 0) variant = rng_.Int(0, kRoadVariants - 1);
      const double vbase = variant * (kRoadBlockLength / 0.02) + (i % seg_per_block) * (segment_m_ / 0.02);
      const double va = vbase, vb = vbase + segment_m_ / 0.02;
        // Road edges right and left of the centre line: route mode narrows the
      // inside of a curve tighter than the road is wide (texture u: 0 .. 512
      // across the full width).
      double right = kRoadHalfWidth, left = kRoadHalfWidth, u_right = 0, u_left = 512;
      if (track_) {
        right = std::clamp(FoldLimit(sa - 1, sb + 1, -1.0), 0.5, kRoadHalfWidth);
        left = std::clamp(FoldLimit(sa - 1, sb + 1, 1.0), 0.5, kRoadHalfWidth);
        u_right = 256 - right / 0.02;
        u_left = 256 + left / 0.02;
      }
      const Eigen::Vector3d A = route_.Point(sa, -right, 0), B = route_.Point(sa, left, 0), C = route_.Point(sb, left, 0),
                            D = route_.Point(sb, -right, 0);
      b_.Tri(A, B, C, u_right, va, u_left, va, u_left, vb, kTexRoad, 1.0f, kUp);
      b_.Tri(A, C, D, u_right, va, u_left, vb, u_right, vb, kTexRoad, 1.0f, kUp);
      for (double side : {-1.0, 1.0}) {
        // curb face
        const double edge = side > 0 ? left : right;
        const Eigen::Vector3d ca = route_.Point(sa, side * edge, 0), cb = route_.Point(sb, side * edge, 0);
        const double mc = textures_[kTexCurb].m_per_texel;
        b_.Tri(ca, cb, cb + kUp * kCurbH, sa / mc, 0, sb / mc, 0, sb / mc, kCurbH / mc, kTexCurb, 0.95f, -side * Normal(sa));
        b_.Tri(ca, cb + kUp * kCurbH, ca + kUp * kCurbH, sa / mc, 0, sb / mc, kCurbH / mc, sa / mc, kCurbH / mc, kTexCurb, 0.95f, -side * Normal(sa));
        // sidewalk, verge bands
        const double lim = MaxOffset(sa - 2, sb + 2, side);
        const double bands[4] = {kRoadHalfWidth, kRoadHalfWidth + kSidewalkW, 20.0, 60.0};
        for (int k = 0; k < 3; ++k) {
          const double d0 = bands[k], d1 = std::min(bands[k + 1], lim);
          if (d1 <= d0 + 0.1) break;
          const int t = k == 0 ? kTexSidewalk : kTexGrass;
          const double m = textures_[t].m_per_texel;
          const Eigen::Vector3d p00 = route_.Point(sa, side * d0, kCurbH), p01 = route_.Point(sa, side * d1, kCurbH),
                                p11 = route_.Point(sb, side * d1, kCurbH), p10 = route_.Point(sb, side * d0, kCurbH);
          const float sh = k == 0 ? 1.0f : 0.9f;
          b_.Tri(p00, p01, p11, sa / m, d0 / m, sa / m, d1 / m, sb / m, d1 / m, t, sh, kUp);
          b_.Tri(p00, p11, p10, sa / m, d0 / m, sb / m, d1 / m, sb / m, d0 / m, t, sh, kUp);
        }
      }
    }
    return floor_z;
  }

  // Urban and green stretches along the route_.
  void BuildZones() {
    for (double s = 0; s < length_m_;) {
      const bool urban = zones_.empty() ? true : !zones_.back().urban || rng_.Chance(0.3);
      const double len = urban ? rng_.Uniform(150, 450) : rng_.Uniform(80, 250);
      zones_.push_back({s, s + len, urban});
      s += len;
    }
  }

  // Buildings (urban) or vegetation (green) on one side.
  void BuildFrontage(double side) {
    // Walking along s.
    double s = rng_.Uniform(0, 8);
    while (s < length_m_ - 40) {
      b_.out = ChunkOf(s);
      if (IsUrban(s)) {
        const double w = rng_.Uniform(8, 24), depth = rng_.Uniform(10, 14);
        const double d0 = kRoadHalfWidth + kSidewalkW + rng_.Uniform(0.3, 3.5);
        const double height = rng_.Uniform(6, 19.5);
        const double sa = s, sb = std::min(s + w, length_m_ - 30);
        const double d1 = std::min(d0 + depth, MaxOffset(sa - 5, sb + 5, side));
        if (d1 > d0 + 3) {
          const int ftex = kTexFacade0 + rng_.Int(0, kNumFacades - 1);
          const float shade = static_cast<float>(rng_.Uniform(0.8, 1.15));
          double u = rng_.Uniform(0, 20.48);
          const int pieces = std::max(1, static_cast<int>(std::ceil((sb - sa) / 4.0)));
          for (int k = 0; k < pieces; ++k) {
            const double s0 = sa + (sb - sa) * k / pieces, s1 = sa + (sb - sa) * (k + 1) / pieces;
            const Eigen::Vector3d p0 = route_.Point(s0, side * d0, -0.6), p1 = route_.Point(s1, side * d0, -0.6);
            Eigen::Vector3d eu = p1 - p0;
            eu.z() = 0;
            const Eigen::Vector3d base(p0.x(), p0.y(), p0.z() + 0.6 + height);
            // facade texture: row 1024 (= 0) at ground level, rows grow downwards
            b_.Rect(base, eu, -kUp * (height + 0.6), u, 20.48 - height, 1, ftex, shade, -side * Normal(0.5 * (s0 + s1)));
            u += eu.norm();
          }
          // side walls
          for (int e = 0; e < 2; ++e) {
            const double se = e == 0 ? sa : sb;
            const Eigen::Vector3d q0 = route_.Point(se, side * d0, -0.6), q1 = route_.Point(se, side * d1, -0.6);
            Eigen::Vector3d ev = q1 - q0;
            ev.z() = 0;
            const Eigen::Vector3d top(q0.x(), q0.y(), q0.z() + 0.6 + height);
            b_.Rect(top, ev, -kUp * (height + 0.6), rng_.Uniform(0, 7), 0, 1, kTexWall, shade,
                   (e == 0 ? -1.0 : 1.0) * Tangent(se));
          }
        }
        const double gap = rng_.Chance(0.35) ? 0.0 : rng_.Uniform(1.5, 9);
        if (gap > 3 && rng_.Chance(0.5)) {  // fence in the gap, at the back of the sidewalk
          const Eigen::Vector3d f0 = route_.Point(sb, side * (kRoadHalfWidth + kSidewalkW + 0.2), kCurbH);
          const Eigen::Vector3d f1 = route_.Point(sb + gap, side * (kRoadHalfWidth + kSidewalkW + 0.2), kCurbH);
          const double fh = rng_.Uniform(1.0, 1.8);
          if (Fits(sb, sb + gap, side, kRoadHalfWidth + kSidewalkW + 0.2))
            b_.Rect(f0 + kUp * fh, f1 - f0, -kUp * fh, 0, 0, 1, kTexFence, 1.0f, -side * Normal(sb), true);
        }
        s = sb + gap;
      } else {
        const double kind = rng_.Uniform();
        if (kind < 0.55) {  // tree
          const double d = rng_.Uniform(kRoadHalfWidth + kSidewalkW + 1.0, 17);
          if (d < MaxOffset(s - 3, s + 3, side)) {
            const Eigen::Vector3d o = route_.Point(s, side * d, kCurbH - 0.2);
            const double th = rng_.Uniform(2.2, 3.5), cw = rng_.Uniform(1.5, 2.6), ch = rng_.Uniform(2.5, 4.5);
            const double a = rng_.Uniform(0, kPi);
            const Eigen::Vector3d f(std::cos(a), std::sin(a), 0), l(-std::sin(a), std::cos(a), 0);
            b_.Box(o, f, l, -0.15, 0.15, -0.15, 0.15, 0, th + 0.3, kTexBark, 1.0f, rng_.Uniform(0, 1));
            const float sh = static_cast<float>(rng_.Uniform(0.75, 1.1));
            b_.Box(o, f, l, -cw, cw, -cw, cw, th, th + ch, kTexLeaves, sh, rng_.Uniform(0, 5));
            const Eigen::Vector3d f2 = (f + l).normalized(), l2 = (l - f).normalized();
            b_.Box(o, f2, l2, -cw * 0.8, cw * 0.8, -cw * 0.8, cw * 0.8, th + 0.4, th + ch + 0.6, kTexLeaves, sh * 0.9f, rng_.Uniform(0, 5));
          }
          s += rng_.Uniform(5, 14);
        } else if (kind < 0.8) {  // hedge
          const double len = rng_.Uniform(5, 20), d = kRoadHalfWidth + kSidewalkW + rng_.Uniform(0.2, 1.5);
          const double h = rng_.Uniform(0.8, 1.6), th = rng_.Uniform(0.8, 1.4);
          const int pieces = std::max(1, static_cast<int>(std::ceil(len / 4.0)));
          const bool hedge_fits = Fits(s, s + len, side, d + th);
          for (int k = 0; hedge_fits && k < pieces; ++k) {
            const double s0 = s + len * k / pieces, s1 = s + len * (k + 1) / pieces;
            const Eigen::Vector3d o = route_.Point(s0, side * d, kCurbH);
            const Eigen::Vector3d t = Tangent(s0), l = side * Normal(s0);
            b_.Box(o, t, l, 0, (route_.Point(s1, side * d, 0) - route_.Point(s0, side * d, 0)).norm(), 0, th, -0.1, h,
                  kTexLeaves, 0.85f, s0);
          }
          s += len + rng_.Uniform(1, 6);
        } else {  // small house further back
          const double w = rng_.Uniform(7, 12), d0 = rng_.Uniform(16, 28), h = rng_.Uniform(4, 7);
          const double sb = std::min(s + w, length_m_ - 30);
          if (d0 + 9 < MaxOffset(s - 5, sb + 5, side) && sb > s + 3) {
            const int ftex = kTexFacade0 + rng_.Int(0, kNumFacades - 1);
            const Eigen::Vector3d p0 = route_.Point(s, side * d0, -0.6), p1 = route_.Point(sb, side * d0, -0.6);
            Eigen::Vector3d eu = p1 - p0;
            eu.z() = 0;
            const Eigen::Vector3d base(p0.x(), p0.y(), p0.z() + 0.6 + h);
            b_.Rect(base, eu, -kUp * (h + 0.6), rng_.Uniform(0, 20), 20.48 - h, 1, ftex, 1.0f, -side * Normal(s));
            for (int e = 0; e < 2; ++e) {
              const double se = e == 0 ? s : sb;
              const Eigen::Vector3d q0 = route_.Point(se, side * d0, -0.6), q1 = route_.Point(se, side * (d0 + 9), -0.6);
              Eigen::Vector3d ev = q1 - q0;
              ev.z() = 0;
              b_.Rect(Eigen::Vector3d(q0.x(), q0.y(), q0.z() + 0.6 + h), ev, -kUp * (h + 0.6), 0, 0, 1, kTexWall, 1.0f,
                     (e == 0 ? -1.0 : 1.0) * Tangent(se));
            }
          }
          s = sb + rng_.Uniform(3, 10);
        }
      }
    }
  }

  // Lamp poles and signs on one side's sidewalk edge.
  void BuildStreetFurniture(double side) {
    for (double sp = rng_.Uniform(5, 30); sp < length_m_ - 30; sp += rng_.Uniform(24, 42)) {
      b_.out = ChunkOf(sp);
      const Eigen::Vector3d o = route_.Point(sp, side * (kRoadHalfWidth + 0.5), kCurbH);
      const Eigen::Vector3d t = Tangent(sp), l = side * Normal(sp);
      const double ph = rng_.Uniform(6, 8);
      if (Fits(sp - 1, sp + 1, side, kRoadHalfWidth + 0.7)) {
        b_.Box(o, t, l, -0.08, 0.08, -0.08, 0.08, 0, ph, kTexMetal, 1.0f);
        b_.Box(o, t, l, -0.05, 0.05, -1.6, 0.0, ph - 0.12, ph, kTexMetal, 0.9f);     // arm over the road
        b_.Box(o, t, l, -0.18, 0.18, -1.9, -1.3, ph - 0.3, ph - 0.05, kTexMetal, 0.7f);  // lamp head
      }
      if (rng_.Chance(0.35)) {  // traffic sign facing the traffic in our direction
        const double ss = sp + 6;
        const Eigen::Vector3d so = route_.Point(ss, side * (kRoadHalfWidth + 0.6), kCurbH);
        const Eigen::Vector3d st = Tangent(ss), sl = side * Normal(ss);
        const double sz = rng_.Uniform(0.6, 0.9), sign_u = rng_.Uniform(0, 1.28);
        if (Fits(ss - 1, ss + 1, side, kRoadHalfWidth + 1.1)) {
          b_.Box(so, st, sl, -0.04, 0.04, -0.04, 0.04, 0, 2.4, kTexMetal, 1.0f);
          b_.Rect(so + kUp * (2.4 + sz) - sl * (sz / 2) - st * 0.05, sl * sz, -kUp * sz, sign_u, 0, 1, kTexSign, 1.0f,
                 -st);
          b_.Rect(so + kUp * (2.4 + sz) - sl * (sz / 2) - st * 0.06, sl * sz, -kUp * sz, 0, 0, 1, kTexMetal, 0.8f, st);
        }
      }
    }
  }

  // Parked cars in one side's parking strip (urban zones).
  void BuildParkedCars(double side) {
    for (double sp = rng_.Uniform(3, 15); sp < length_m_ - 30;) {
      const double len = rng_.Uniform(4.0, 5.2);
      if (IsUrban(sp) && rng_.Chance(0.55) && std::abs(route_.Kappa(sp)) < 0.012 && Fits(sp, sp + len, side, 5.3)) {
        b_.out = ChunkOf(sp);
        const double sc = sp + len / 2;
        const int style = rng_.Chance(0.15) ? 2 : rng_.Int(0, 1);
        const double heading = route_.Heading(sc) + rng_.Uniform(-0.03, 0.03);
        AddCar(b_, route_.Point(sc, side * 4.3, 0), heading, len, static_cast<float>(rng_.Uniform(0.25, 1.35)), style);
      }
      sp += len + rng_.Uniform(0.8, 3.5);
    }
  }

 private:
  struct Zone { double s0, s1; bool urban; };

  std::vector<Poly>* ChunkOf(double s) {
    const int n_chunks = static_cast<int>(chunks_.size());
    return &chunks_[std::clamp(static_cast<int>(s / chunk_m_), 0, n_chunks - 1)];
  }
  Eigen::Vector3d Tangent(double s) const {
    const double h = route_.Heading(s);
    return Eigen::Vector3d(std::cos(h), std::sin(h), 0);
  }
  Eigen::Vector3d Normal(double s) const {
    const double h = route_.Heading(s);
    return Eigen::Vector3d(-std::sin(h), std::cos(h), 0);
  }
  // Max lateral offset on side `side` over [sa, sb] before the tube folds
  // (route mode: the road's centre line is center_shift_m left of the track
  // the curvature is of).
  double FoldLimit(double sa, double sb, double side) const {
    double k = 0;
    for (double s = sa; s <= sb; s += 1.0) k = std::max(k, side * route_.Kappa(s));
    if (!track_) return k > 1e-6 ? 0.85 / k : 1e9;
    return k > 1e-6 ? 0.85 / k - side * route_.center_shift_m() : 1e9;
  }
  // The same, and in route mode no further than the clearance.
  double MaxOffset(double sa, double sb, double side) const {
    double lim = FoldLimit(sa, sb, side);
    if (!track_) return lim;
    const std::vector<double>& c = clearance_[side > 0 ? 1 : 0];
    for (double s = sa; s <= sb; s += 1.0)
      lim = std::min(lim, c[static_cast<size_t>(std::clamp(std::lround(s), 0L, static_cast<long>(c.size()) - 1))]);
    return lim;
  }
  // Route mode: whether something reaching `d` from the centre line fits on
  // side `side` over [sa, sb] (always in the generated world).
  bool Fits(double sa, double sb, double side, double d) const { return !track_ || d < MaxOffset(sa, sb, side); }
  bool IsUrban(double s) const {
    for (const auto& z : zones_)
      if (s >= z.s0 && s < z.s1) return z.urban;
    return true;
  }

  const Route& route_;
  const std::vector<MipTexture>& textures_;
  std::vector<std::vector<Poly>>& chunks_;
  const double chunk_m_, segment_m_;
  Rng& rng_;
  Builder b_;
  const double length_m_;
  const bool track_;
  std::vector<double> clearance_[2];  // route mode: [0]: right (side -1), [1]: left
  std::vector<Zone> zones_;
};

}  // namespace

double BuildStaticWorld(const Route& route, const std::vector<MipTexture>& textures,
                        std::vector<std::vector<Poly>>& chunks, double chunk_m, double segment_m, Rng& rng) {
  WorldBuilder world(route, textures, chunks, chunk_m, segment_m, rng);
  const double floor_z = world.BuildGround();
  world.BuildZones();
  for (double side : {-1.0, 1.0}) {
    world.BuildFrontage(side);
    world.BuildStreetFurniture(side);
    world.BuildParkedCars(side);
  }
  return floor_z;
}

}  // namespace locaid::synth::parts
