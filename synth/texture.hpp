// Procedural grayscale textures with precomputed mip maps for the synthetic
// renderer. Sizes are powers of two; coordinates wrap.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

namespace locaid::synth {

struct MipTexture {
  int log2_w = 0, log2_h = 0;              // level 0 size
  double m_per_texel = 0.02;               // world size of one level-0 texel
  std::vector<std::vector<uint8_t>> levels;  // level l: (w >> l) x (h >> l), row-major
  int width(int level = 0) const { return (1 << log2_w) >> level; }
  int height(int level = 0) const { return (1 << log2_h) >> level; }
};

// Texture ids of the synthetic world.
enum TextureId : int {
  kTexRoad = 0,   // 512 x 8192, 2 cm: 10.24 m across, 4 variants of 40.96 m along
  kTexSidewalk,
  kTexCurb,
  kTexGrass,
  kTexWall,       // building side walls
  kTexCarBody,
  kTexGlass,
  kTexTire,
  kTexBark,
  kTexLeaves,
  kTexMetal,
  kTexSign,
  kTexFence,
  kTexFacade0,    // kNumFacades facade variants follow
};
constexpr int kNumFacades = 8;
constexpr int kNumTextures = kTexFacade0 + kNumFacades;

// Road texture layout (m): lateral extent [-kRoadHalfWidth, +kRoadHalfWidth],
// one variant block every kRoadBlockLength along the route.
constexpr double kRoadHalfWidth = 5.12;
constexpr double kRoadBlockLength = 40.96;
constexpr int kRoadVariants = 4;

// All textures of the world, generated deterministically from `seed`.
// `between` (if set) runs after each texture: a caller cancels by throwing.
std::vector<MipTexture> MakeTextures(uint64_t seed, const std::function<void()>& between = {});

}  // namespace locaid::synth
