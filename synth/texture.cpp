#include "synth/texture.hpp"

#include "synth/random.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace locaid::synth {
namespace {

struct Img {
  int w = 0, h = 0;
  std::vector<float> px;
  Img(int w_, int h_, float v) : w(w_), h(h_), px(static_cast<size_t>(w_) * h_, v) {}
  float& at(int x, int y) { return px[static_cast<size_t>(y & (h - 1)) * w + (x & (w - 1))]; }
};

float SmoothF(float t) { return t * t * (3 - 2 * t); }

// Tileable value noise with cells of cx x cy texels (must divide w, h), amplitude amp.
void AddValueNoise(Img& img, int cx, int cy, float amp, Rng& rng) {
  const int gw = std::max(1, img.w / cx), gh = std::max(1, img.h / cy);
  std::vector<float> g(static_cast<size_t>(gw) * gh);
  for (auto& v : g) v = static_cast<float>(rng.Uniform(-1, 1));
  std::vector<int> x0(img.w), x1(img.w);
  std::vector<float> fx(img.w), row(gw);
  for (int x = 0; x < img.w; ++x) {
    const float gx = static_cast<float>(x) / cx;
    x0[x] = static_cast<int>(gx) % gw;
    x1[x] = (x0[x] + 1) % gw;
    fx[x] = SmoothF(gx - std::floor(gx));
  }
  for (int y = 0; y < img.h; ++y) {
    const float gy = static_cast<float>(y) / cy;
    const int y0 = static_cast<int>(gy) % gh, y1 = (y0 + 1) % gh;
    const float fy = SmoothF(gy - std::floor(gy));
    const float* r0 = &g[static_cast<size_t>(y0) * gw];
    const float* r1 = &g[static_cast<size_t>(y1) * gw];
    for (int i = 0; i < gw; ++i) row[i] = amp * (r0[i] + (r1[i] - r0[i]) * fy);
    float* out = &img.px[static_cast<size_t>(y) * img.w];
    if (cx == 1) {
      for (int x = 0; x < img.w; ++x) out[x] += row[x];
    } else {
      for (int x = 0; x < img.w; ++x) out[x] += row[x0[x]] + (row[x1[x]] - row[x0[x]]) * fx[x];
    }
  }
}

// Octaves from cell `big` down to 1 texel, amplitude * persistence^k.
void AddFractal(Img& img, int big, float amp, float persistence, Rng& rng, int smallest = 1) {
  for (int c = big; c >= smallest; c /= 2) {
    AddValueNoise(img, std::min(c, img.w), std::min(c, img.h), amp, rng);
    amp *= persistence;
  }
}

void FillRect(Img& img, int x0, int y0, int x1, int y1, float v, float alpha = 1) {
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      float& p = img.at(x, y);
      p += (v - p) * alpha;
    }
}
void AddRect(Img& img, int x0, int y0, int x1, int y1, float dv) {
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) img.at(x, y) += dv;
}

// Random-walk crack line.
void Crack(Img& img, Rng& rng, int length, float dark) {
  double x = rng.Uniform(0, img.w), y = rng.Uniform(0, img.h), a = rng.Uniform(0, 6.283);
  for (int i = 0; i < length; ++i) {
    a += rng.Uniform(-0.5, 0.5);
    x += std::cos(a);
    y += std::sin(a);
    img.at(static_cast<int>(x), static_cast<int>(y)) -= dark;
    if (rng.Chance(0.3)) img.at(static_cast<int>(x) + 1, static_cast<int>(y)) -= dark * 0.5f;
  }
}

void Blob(Img& img, double cx, double cy, double rx, double ry, float dv) {
  for (int y = static_cast<int>(cy - ry); y <= static_cast<int>(cy + ry); ++y)
    for (int x = static_cast<int>(cx - rx); x <= static_cast<int>(cx + rx); ++x) {
      const double dx = (x - cx) / rx, dy = (y - cy) / ry, r2 = dx * dx + dy * dy;
      if (r2 < 1) img.at(x, y) += dv * static_cast<float>(1 - r2 * r2);
    }
}

