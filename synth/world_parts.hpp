// The pieces the synthetic world is made of, shared by World (synth/world.cpp:
// what is drawn per frame) and the builder of its static part
// (synth/world_parts.cpp): the polygon builder, the road's centre line
// hashed by place, a car, and BuildStaticWorld.
#pragma once

#include "synth/motion.hpp"
#include "synth/random.hpp"
#include "synth/renderer.hpp"
#include "synth/texture.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace locaid::synth::parts {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kCurbH = 0.12, kSidewalkW = 3.0;

inline const Eigen::Vector3d kSun = Eigen::Vector3d(0.35, -0.3, 0.88).normalized();
inline const Eigen::Vector3d kUp = Eigen::Vector3d::UnitZ();

inline float Light(const Eigen::Vector3d& n) {
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

// A parked or oncoming car at `o` facing `heading` (style 2: a van).
void AddCar(Builder& b, const Eigen::Vector3d& o, double heading, double length, float shade, int style);

// The static world along `route` into `chunks` (each `chunk_m` of route):
// ground, zones, frontage, street furniture and parked cars, drawing from
// `rng` in that order. Returns the lowest ground height (the floor under
// everything).
double BuildStaticWorld(const Route& route, const std::vector<MipTexture>& textures,
                        std::vector<std::vector<Poly>>& chunks, double chunk_m, double segment_m, Rng& rng);

}  // namespace locaid::synth::parts
