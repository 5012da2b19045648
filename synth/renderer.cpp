#include "synth/renderer.hpp"

#include "synth/random.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locaid::synth {

Renderer::Renderer(const Intrinsics& K, const std::vector<MipTexture>* textures)
    : K_(K), tex_(textures) {
  if (K.width <= 0 || K.height <= 0) throw std::invalid_argument("synth renderer: bad image size");
  const size_t n = static_cast<size_t>(K.width) * K.height;
  color_.resize(n);
  inv_z_.resize(n);
  tmp_.resize(n);
  vignette_.resize(n);
  const double rmax2 = (K.width * 0.5) * (K.width * 0.5) + (K.height * 0.5) * (K.height * 0.5);
  for (int y = 0; y < K.height; ++y)
    for (int x = 0; x < K.width; ++x) {
      const double dx = x - K.cx, dy = y - K.cy;
      vignette_[static_cast<size_t>(y) * K.width + x] = static_cast<float>(1.0 - 0.22 * (dx * dx + dy * dy) / rmax2);
    }
  row_xl_.resize(K.height);
  row_xr_.resize(K.height);
  Rng rng(12345, 3);
  noise_table_.resize(1 << 16);
  for (auto& v : noise_table_) v = static_cast<int8_t>(std::clamp(std::lround(10.0 * rng.Normal()), -127L, 127L));
}

namespace {
constexpr int kMaxVerts = 8;
struct V3 { double x, y, z; };

// One mip level as the span loops sample it.
struct MipLevel {
  const uint8_t* texels;
  int lw, mask_x, mask_y;  // log2 of the row length; wrap masks
};

MipLevel LevelOf(const MipTexture& tex, int level) {
  const int lw = tex.log2_w - level, lh = tex.log2_h - level;
  return {tex.levels[level].data(), lw, (1 << std::max(lw, 0)) - 1, (1 << std::max(lh, 0)) - 1};
}

// Bilinear texel lookup, wrapping. (iu, iv): texel position x 256, already
// shifted by -128 (texel centres) and +2^28 (kept positive); returns grey x 65536.
inline int Bilinear(const MipLevel& m, int iu, int iv) {
  const int tx0 = (iu >> 8) & m.mask_x, ty0 = (iv >> 8) & m.mask_y;
  const int tx1 = (tx0 + 1) & m.mask_x, ty1 = (ty0 + 1) & m.mask_y;
  const int fx = iu & 255, fy = iv & 255;
  const uint8_t* r0 = m.texels + (static_cast<size_t>(ty0) << m.lw);
  const uint8_t* r1 = m.texels + (static_cast<size_t>(ty1) << m.lw);
  const int top = r0[tx0] * 256 + (r0[tx1] - r0[tx0]) * fx;
  const int bot = r1[tx0] * 256 + (r1[tx1] - r1[tx0]) * fx;
  return top * 256 + (bot - top) * fy;
}
}  // namespace

void Renderer::Render(const std::vector<const Poly*>& polys, const Eigen::Isometry3d& T_world_cam,
                      const Photometry& photometry, cv::Mat& image_u8) {
  const Eigen::Isometry3d T_cw = T_world_cam.inverse();
  const Eigen::Matrix3d R_cw = T_cw.linear();
  const Eigen::Vector3d t_cw = T_cw.translation();
  std::fill(inv_z_.begin(), inv_z_.end(), 0.0f);
  // Front-to-back order so the depth test rejects hidden pixels before texturing.
  sorted_.clear();
  const Eigen::RowVector3d r2 = R_cw.row(2);
  for (const Poly* p : polys) {
    Eigen::Vector3d c = p->p[0] + p->p[1] + p->p[2];
    if (p->n == 4) c += p->p[3];
    const double z = r2.dot(c / p->n) + t_cw.z();
    sorted_.push_back({p->background ? 1e30f : static_cast<float>(z), p});
  }
  std::stable_sort(sorted_.begin(), sorted_.end(), [](const Item& a, const Item& b) { return a.key < b.key; });
  for (const Item& it : sorted_) DrawPoly(*it.poly, R_cw, t_cw);
  PostProcess(R_cw, photometry, image_u8);
}