// Text-like strokes in a box (signs, shop names).
void Strokes(Img& img, Rng& rng, int x0, int y0, int x1, int y1, float v) {
  int x = x0;
  const int hh = y1 - y0;
  while (x < x1 - 2) {
    const int cw = std::max(2, static_cast<int>(hh * rng.Uniform(0.4, 0.8)));
    const int pattern = rng.Int(0, 5);
    const int t = std::max(1, hh / 6);
    if (pattern != 5) {
      if (pattern & 1) FillRect(img, x, y0, x + t, y1, v);
      if (pattern & 2) FillRect(img, x, y0, x + cw, y0 + t, v);
      if (pattern == 2 || pattern == 4) FillRect(img, x + cw - t, y0, x + cw, y1, v);
      if (pattern >= 3) FillRect(img, x, y1 - t, x + cw, y1, v);
      if (pattern == 0 || pattern == 4) FillRect(img, x, (y0 + y1) / 2, x + cw, (y0 + y1) / 2 + t, v);
    }
    x += cw + std::max(1, cw / 3);
  }
}

MipTexture Finish(const Img& img, double m_per_texel) {
  MipTexture t;
  t.m_per_texel = m_per_texel;
  t.log2_w = static_cast<int>(std::lround(std::log2(img.w)));
  t.log2_h = static_cast<int>(std::lround(std::log2(img.h)));
  std::vector<uint8_t> l0(img.px.size());
  for (size_t i = 0; i < l0.size(); ++i)
    l0[i] = static_cast<uint8_t>(std::clamp(std::lround(img.px[i]), 0L, 255L));
  t.levels.push_back(std::move(l0));
  int w = img.w, h = img.h;
  while (w > 1 && h > 1) {
    const int nw = w / 2, nh = h / 2;
    const auto& src = t.levels.back();
    std::vector<uint8_t> dst(static_cast<size_t>(nw) * nh);
    for (int y = 0; y < nh; ++y)
      for (int x = 0; x < nw; ++x) {
        const size_t a = static_cast<size_t>(2 * y) * w + 2 * x;
        dst[static_cast<size_t>(y) * nw + x] =
            static_cast<uint8_t>((src[a] + src[a + 1] + src[a + w] + src[a + w + 1] + 2) / 4);
      }
    t.levels.push_back(std::move(dst));
    w = nw; h = nh;
  }
  return t;
}

MipTexture MakeRoad(Rng& rng) {
  const int W = 512, H = 8192;  // 2 cm texels
  Img img(W, H, 100);
  AddFractal(img, 512, 9, 0.7f, rng);
  AddValueNoise(img, 1, 1, 9, rng);
  AddValueNoise(img, 2, 2, 6, rng);
  // wheel tracks: slightly darker/polished bands
  for (double d : {-2.55, -0.95, 0.95, 2.55}) {
    const int c = static_cast<int>((d + kRoadHalfWidth) / 0.02);
    for (int y = 0; y < H; ++y)
      for (int x = c - 14; x <= c + 14; ++x) img.at(x, y) -= 6.0f * (1.0f - std::abs(x - c) / 15.0f);
  }
  // parking strips: different surface
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double d = x * 0.02 - kRoadHalfWidth;
      if (std::abs(d) > 3.6) img.at(x, y) += 10;
    }
  // patches and cracks
  for (int i = 0; i < 70; ++i) {
    const int x0 = rng.Int(0, W), y0 = rng.Int(0, H), pw = rng.Int(20, 200), ph = rng.Int(20, 300);
    AddRect(img, x0, y0, x0 + pw, y0 + ph, static_cast<float>(rng.Uniform(-14, 10)));
  }
  for (int i = 0; i < 160; ++i) Crack(img, rng, rng.Int(30, 250), static_cast<float>(rng.Uniform(15, 40)));
  for (int i = 0; i < 12; ++i) {  // manholes
    const double cx = rng.Uniform(100, 412), cy = rng.Uniform(0, H);
    Blob(img, cx, cy, 30, 30, -25);
    Blob(img, cx, cy, 26, 26, 18);
  }
  // markings with wear
  Img wear(W, H, 0);
  AddFractal(wear, 64, 0.35f, 0.6f, rng);
  auto paint = [&](int x0, int x1, int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const float a = std::clamp(0.85f + wear.at(x, y), 0.0f, 1.0f);
        float& p = img.at(x, y);
        p += (215 - p) * a;
      }
  };
  const int le = static_cast<int>((-3.5 + kRoadHalfWidth) / 0.02), re = static_cast<int>((3.5 + kRoadHalfWidth) / 0.02);
  paint(le - 4, le + 4, 0, H);
  paint(re - 4, re + 4, 0, H);
  for (int y = 0; y < H; y += 256) paint(253, 259, y, y + 100);  // 2 m dash, 5.12 m period
  for (int v = 0; v < kRoadVariants; ++v) {  // a few stop lines / arrows per variant
    if (rng.Chance(0.5)) {
      const int y = v * 2048 + rng.Int(200, 1800);
      paint(re - 175, 256, y, y + 25);
    }
  }
  return Finish(img, 0.02);
}

