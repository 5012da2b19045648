#include "synth/world.hpp"

#include "synth/random.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <unordered_map>

namespace locaid::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kCurbH = 0.12, kSidewalkW = 3.0;

const Eigen::Vector3d kSun = Eigen::Vector3d(0.35, -0.3, 0.88).normalized();
const Eigen::Vector3d kUp = Eigen::Vector3d::UnitZ();

float Light(const Eigen::Vector3d& n) {
  return static_cast<float>(0.6 + 0.4 * std::max(0.0, n.normalized().dot(kSun)));
}


// Polygon builder: orients the winding so the normal points along `outward`.
struct Builder {
  const std::vector<MipTexture>& tex;
  std::vector<Poly>* out = nullptr;

  void Tri(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
           double ua, double va, double ub, double vb, double uc, double vc, int t, float shade,
           const Eigen::Vector3d& outward) {
    Poly p;
    p.n = 3;
    p.tex = t;
    p.p = {a, b, c, c};
    // keep texture coordinates small: shift by whole texture periods
    const int W = tex[t].width(), H = tex[t].height();
    const double su = std::floor(std::min({ua, ub, uc}) / W) * W, sv = std::floor(std::min({va, vb, vc}) / H) * H;
    p.u = {float(ua - su), float(ub - su), float(uc - su), 0};
    p.v = {float(va - sv), float(vb - sv), float(vc - sv), 0};
    Add(p, (b - a).cross(c - a), outward, shade);
  }

  // Rectangle o, o+eu, o+eu+ev, o+ev; texture (u0, v0) at o, u grows along eu,
  // v grows along ev (both in metres, scaled by the texture's m_per_texel).
  void Rect(const Eigen::Vector3d& o, const Eigen::Vector3d& eu, const Eigen::Vector3d& ev,
            double u0_m, double v0_m, double v_sign, int t, float shade, const Eigen::Vector3d& outward,
            bool two_sided = false) {
    const double m = tex[t].m_per_texel;
    const int W = tex[t].width(), H = tex[t].height();
    const double u0 = u0_m / m, v0 = v0_m / m, du = eu.norm() / m, dv = v_sign * ev.norm() / m;
    const double su = std::floor(std::min(u0, u0 + du) / W) * W, sv = std::floor(std::min(v0, v0 + dv) / H) * H;
    Poly p;
    p.n = 4;
    p.tex = t;
    p.two_sided = two_sided;
    p.p = {o, o + eu, o + eu + ev, o + ev};
    p.u = {float(u0 - su), float(u0 + du - su), float(u0 + du - su), float(u0 - su)};
    p.v = {float(v0 - sv), float(v0 - sv), float(v0 + dv - sv), float(v0 + dv - sv)};
    Add(p, eu.cross(ev), outward, shade);
  }

  // Adds p (normal n) facing `outward`: when n points away, the vertex order
  // after the first is reversed (swapping vertex 1 and the last one).
  void Add(Poly p, Eigen::Vector3d n, const Eigen::Vector3d& outward, float shade) {
    if (n.dot(outward) < 0) {
      const int last = p.n - 1;
      std::swap(p.p[1], p.p[last]);
      std::swap(p.u[1], p.u[last]);
      std::swap(p.v[1], p.v[last]);
      n = -n;
    }
    p.shade = shade * Light(n);
    out->push_back(p);
  }