void Renderer::DrawPoly(const Poly& poly, const Eigen::Matrix3d& R_cw, const Eigen::Vector3d& t_cw) {
  const int W = K_.width, H = K_.height;
  Eigen::Vector3d P[4];
  bool any_front = false;
  for (int i = 0; i < poly.n; ++i) {
    P[i] = R_cw * poly.p[i] + t_cw;
    any_front |= P[i].z() > near_m;
  }
  if (!any_front) return;
  // Frustum side planes (quick reject when all vertices are outside one plane).
  {
    const double xl = -K_.cx / K_.fx, xr = (W - K_.cx) / K_.fx, yt = -K_.cy / K_.fy, yb = (H - K_.cy) / K_.fy;
    int out_l = 0, out_r = 0, out_t = 0, out_b = 0;
    for (int i = 0; i < poly.n; ++i) {
      out_l += P[i].x() < xl * P[i].z();
      out_r += P[i].x() > xr * P[i].z();
      out_t += P[i].y() < yt * P[i].z();
      out_b += P[i].y() > yb * P[i].z();
    }
    if (out_l == poly.n || out_r == poly.n || out_t == poly.n || out_b == poly.n) return;
  }
  const Eigen::Vector3d e1 = P[1] - P[0], e2 = P[2] - P[0];
  const Eigen::Vector3d n = e1.cross(e2);
  const double d = n.dot(P[0]);
  if (!poly.two_sided && d >= 0) return;  // back face
  if (std::abs(d) < 1e-9 * n.norm() * (P[0].norm() + 1e-9)) return;  // edge-on
  // Affine texture map u(P) = u0 + alpha_u . (P - P0) on the polygon plane.
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  if (det <= 1e-18) return;
  const double i11 = g22 / det, i12 = -g12 / det, i22 = g11 / det;
  const double du1 = poly.u[1] - poly.u[0], du2 = poly.u[2] - poly.u[0];
  const double dv1 = poly.v[1] - poly.v[0], dv2 = poly.v[2] - poly.v[0];
  const Eigen::Vector3d alpha_u = e1 * (du1 * i11 + du2 * i12) + e2 * (du1 * i12 + du2 * i22);
  const Eigen::Vector3d alpha_v = e1 * (dv1 * i11 + dv2 * i12) + e2 * (dv1 * i12 + dv2 * i22);
  const Eigen::Vector3d Wv = n / d;  // 1/z = Wv . r, r = P / z
  const Eigen::Vector3d Uv = alpha_u + (poly.u[0] - alpha_u.dot(P[0])) * Wv;
  const Eigen::Vector3d Vv = alpha_v + (poly.v[0] - alpha_v.dot(P[0])) * Wv;
  auto screen = [&](const Eigen::Vector3d& C, double out[3]) {
    out[0] = C.x() / K_.fx;
    out[1] = C.y() / K_.fy;
    out[2] = C.z() - C.x() * K_.cx / K_.fx - C.y() * K_.cy / K_.fy;
  };
  double Wc[3], Uc[3], Vc[3];
  screen(Wv, Wc);
  screen(Uv, Uc);
  screen(Vv, Vc);

  // Clip against the near plane, project.
  V3 in[kMaxVerts], outv[kMaxVerts];
  int nin = poly.n, nout = 0;
  for (int i = 0; i < nin; ++i) in[i] = {P[i].x(), P[i].y(), P[i].z()};
  for (int i = 0; i < nin; ++i) {
    const V3& a = in[i];
    const V3& b = in[(i + 1) % nin];
    const bool ain = a.z >= near_m, bin = b.z >= near_m;
    if (ain) outv[nout++] = a;
    if (ain != bin) {
      const double t = (near_m - a.z) / (b.z - a.z);
      outv[nout++] = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), near_m};
    }
  }
  if (nout < 3) return;
  double sx[kMaxVerts], sy[kMaxVerts];
  double ymin = 1e30, ymax = -1e30;
  for (int i = 0; i < nout; ++i) {
    sx[i] = K_.cx + K_.fx * outv[i].x / outv[i].z;
    sy[i] = K_.cy + K_.fy * outv[i].y / outv[i].z;
    ymin = std::min(ymin, sy[i]);
    ymax = std::max(ymax, sy[i]);
  }
  const int y0 = std::max(0, static_cast<int>(std::ceil(ymin)));
  const int y1 = std::min(H - 1, static_cast<int>(std::ceil(ymax)) - 1);
  if (y0 > y1) return;
  for (int y = y0; y <= y1; ++y) {
    row_xl_[y] = 1e30f;
    row_xr_[y] = -1e30f;
  }
  for (int i = 0; i < nout; ++i) {
    const int j = (i + 1) % nout;
    double ax = sx[i], ay = sy[i], bx = sx[j], by = sy[j];
    if (ay == by) continue;
    if (ay > by) { std::swap(ax, bx); std::swap(ay, by); }
    const int ya = std::max(y0, static_cast<int>(std::ceil(ay)));
    const int yb = std::min(y1, static_cast<int>(std::ceil(by)) - 1);
    const double slope = (bx - ax) / (by - ay);
    for (int y = ya; y <= yb; ++y) {
      const float x = static_cast<float>(ax + (y - ay) * slope);
      row_xl_[y] = std::min(row_xl_[y], x);
      row_xr_[y] = std::max(row_xr_[y], x);
    }
  }

  const MipTexture& tex = (*tex_)[poly.tex];
  const int max_level = static_cast<int>(tex.levels.size()) - 1;
  const float kshade = poly.shade / 65536.0f;
  constexpr int kChunk = 32;
  for (int y = y0; y <= y1; ++y) {
    if (row_xl_[y] > row_xr_[y]) continue;
    const int xs = std::max(0, static_cast<int>(std::ceil(row_xl_[y])));
    const int xe = std::min(W, static_cast<int>(std::ceil(row_xr_[y])));
    float* zrow = &inv_z_[static_cast<size_t>(y) * W];
    float* crow = &color_[static_cast<size_t>(y) * W];
    for (int c0 = xs; c0 < xe; c0 += kChunk) {
      const int c1 = std::min(xe, c0 + kChunk);
      // Mip level from the texture footprint at the chunk centre.
      const double xm = 0.5 * (c0 + c1 - 1);
      const double wm = Wc[0] * xm + Wc[1] * y + Wc[2];
      if (wm <= 0) continue;
      const double zm = 1.0 / wm;
      const double um = (Uc[0] * xm + Uc[1] * y + Uc[2]) * zm, vm = (Vc[0] * xm + Vc[1] * y + Vc[2]) * zm;
      const double dudx = zm * (Uc[0] - um * Wc[0]), dudy = zm * (Uc[1] - um * Wc[1]);
      const double dvdx = zm * (Vc[0] - vm * Wc[0]), dvdy = zm * (Vc[1] - vm * Wc[1]);
      const double foot_x2 = dudx * dudx + dvdx * dvdx, foot_y2 = dudy * dudy + dvdy * dvdy;
      if (anisotropic) {
        AnisotropicSpan(tex, Uc, Vc, Wc, foot_x2, foot_y2, c0, c1, y, kshade, zrow, crow);
        continue;
      }
      const double rho2 = std::max(foot_x2, foot_y2);
      // round(log2(rho)) = floor(log2(2 rho^2) / 2)
      int level = rho2 > 1 ? std::ilogb(2 * rho2) / 2 : 0;
      level = std::min(level, max_level);
      const MipLevel mip = LevelOf(tex, level);
      const float scale = 256.0f / static_cast<float>(1 << level);
      float w = static_cast<float>(Wc[0] * c0 + Wc[1] * y + Wc[2]);
      float uz = static_cast<float>((Uc[0] * c0 + Uc[1] * y + Uc[2]) * scale);
      float vz = static_cast<float>((Vc[0] * c0 + Vc[1] * y + Vc[2]) * scale);
      const float dw = static_cast<float>(Wc[0]), duz = static_cast<float>(Uc[0] * scale),
                  dvz = static_cast<float>(Vc[0] * scale);
      for (int x = c0; x < c1; ++x, w += dw, uz += duz, vz += dvz) {
        if (!(w > zrow[x])) continue;
        const float z = 1.0f / w;
        const int iu = static_cast<int>(uz * z) - 128 + (1 << 28);
        const int iv = static_cast<int>(vz * z) - 128 + (1 << 28);
        crow[x] = static_cast<float>(Bilinear(mip, iu, iv)) * kshade;
        zrow[x] = w;
      }
    }
  }
}