MipTexture MakeSidewalk(Rng& rng) {
  const int N = 512;  // 1 cm, tiles 32 cm
  Img img(N, N, 150);
  AddFractal(img, 128, 10, 0.6f, rng);
  AddValueNoise(img, 1, 1, 8, rng);
  for (int ty = 0; ty < N / 32; ++ty)
    for (int tx = 0; tx < N / 32; ++tx) {
      const int off = (ty & 1) ? 16 : 0;
      AddRect(img, tx * 32 + off, ty * 32, tx * 32 + off + 32, ty * 32 + 32, static_cast<float>(rng.Uniform(-22, 22)));
      FillRect(img, tx * 32 + off, ty * 32, tx * 32 + off + 2, ty * 32 + 32, 85, 0.7f);
      FillRect(img, tx * 32 + off, ty * 32, tx * 32 + off + 32, ty * 32 + 2, 85, 0.7f);
    }
  for (int i = 0; i < 25; ++i) Blob(img, rng.Uniform(0, N), rng.Uniform(0, N), rng.Uniform(5, 40), rng.Uniform(5, 40), static_cast<float>(rng.Uniform(-35, 15)));
  for (int i = 0; i < 20; ++i) Crack(img, rng, rng.Int(10, 80), 30);
  return Finish(img, 0.01);
}

MipTexture MakeConcrete(Rng& rng, int w, int h, float base, int block) {
  Img img(w, h, base);
  AddFractal(img, std::min(w, h) / 2, 9, 0.65f, rng);
  AddValueNoise(img, 1, 1, 7, rng);
  for (int x = 0; x < w; x += block) FillRect(img, x, 0, x + 2, h, base * 0.55f, 0.8f);
  for (int i = 0; i < 10; ++i) Blob(img, rng.Uniform(0, w), rng.Uniform(0, h), rng.Uniform(4, 20), rng.Uniform(4, 20), -25);
  return Finish(img, 0.01);
}

MipTexture MakeGrass(Rng& rng) {
  const int N = 512;  // 2 cm
  Img img(N, N, 85);
  AddFractal(img, 256, 16, 0.7f, rng);
  AddValueNoise(img, 1, 1, 22, rng);
  AddValueNoise(img, 2, 2, 14, rng);
  for (int i = 0; i < 60; ++i) Blob(img, rng.Uniform(0, N), rng.Uniform(0, N), rng.Uniform(3, 30), rng.Uniform(3, 30), static_cast<float>(rng.Uniform(-30, 40)));
  return Finish(img, 0.02);
}

MipTexture MakeBrickWall(Rng& rng) {
  const int N = 512;  // 1.5 cm, bricks 16 x 5 texels
  Img img(N, N, 120);
  for (int by = 0; by < N / 5 + 1; ++by)
    for (int bx = 0; bx < N / 16 + 1; ++bx) {
      const int off = (by & 1) ? 8 : 0;
      FillRect(img, bx * 16 + off, by * 5, bx * 16 + off + 15, by * 5 + 4, static_cast<float>(rng.Uniform(95, 150)));
    }
  AddFractal(img, 256, 14, 0.6f, rng, 2);
  AddValueNoise(img, 1, 1, 8, rng);
  for (int i = 0; i < 15; ++i) Blob(img, rng.Uniform(0, N), rng.Uniform(0, N), rng.Uniform(10, 60), rng.Uniform(10, 80), -25);
  return Finish(img, 0.015);
}

MipTexture MakeCarBody(Rng& rng) {
  const int N = 256;  // 2 cm -> 5.12 m
  Img img(N, N, 170);
  AddFractal(img, 128, 6, 0.5f, rng);
  for (int i = 0; i < 6; ++i) {
    const int x = rng.Int(0, N);
    FillRect(img, x, 0, x + 1, N, 60, 0.8f);
  }
  FillRect(img, 0, 200, N, 203, 90, 0.8f);
  for (int i = 0; i < 6; ++i) {  // lights / handles / plates
    const int x = rng.Int(0, N), y = rng.Int(60, 180);
    FillRect(img, x, y, x + rng.Int(4, 25), y + rng.Int(3, 10), static_cast<float>(rng.Uniform(30, 250)));
  }
  return Finish(img, 0.02);
}

MipTexture MakeGlass(Rng& rng) {
  const int N = 256;
  Img img(N, N, 45);
  AddFractal(img, 128, 25, 0.55f, rng, 4);
  for (int i = 0; i < 5; ++i) {
    const int x = rng.Int(0, N);
    FillRect(img, x, 0, x + rng.Int(3, 8), N, 25, 0.9f);
  }
  return Finish(img, 0.02);
}

