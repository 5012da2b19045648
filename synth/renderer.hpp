// Software renderer of the synthetic world: z-buffered scanline rasterizer of
// convex planar polygons with perspective-correct, mip-mapped, bilinearly
// (optionally anisotropically) filtered grayscale textures; then sky, haze,
// optics blur, vignetting, exposure gain and sensor noise. Single-threaded,
// no virtual calls per pixel.
#pragma once

#include "synth/texture.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace locaid::synth {

// Convex planar polygon (3 or 4 vertices) in world (ENU) coordinates. The
// texture map is affine, defined by vertices 0, 1, 2 (texture coordinates in
// level-0 texels); quads must be parallelograms in texture space.
struct Poly {
  std::array<Eigen::Vector3d, 4> p;
  std::array<float, 4> u{}, v{};
  int n = 4;
  int tex = 0;
  float shade = 1;           // albedo multiplier (lighting, object colour)
  bool two_sided = false;    // else culled when seen from behind (normal by winding)
  bool background = false;   // drawn after everything else (fills holes only)
};

struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
};

// Per-image photometric settings.
struct Photometry {
  double gain = 1.0;          // global exposure gain
  double offset_dn = 0.0;     // black level offset
  double noise_sigma_dn = 1.2;
  uint64_t noise_seed = 0;    // per image
};

class Renderer {
 public:
  Renderer(const Intrinsics& K, const std::vector<MipTexture>* textures);

  // Renders `polys` (any order; they are sorted front to back) as seen by a
  // camera (x right, y down, z forward) with pose T_world_cam, into an 8-bit image.
  void Render(const std::vector<const Poly*>& polys, const Eigen::Isometry3d& T_world_cam,
              const Photometry& photometry, cv::Mat& image_u8);

  // Inverse depth (1/z, 0 = sky) of the last rendered image, row-major.
  const std::vector<float>& inverse_depth() const { return inv_z_; }

  double near_m = 0.3;
  // Texture filtering. false: one mip level per 32-pixel span, chosen by the
  // longest axis of the pixel's texture footprint (fast; ground seen at a
  // grazing angle is blurred sideways as much as in depth). true: the level
  // follows the shortest axis and several samples average the longest one, as
  // a real lens sees the road (about 2x the rendering time).
  bool anisotropic = false;
  double fog_start_m = 45, fog_end_m = 185;  // haze: none before start, full at end
  float haze_dn = 175, sky_zenith_dn = 140;

 private:
  void DrawPoly(const Poly& poly, const Eigen::Matrix3d& R_cw, const Eigen::Vector3d& t_cw);
  void PostProcess(const Eigen::Matrix3d& R_cw, const Photometry& ph, cv::Mat& out);
  void AnisotropicSpan(const MipTexture& tex, const double* Uc, const double* Vc, const double* Wc, double foot_x2,
                       double foot_y2, int c0, int c1, int y, float kshade, float* zrow, float* crow) const;

  Intrinsics K_;
  const std::vector<MipTexture>* tex_;
  std::vector<float> color_, inv_z_, tmp_;
  std::vector<float> vignette_;
  std::vector<float> fog_lut_;
  double fog_lut_max_inv_z_ = 0;
  std::vector<int8_t> noise_table_;
  std::vector<float> row_xl_, row_xr_;
  struct Item { float key; const Poly* poly; };
  std::vector<Item> sorted_;
};

}  // namespace locaid::synth