// Anisotropic variant of the span loop. The footprint of a pixel in the
// texture is long along one screen axis (for the road ahead: the rows, which
// cover metres of depth) and short along the other. The isotropic loop picks
// the mip level of the long axis and so blurs the road sideways as much as in
// depth; here the level follows the short axis, and n bilinear samples spread
// along the long axis (n = the axis ratio, at most kMaxAnisotropy) average it.
void Renderer::AnisotropicSpan(const MipTexture& tex, const double* Uc, const double* Vc, const double* Wc,
                               double foot_x2, double foot_y2, int c0, int c1, int y, float kshade, float* zrow,
                               float* crow) const {
  constexpr int kMaxAnisotropy = 16;
  const int max_level = static_cast<int>(tex.levels.size()) - 1;
  const bool long_y = foot_y2 >= foot_x2;
  const double long_axis = std::sqrt(std::max(foot_x2, foot_y2));
  const double short_axis = std::sqrt(std::max(1e-12, std::min(foot_x2, foot_y2)));
  const int n = std::clamp(static_cast<int>(std::ceil(long_axis / short_axis)), 1, kMaxAnisotropy);
  const double per_sample = long_axis / n;
  const int level = per_sample > 1 ? std::min(static_cast<int>(std::lround(std::log2(per_sample))), max_level) : 0;
  const MipLevel mip = LevelOf(tex, level);
  const double scale = 256.0 / static_cast<double>(1 << level);
  for (int x = c0; x < c1; ++x) {
    const double w_center = Wc[0] * x + Wc[1] * y + Wc[2];
    if (!(static_cast<float>(w_center) > zrow[x])) continue;
    int64_t acc = 0;
    for (int k = 0; k < n; ++k) {
      const double d = (k + 0.5) / n - 0.5;  // sample offset along the long axis, pixels
      double xs = long_y ? x : x + d, ys = long_y ? y + d : y;
      double w_sample = Wc[0] * xs + Wc[1] * ys + Wc[2];
      if (!(w_sample > 0)) {  // beyond the plane's horizon (sub-pixel next to it): use the centre
        xs = x;
        ys = y;
        w_sample = w_center;
      }
      const double inv_w = 1.0 / w_sample;
      const int iu = static_cast<int>((Uc[0] * xs + Uc[1] * ys + Uc[2]) * inv_w * scale) - 128 + (1 << 28);
      const int iv = static_cast<int>((Vc[0] * xs + Vc[1] * ys + Vc[2]) * inv_w * scale) - 128 + (1 << 28);
      acc += Bilinear(mip, iu, iv);
    }
    crow[x] = static_cast<float>(static_cast<double>(acc) / n) * kshade;
    zrow[x] = static_cast<float>(w_center);
  }
}