MipTexture MakeSimple(Rng& rng, int w, int h, float base, float fract_amp, float white, double m) {
  Img img(w, h, base);
  AddFractal(img, std::min(w, h) / 2, fract_amp, 0.6f, rng);
  AddValueNoise(img, 1, 1, white, rng);
  return Finish(img, m);
}

MipTexture MakeBark(Rng& rng) {
  Img img(128, 512, 70);
  AddValueNoise(img, 2, 32, 25, rng);
  AddValueNoise(img, 1, 8, 15, rng);
  AddValueNoise(img, 8, 64, 15, rng);
  return Finish(img, 0.01);
}

MipTexture MakeLeaves(Rng& rng) {
  const int N = 512;  // 1 cm
  Img img(N, N, 60);
  AddFractal(img, 128, 20, 0.6f, rng, 8);
  for (int i = 0; i < 5000; ++i)
    Blob(img, rng.Uniform(0, N), rng.Uniform(0, N), rng.Uniform(1.5, 5), rng.Uniform(1.5, 4), static_cast<float>(rng.Uniform(-40, 60)));
  return Finish(img, 0.01);
}

MipTexture MakeSign(Rng& rng) {
  const int N = 256;  // 0.5 cm -> 1.28 m
  Img img(N, N, 60);
  FillRect(img, 6, 6, N - 6, N - 6, 225);
  FillRect(img, 14, 14, N - 14, N - 14, 90);
  FillRect(img, 24, 24, N - 24, N - 24, 230);
  for (int r = 0; r < 5; ++r) Strokes(img, rng, 40, 40 + r * 36, N - 40, 40 + r * 36 + 22, 30);
  AddValueNoise(img, 1, 1, 6, rng);
  return Finish(img, 0.005);
}

MipTexture MakeFence(Rng& rng) {
  const int N = 256;  // 2 cm, slats
  Img img(N, N, 50);
  for (int x = 0; x < N; x += 8) FillRect(img, x, 0, x + 6, N, static_cast<float>(rng.Uniform(120, 170)));
  FillRect(img, 0, 40, N, 46, 140);
  FillRect(img, 0, 200, N, 206, 140);
  AddFractal(img, 128, 12, 0.6f, rng);
  return Finish(img, 0.02);
}