  // Axis-aligned box in a local frame (origin o on the ground, forward f,
  // left l, up z): x in [x0,x1], y in [y0,y1], z in [z0,z1]. 4 sides + top.
  void Box(const Eigen::Vector3d& o, const Eigen::Vector3d& f, const Eigen::Vector3d& l, double x0,
           double x1, double y0, double y1, double z0, double z1, int t, float shade, double u_off = 0) {
    const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
    auto P = [&](double x, double y, double h) { return Eigen::Vector3d(o + f * x + l * y + z * h); };
    const Eigen::Vector3d H = z * (z1 - z0);
    // v: from the top down (texture rows grow downwards)
    Rect(P(x0, y0, z1), f * (x1 - x0), -H, u_off, 0, 1, t, shade, -l);
    Rect(P(x1, y1, z1), -f * (x1 - x0), -H, u_off, 0, 1, t, shade, l);
    Rect(P(x1, y0, z1), l * (y1 - y0), -H, u_off + 1.3, 0, 1, t, shade, f);
    Rect(P(x0, y1, z1), -l * (y1 - y0), -H, u_off + 2.1, 0, 1, t, shade, -f);
    Rect(P(x0, y0, z1), f * (x1 - x0), l * (y1 - y0), u_off, 0, 1, t, shade, z);
  }
};

// Route mode: the road's centre line every `step` metres, hashed by place.
class CenterSamples {
 public:
  CenterSamples(const Route& route, double step) : step_(step) {
    const int n = static_cast<int>(route.length_m() / step) + 1;
    for (int i = 0; i < n; ++i) {
      const double s = i * step, h = route.Heading(s);
      p_.push_back(route.Center(s));
      t_.emplace_back(std::cos(h), std::sin(h));
      grid_[Key(Cell(p_.back().x()), Cell(p_.back().y()))].push_back(i);
    }
  }
  int size() const { return static_cast<int>(p_.size()); }
  double s(int i) const { return i * step_; }
  const Eigen::Vector2d& p(int i) const { return p_[static_cast<size_t>(i)]; }
  const Eigen::Vector2d& t(int i) const { return t_[static_cast<size_t>(i)]; }
  // f(j) for every sample j within r of q.
  template <class F>
  void Near(const Eigen::Vector2d& q, double r, F f) const {
    for (int64_t cx = Cell(q.x() - r); cx <= Cell(q.x() + r); ++cx)
      for (int64_t cy = Cell(q.y() - r); cy <= Cell(q.y() + r); ++cy) {
        const auto it = grid_.find(Key(cx, cy));
        if (it == grid_.end()) continue;
        for (int j : it->second)
          if ((p_[static_cast<size_t>(j)] - q).squaredNorm() <= r * r) f(j);
      }
  }

 private:
  static constexpr double kCellM = 16;
  static int64_t Cell(double x) { return static_cast<int64_t>(std::floor(x / kCellM)); }
  static int64_t Key(int64_t cx, int64_t cy) { return cx * 2000003 + cy; }
  double step_;
  std::vector<Eigen::Vector2d> p_, t_;
  std::unordered_map<int64_t, std::vector<int>> grid_;
};

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

  bool track() const { return track_; }

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

World::World(const Route& route, const std::vector<MipTexture>& textures, uint64_t seed,
             double duration_s, const WorldConfig& config)
    : route_(route), tex_(textures), cfg_(config) {
  chunk_m_ = cfg_.segment_m * 8;
  const double L = route.length_m();
  chunks_.resize(static_cast<int>(std::ceil(L / chunk_m_)) + 1);
  Rng rng(seed, 5);
  WorldBuilder world(route, textures, chunks_, chunk_m_, cfg_.segment_m, rng);
  ground_floor_z_ = world.BuildGround();
  world.BuildZones();
  for (double side : {-1.0, 1.0}) {
    world.BuildFrontage(side);
    world.BuildStreetFurniture(side);
    world.BuildParkedCars(side);
  }
  // Oncoming traffic on the left lane.
  const double span = L + 15.0 * duration_s;
  for (double s0 = rng.Uniform(60, 150); s0 < span; s0 += rng.Uniform(0.4, 1.6) * cfg_.oncoming_spacing_m) {
    movers_.push_back({s0, rng.Uniform(7, 14), rng.Uniform(4.0, 5.0), rng.Uniform(0.25, 1.35),
                       rng.Chance(0.15) ? 2 : rng.Int(0, 1)});
  }
  if (world.track()) FindConflicts();
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