void Renderer::PostProcess(const Eigen::Matrix3d& R_cw, const Photometry& ph, cv::Mat& out) {
  const int W = K_.width, H = K_.height;
  // Haze LUT over inverse depth.
  if (fog_lut_.empty()) {
    fog_lut_.resize(2048);
    fog_lut_max_inv_z_ = 1.0 / fog_start_m;
    for (size_t i = 0; i < fog_lut_.size(); ++i) {
      const double iz = (i + 0.5) / fog_lut_.size() * fog_lut_max_inv_z_;
      const double z = 1.0 / iz;
      double t = std::clamp((z - fog_start_m) / (fog_end_m - fog_start_m), 0.0, 1.0);
      t = t * t * (3 - 2 * t);
      fog_lut_[i] = static_cast<float>(t);
    }
  }
  const Eigen::Vector3d up_c = R_cw * Eigen::Vector3d::UnitZ();
  const float lut_scale = static_cast<float>(fog_lut_.size() / fog_lut_max_inv_z_);
  const int lut_n = static_cast<int>(fog_lut_.size());
  const float ifx = static_cast<float>(1.0 / K_.fx), cxf = static_cast<float>(K_.cx);
  const float ux = static_cast<float>(up_c.x()), uy = static_cast<float>(up_c.y()), uz = static_cast<float>(up_c.z());
  const float haze = haze_dn, zenith = sky_zenith_dn;
  for (int y = 0; y < H; ++y) {
    const float ry = static_cast<float>((y - K_.cy) / K_.fy);
    const float ry2 = ry * ry + 1.0f, sy = uy * ry + uz;
    float* c = &color_[static_cast<size_t>(y) * W];
    const float* iz = &inv_z_[static_cast<size_t>(y) * W];
    for (int x = 0; x < W; ++x) {
      if (iz[x] == 0.0f) {
        const float rx = (static_cast<float>(x) - cxf) * ifx;
        const float t = std::clamp((ux * rx + sy) / std::sqrt(rx * rx + ry2) * 2.5f, 0.0f, 1.0f);
        c[x] = haze + (zenith - haze) * t;
      } else {
        const int k = static_cast<int>(iz[x] * lut_scale);
        if (k < lut_n) c[x] += (haze - c[x]) * fog_lut_[k];
      }
    }
  }
  // Optics blur [1 2 1]/4 separable.
  for (int y = 0; y < H; ++y) {
    const float* s = &color_[static_cast<size_t>(y) * W];
    float* t = &tmp_[static_cast<size_t>(y) * W];
    t[0] = 0.75f * s[0] + 0.25f * s[1];
    for (int x = 1; x < W - 1; ++x) t[x] = 0.25f * (s[x - 1] + s[x + 1]) + 0.5f * s[x];
    t[W - 1] = 0.75f * s[W - 1] + 0.25f * s[W - 2];
  }
  out.create(H, W, CV_8UC1);
  Rng rng(ph.noise_seed, 11);
  const float gain = static_cast<float>(ph.gain), offset = static_cast<float>(ph.offset_dn) + 0.5f;
  const float nscale = static_cast<float>(ph.noise_sigma_dn / 10.0);
  for (int y = 0; y < H; ++y) {
    const float* a = &tmp_[static_cast<size_t>(std::max(0, y - 1)) * W];
    const float* b = &tmp_[static_cast<size_t>(y) * W];
    const float* c = &tmp_[static_cast<size_t>(std::min(H - 1, y + 1)) * W];
    const float* vig = &vignette_[static_cast<size_t>(y) * W];
    uint8_t* o = out.ptr<uint8_t>(y);
    const uint32_t base = static_cast<uint32_t>(rng.Next() & 0xFFFF);
    for (int x = 0; x < W; ++x) {
      const float v = (0.25f * (a[x] + c[x]) + 0.5f * b[x]) * gain * vig[x] + offset +
                      nscale * noise_table_[(base + static_cast<uint32_t>(x) * 7u) & 0xFFFF];
      o[x] = static_cast<uint8_t>(std::clamp(v, 0.0f, 255.0f));
    }
  }
}

}  // namespace locaid::synth