MipTexture MakeFacade(Rng& rng) {
  const int N = 1024;  // 2 cm: 20.48 m; row N-1 is just above the ground
  const float wall = static_cast<float>(rng.Uniform(105, 200));
  Img img(N, N, wall);
  AddFractal(img, 512, 12, 0.62f, rng);
  AddValueNoise(img, 1, 1, 6, rng);
  const int n_bays = rng.Int(6, 8), bay = N / n_bays;
  const int n_floors = rng.Int(6, 7), floor_h = N / n_floors;
  const int win_w = static_cast<int>(bay * rng.Uniform(0.38, 0.6));
  const int win_h = static_cast<int>(floor_h * rng.Uniform(0.45, 0.62));
  const float frame = static_cast<float>(std::clamp(wall + rng.Uniform(-70, 70), 30.0, 240.0));
  // plinth and floor cornices
  FillRect(img, 0, N - 30, N, N, wall * 0.6f, 0.8f);
  for (int f = 1; f < n_floors; ++f) FillRect(img, 0, N - f * floor_h - 6, N, N - f * floor_h, wall * 0.8f, 0.7f);
  for (int f = 0; f < n_floors; ++f) {
    const int top_floor = N - (f + 1) * floor_h;
    for (int b = 0; b < n_bays; ++b) {
      const int cx = b * bay + bay / 2;
      if (f == 0) {  // ground floor: shop windows, doors, signs
        const int kind = rng.Int(0, 2);
        const int x0 = b * bay + 10, x1 = (b + 1) * bay - 10;
        const int y0 = top_floor + 30, y1 = N - 30;
        if (kind == 0) {  // shop window + sign
          FillRect(img, x0, y0, x1, y1, frame);
          Img* p = &img;
          for (int y = y0 + 5; y < y1 - 5; ++y)
            for (int x = x0 + 5; x < x1 - 5; ++x)
              p->at(x, y) = static_cast<float>(35 + 30 * std::sin(x * 0.05 + y * 0.02)) + (x * 7 + y * 13) % 11;
          FillRect(img, x0, y0 - 26, x1, y0 - 4, static_cast<float>(rng.Uniform(20, 240)));
          Strokes(img, rng, x0 + 6, y0 - 22, x1 - 6, y0 - 8, static_cast<float>(rng.Uniform(0, 255)));
        } else if (kind == 1) {  // door
          const int dw = rng.Int(45, 70);
          FillRect(img, cx - dw / 2 - 5, y0 - 5, cx + dw / 2 + 5, N - 30, frame);
          FillRect(img, cx - dw / 2, y0, cx + dw / 2, N - 30, static_cast<float>(rng.Uniform(25, 110)));
          FillRect(img, cx + dw / 4, (y0 + N) / 2, cx + dw / 4 + 4, (y0 + N) / 2 + 4, 220);
        } else {  // window like upper floors
          const int w0 = cx - win_w / 2, h0 = top_floor + (floor_h - win_h) / 2;
          FillRect(img, w0 - 6, h0 - 6, w0 + win_w + 6, h0 + win_h + 6, frame);
          FillRect(img, w0, h0, w0 + win_w, h0 + win_h, static_cast<float>(rng.Uniform(25, 80)));
        }
        continue;
      }
      const int w0 = cx - win_w / 2, h0 = top_floor + (floor_h - win_h) / 2;
      FillRect(img, w0 - 6, h0 - 6, w0 + win_w + 6, h0 + win_h + 8, frame);   // frame
      FillRect(img, w0 - 10, h0 + win_h + 8, w0 + win_w + 10, h0 + win_h + 14, frame * 0.8f);  // sill
      const float glass = static_cast<float>(rng.Uniform(20, 75));
      for (int y = h0; y < h0 + win_h; ++y)
        for (int x = w0; x < w0 + win_w; ++x)
          img.at(x, y) = glass + 25.0f * static_cast<float>((x - w0) + 0.6 * (y - h0)) / (win_w + win_h);
      if (rng.Chance(0.5)) {  // curtain / blind
        const int ch = static_cast<int>(win_h * rng.Uniform(0.15, 0.9));
        const float cv = static_cast<float>(rng.Uniform(110, 230));
        for (int y = h0; y < h0 + ch; ++y)
          for (int x = w0; x < w0 + win_w; ++x) img.at(x, y) = cv - ((y - h0) % 6 == 0 ? 25.f : 0.f);
      }
      FillRect(img, cx - 2, h0, cx + 2, h0 + win_h, frame);  // mullion
      if (rng.Chance(0.3)) FillRect(img, w0, h0 + win_h / 3, w0 + win_w, h0 + win_h / 3 + 3, frame);
      if (rng.Chance(0.25)) {  // dirt streak below
        for (int y = h0 + win_h + 14; y < std::min(N, h0 + win_h + 14 + rng.Int(20, 90)); ++y)
          for (int x = w0; x < w0 + win_w; ++x) img.at(x, y) -= 12.0f * ((x * 31) % 7 > 2);
      }
    }
  }
  if (rng.Chance(0.6)) {  // drain pipe
    const int x = rng.Int(0, n_bays - 1) * bay;
    FillRect(img, x - 5, 0, x + 5, N, frame * 0.7f);
  }
  for (int i = 0; i < 8; ++i) Blob(img, rng.Uniform(0, N), rng.Uniform(0, N), rng.Uniform(20, 120), rng.Uniform(20, 120), static_cast<float>(rng.Uniform(-18, 10)));
  return Finish(img, 0.02);
}

}  // namespace

std::vector<MipTexture> MakeTextures(uint64_t seed, const std::function<void()>& between) {
  std::vector<MipTexture> t(kNumTextures);
  Rng rng(seed, 7);
  const auto made = [&](int id, MipTexture texture) {
    t[id] = std::move(texture);
    if (between) between();
  };
  // One statement each, in this order: the random stream, and so every
  // texture, is the same as ever.
  made(kTexRoad, MakeRoad(rng));
  made(kTexSidewalk, MakeSidewalk(rng));
  made(kTexCurb, MakeConcrete(rng, 256, 64, 160, 128));
  made(kTexGrass, MakeGrass(rng));
  made(kTexWall, MakeBrickWall(rng));
  made(kTexCarBody, MakeCarBody(rng));
  made(kTexGlass, MakeGlass(rng));
  made(kTexTire, MakeSimple(rng, 64, 64, 30, 8, 6, 0.01));
  made(kTexBark, MakeBark(rng));
  made(kTexLeaves, MakeLeaves(rng));
  made(kTexMetal, MakeSimple(rng, 64, 256, 140, 14, 5, 0.01));
  made(kTexSign, MakeSign(rng));
  made(kTexFence, MakeFence(rng));
  for (int i = 0; i < kNumFacades; ++i) made(kTexFacade0 + i, MakeFacade(rng));
  return t;
}

}  // namespace locaid::synth
