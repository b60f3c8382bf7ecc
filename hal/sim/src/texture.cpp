// Procedural material tiles. Each recipe layers tileable multi-octave value noise (the surface
// mottling) with drawn detail at several scales (speckles, stains, scratches, cracks, grain,
// printed labels) so that FAST/ORB corners exist at every viewing distance the mip chain covers.
// Everything wraps at the tile border, so the world-space planar projection has no seams.

#include "texture.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

#include "hwr/sim/random.hpp"

namespace hwr::sim::detail {
namespace {

constexpr int kLog2Size = 10;
constexpr int kSize = 1 << kLog2Size;
constexpr int kMinLevelLog2 = 2;  // smallest mip level is 4x4

// Uniform integer in [lo, hi].
int uniform_int(Rng* rng, int lo, int hi) {
  return lo + static_cast<int>(rng->next_u64() % static_cast<uint64_t>(hi - lo + 1));
}

// Draws that fill several values come one statement each: C++ leaves the order in which a call's
// arguments are evaluated open, and GCC on x86-64, GCC on aarch64 and clang each chose their own, so
// Point(uniform_int(rng, ...), uniform_int(rng, ...)) gave each platform other textures (random.hpp).
// The order below, last value first, keeps the texels GCC's x86-64 builds made; the file is built
// with -ffp-contract=off (CMakeLists.txt), and the texels are then the same on aarch64.

// A texel position, y drawn before x.
cv::Point random_texel(Rng* rng) {
  const int y = uniform_int(rng, 0, kSize - 1);
  const int x = uniform_int(rng, 0, kSize - 1);
  return {x, y};
}

// A colour whose channel k is uniform in ck = [lo, hi], the last channel drawn first.
cv::Scalar random_colour(Rng* rng, const cv::Vec2d& c0, const cv::Vec2d& c1, const cv::Vec2d& c2) {
  const double v2 = rng->uniform(c2[0], c2[1]);
  const double v1 = rng->uniform(c1[0], c1[1]);
  const double v0 = rng->uniform(c0[0], c0[1]);
  return {v0, v1, v2};
}

// Row-major kSize x kSize scalar field.
using Field = std::vector<float>;

float smoothstep01(float t) { return t * t * (3.0f - 2.0f * t); }

// One tileable value-noise octave with gx x gy lattice cells (both divide kSize), added with
// `amplitude` times a value in [-1, 1].
void add_value_noise(Rng* rng, int gx, int gy, float amplitude, Field* field) {
  std::vector<float> lattice(static_cast<size_t>(gx) * gy);
  for (float& l : lattice) l = static_cast<float>(rng->uniform(-1.0, 1.0));
  const int cx = kSize / gx, cy = kSize / gy;
  std::vector<float> wx(kSize);
  std::vector<int> ix(kSize);
  for (int x = 0; x < kSize; ++x) {
    ix[x] = x / cx;
    wx[x] = smoothstep01(static_cast<float>(x % cx) / static_cast<float>(cx));
  }
  for (int y = 0; y < kSize; ++y) {
    const int iy0 = y / cy, iy1 = (iy0 + 1) % gy;
    const float wy = smoothstep01(static_cast<float>(y % cy) / static_cast<float>(cy));
    const float* r0 = &lattice[static_cast<size_t>(iy0) * gx];
    const float* r1 = &lattice[static_cast<size_t>(iy1) * gx];
    float* out = &(*field)[static_cast<size_t>(y) * kSize];
    for (int x = 0; x < kSize; ++x) {
      const int i0 = ix[x], i1 = (i0 + 1) % gx;
      const float a = r0[i0] + (r0[i1] - r0[i0]) * wx[x];
      const float b = r1[i0] + (r1[i1] - r1[i0]) * wx[x];
      out[x] += amplitude * (a + (b - a) * wy);
    }
  }
}

// Fractal sum of octaves from a coarsest lattice of g0 cells (aniso: the y lattice is that many
// times finer, for brushed metal and wood grain); roughly in [-1, 1].
Field fbm(Rng* rng, int g0, int octaves, float persistence, int aniso = 1) {
  Field field(static_cast<size_t>(kSize) * kSize, 0.0f);
  float amplitude = 1.0f, total = 0.0f;
  for (int o = 0; o < octaves; ++o) {
    const int g = std::min(g0 << o, kSize);
    add_value_noise(rng, g, std::min(g * aniso, kSize), amplitude, &field);
    total += amplitude;
    amplitude *= persistence;
  }
  const float inv = 1.8f / total;  // sums of octaves rarely reach their bound
  for (float& f : field) f = std::clamp(f * inv, -1.0f, 1.0f);
  return field;
}

cv::Vec3f bgr(double b, double g, double r) {
  return {static_cast<float>(b), static_cast<float>(g), static_cast<float>(r)};
}

cv::Scalar gray(double v) { return {v, v, v}; }

// Canvas: a CV_8UC3 tile; drawing wraps around the borders by drawing the 9 periodic copies.
template <class Draw>
void draw_wrapped(cv::Mat* canvas, Draw draw) {
  for (int oy = -kSize; oy <= kSize; oy += kSize) {
    for (int ox = -kSize; ox <= kSize; ox += kSize) draw(canvas, cv::Point(ox, oy));
  }
}

cv::Mat to_canvas(const std::vector<cv::Vec3f>& albedo) {
  cv::Mat canvas(kSize, kSize, CV_8UC3);
  for (int y = 0; y < kSize; ++y) {
    auto* row = canvas.ptr<cv::Vec3b>(y);
    for (int x = 0; x < kSize; ++x) {
      const cv::Vec3f& a = albedo[static_cast<size_t>(y) * kSize + x];
      row[x] = cv::Vec3b(cv::saturate_cast<uchar>(a[0]), cv::saturate_cast<uchar>(a[1]),
                         cv::saturate_cast<uchar>(a[2]));
    }
  }
  return canvas;
}

// Base colour modulated by a field: c * (1 + contrast * f).
std::vector<cv::Vec3f> modulate(const cv::Vec3f& colour, const Field& f, float contrast) {
  std::vector<cv::Vec3f> out(f.size());
  for (size_t i = 0; i < f.size(); ++i) out[i] = colour * (1.0f + contrast * f[i]);
  return out;
}

// Filled dots of radius [r0, r1] with a colour from `colour(rng)`.
template <class Colour>
void speckles(cv::Mat* canvas, Rng* rng, int count, int r0, int r1, Colour colour) {
  for (int i = 0; i < count; ++i) {
    const cv::Point c = random_texel(rng);
    const int r = uniform_int(rng, r0, r1);
    const cv::Scalar col = colour(rng);
    draw_wrapped(canvas,
                 [&](cv::Mat* m, cv::Point o) { cv::circle(*m, c + o, r, col, cv::FILLED, cv::LINE_AA); });
  }
}

// Irregular spots of 1-3 cm (clusters of overlapping discs, whose outlines cross in corners):
// dark or light versions of the local colour. They survive the mip chain at 3-6 m, where the
// small speckles have averaged away, so far surfaces keep corners too.
void far_spots(cv::Mat* canvas, Rng* rng, int count) {
  for (int i = 0; i < count; ++i) {
    const cv::Point c = random_texel(rng);
    const double f = rng->uniform() < 0.6 ? rng->uniform(0.35, 0.65) : rng->uniform(1.4, 1.8);
    const cv::Vec3b local = canvas->at<cv::Vec3b>(c);
    const cv::Scalar col(std::min(255.0, local[0] * f + 8), std::min(255.0, local[1] * f + 8),
                         std::min(255.0, local[2] * f + 8));
    const int discs = uniform_int(rng, 2, 4);
    for (int k = 0; k < discs; ++k) {
      const int dy = uniform_int(rng, -5, 5);
      const int dx = uniform_int(rng, -5, 5);
      const cv::Point p = c + cv::Point(dx, dy);
      const int r = uniform_int(rng, 3, 7);
      draw_wrapped(canvas,
                   [&](cv::Mat* m, cv::Point o) { cv::circle(*m, p + o, r, col, cv::FILLED, cv::LINE_AA); });
    }
  }
}

// Soft multiplicative blobs (stains, dirt, water marks): pixel *= 1 - strength * falloff, with a
// tint towards `tint`.
void stains(cv::Mat* canvas, Rng* rng, int count, int r0, int r1, float s0, float s1, const cv::Vec3f& tint) {
  for (int i = 0; i < count; ++i) {
    const int cx = uniform_int(rng, 0, kSize - 1), cy = uniform_int(rng, 0, kSize - 1);
    const int r = uniform_int(rng, r0, r1);
    const float strength = static_cast<float>(rng->uniform(s0, s1));
    const float inv_r2 = 1.0f / static_cast<float>(r * r);
    for (int dy = -r; dy <= r; ++dy) {
      auto* row = canvas->ptr<cv::Vec3b>((cy + dy) & (kSize - 1));
      for (int dx = -r; dx <= r; ++dx) {
        const float d2 = static_cast<float>(dx * dx + dy * dy) * inv_r2;
        if (d2 >= 1.0f) continue;
        const float w = strength * (1.0f - d2) * (1.0f - d2);
        cv::Vec3b& p = row[(cx + dx) & (kSize - 1)];
        for (int c = 0; c < 3; ++c) p[c] = cv::saturate_cast<uchar>(p[c] * (1.0f - w) + tint[c] * w);
      }
    }
  }
}

std::string random_text(Rng* rng, int min_len, int max_len) {
  static constexpr char kAlphabet[] = "ABCDEFGHJKLMNPRSTUVWXYZ0123456789-/#";
  const int n = uniform_int(rng, min_len, max_len);
  std::string s;
  for (int i = 0; i < n; ++i)
    s.push_back(kAlphabet[uniform_int(rng, 0, static_cast<int>(sizeof(kAlphabet)) - 2)]);
  return s;
}

void text(cv::Mat* canvas, Rng* rng, const cv::Point& at, double scale, int thickness,
          const cv::Scalar& col) {
  const std::string s = random_text(rng, 2, 7);
  draw_wrapped(canvas, [&](cv::Mat* m, cv::Point o) {
    cv::putText(*m, s, at + o, cv::FONT_HERSHEY_SIMPLEX, scale, col, thickness, cv::LINE_AA);
  });
}

// Random-walk polyline (cracks, scratches).
void walk(cv::Mat* canvas, Rng* rng, int steps, double step_len, double turn, int thickness,
          const cv::Scalar& col) {
  const double y0 = rng->uniform(0, kSize);
  cv::Point2d p(rng->uniform(0, kSize), y0);
  double heading = rng->uniform(0, 2 * M_PI);
  for (int s = 0; s < steps; ++s) {
    heading += rng->uniform(-turn, turn);
    const cv::Point2d q = p + step_len * cv::Point2d(std::cos(heading), std::sin(heading));
    const cv::Point a(cvRound(p.x), cvRound(p.y)), b(cvRound(q.x), cvRound(q.y));
    draw_wrapped(canvas,
                 [&](cv::Mat* m, cv::Point o) { cv::line(*m, a + o, b + o, col, thickness, cv::LINE_AA); });
    p = q;
    if (p.x < 0 || p.x >= kSize || p.y < 0 || p.y >= kSize) {  // continue from the wrapped copy
      p.x -= kSize * std::floor(p.x / kSize);
      p.y -= kSize * std::floor(p.y / kSize);
    }
  }
}

// Additive per-texel grain (sensor-scale roughness) of +-amplitude levels.
void grain(cv::Mat* canvas, Rng* rng, int amplitude) {
  for (int y = 0; y < kSize; ++y) {
    auto* row = canvas->ptr<cv::Vec3b>(y);
    for (int x = 0; x < kSize; ++x) {
      const int d = static_cast<int>(rng->next_u64() % static_cast<uint64_t>(2 * amplitude + 1)) - amplitude;
      for (int c = 0; c < 3; ++c) row[x][c] = cv::saturate_cast<uchar>(row[x][c] + d);
    }
  }
}

// A printed label or sign: a filled rectangle with a border, text lines and maybe a barcode.
void label(cv::Mat* canvas, Rng* rng, const cv::Scalar& paper, const cv::Scalar& ink, int w0, int w1) {
  const int w = uniform_int(rng, w0, w1), h = uniform_int(rng, w0 / 2, w1 * 2 / 3);
  const cv::Point tl = random_texel(rng);
  draw_wrapped(canvas, [&](cv::Mat* m, cv::Point o) {
    cv::rectangle(*m, cv::Rect(tl + o, cv::Size(w, h)), paper, cv::FILLED);
    cv::rectangle(*m, cv::Rect(tl + o, cv::Size(w, h)), ink, 2);
  });
  const double scale = std::max(0.35, h / 110.0);
  const int line_h = static_cast<int>(28 * scale) + 4;
  for (int y = tl.y + line_h; y < tl.y + h - 6; y += line_h) text(canvas, rng, {tl.x + 6, y}, scale, 1, ink);
  if (rng->uniform() < 0.5) {  // barcode
    int x = tl.x + w / 2;
    const int y0 = tl.y + h / 2, y1 = tl.y + h - 6;
    while (x < tl.x + w - 6) {
      const int bar = uniform_int(rng, 1, 4);
      if (rng->uniform() < 0.5) {
        draw_wrapped(canvas, [&](cv::Mat* m, cv::Point o) {
          cv::rectangle(*m, cv::Rect(cv::Point(x, y0) + o, cv::Size(bar, y1 - y0)), ink, cv::FILLED);
        });
      }
      x += bar;
    }
  }
}

cv::Mat concrete(Rng* rng) {
  const Field f = fbm(rng, 8, 7, 0.6f);
  cv::Mat c = to_canvas(modulate(bgr(150, 152, 156), f, 0.35f));
  stains(&c, rng, 60, 20, 110, 0.15f, 0.45f, bgr(60, 62, 64));
  // Aggregate: light and dark stones at several sizes.
  speckles(&c, rng, 9000, 1, 4,
           [](Rng* r) { return gray(r->uniform() < 0.5 ? r->uniform(30, 90) : r->uniform(190, 250)); });
  speckles(&c, rng, 500, 4, 8, [](Rng* r) { return gray(r->uniform(60, 220)); });
  for (int i = 0; i < 25; ++i) walk(&c, rng, uniform_int(rng, 20, 60), 8.0, 0.6, 1, gray(45));
  far_spots(&c, rng, 400);
  grain(&c, rng, 10);
  return c;
}

cv::Mat painted_wall(Rng* rng) {
  const Field f = fbm(rng, 4, 7, 0.55f);
  cv::Mat c = to_canvas(modulate(bgr(188, 206, 214), f, 0.18f));
  stains(&c, rng, 80, 15, 90, 0.2f, 0.5f, bgr(90, 100, 110));
  // Scuffs, screw holes and dirt.
  speckles(&c, rng, 4000, 1, 4, [](Rng* r) { return gray(r->uniform(60, 150)); });
  speckles(&c, rng, 400, 4, 9, [](Rng* r) { return random_colour(r, {60, 200}, {60, 200}, {60, 200}); });
  // Signs and posters.
  for (int i = 0; i < 16; ++i) {
    const cv::Scalar paper = random_colour(rng, {120, 255}, {120, 255}, {120, 255});
    label(&c, rng, paper, gray(rng->uniform(0, 60)), 50, 160);
  }
  for (int i = 0; i < 30; ++i) {
    const cv::Scalar col = gray(rng->uniform(60, 120));
    walk(&c, rng, uniform_int(rng, 5, 20), 6.0, 0.3, 1, col);
  }
  far_spots(&c, rng, 400);
  grain(&c, rng, 8);
  return c;
}

cv::Mat steel(Rng* rng) {
  // Brushed: noise stretched along u, plus mill-scale mottling.
  Field f = fbm(rng, 4, 6, 0.6f);
  const Field brushed = fbm(rng, 2, 6, 0.7f, 32);
  for (size_t i = 0; i < f.size(); ++i) f[i] = 0.6f * f[i] + 0.4f * brushed[i];
  cv::Mat c = to_canvas(modulate(bgr(178, 176, 172), f, 0.3f));
  stains(&c, rng, 70, 15, 80, 0.2f, 0.55f, bgr(110, 95, 85));  // heat tint / mill scale
  // Weld spatter, pits and grinder marks.
  speckles(&c, rng, 9000, 1, 3,
           [](Rng* r) { return gray(r->uniform() < 0.7 ? r->uniform(20, 90) : r->uniform(220, 255)); });
  for (int i = 0; i < 500; ++i) {
    const cv::Scalar col = gray(rng->uniform() < 0.5 ? 80 : 235);
    const double step_len = rng->uniform(5, 15);
    walk(&c, rng, uniform_int(rng, 1, 4), step_len, 0.2, 1, col);
  }
  // Chalk and marker marks.
  for (int i = 0; i < 45; ++i) {
    const cv::Point at = random_texel(rng);
    const cv::Scalar col = rng->uniform() < 0.5 ? gray(250) : gray(25);
    text(&c, rng, at, rng->uniform(0.5, 1.1), 2, col);
  }
  far_spots(&c, rng, 400);
  grain(&c, rng, 8);
  return c;
}

cv::Mat rusty_steel(Rng* rng) {
  const Field f = fbm(rng, 4, 7, 0.6f);
  const Field rust = fbm(rng, 4, 7, 0.65f);
  std::vector<cv::Vec3f> albedo(f.size());
  const cv::Vec3f metal = bgr(95, 92, 90), oxide = bgr(40, 85, 150);
  for (size_t i = 0; i < f.size(); ++i) {
    // Sharp-edged rust patches (a steep ramp on the second noise).
    const float m = std::clamp((rust[i] + 0.05f) * 6.0f, 0.0f, 1.0f);
    albedo[i] = (metal * (1.0f - m) + oxide * m) * (1.0f + 0.35f * f[i]);
  }
  cv::Mat c = to_canvas(albedo);
  stains(&c, rng, 60, 15, 90, 0.2f, 0.5f, bgr(20, 40, 70));
  speckles(&c, rng, 8000, 1, 3,
           [](Rng* r) { return r->uniform() < 0.6 ? gray(r->uniform(10, 60)) : cv::Scalar(60, 130, 210); });
  speckles(&c, rng, 500, 3, 7, [](Rng* r) { return random_colour(r, {20, 80}, {50, 120}, {90, 190}); });
  far_spots(&c, rng, 400);
  grain(&c, rng, 10);
  return c;
}

cv::Mat wood(Rng* rng) {
  const Field warp = fbm(rng, 4, 5, 0.5f, 4);
  const Field f = fbm(rng, 8, 6, 0.55f);
  constexpr int kPlank = 64;  // texels per plank (about 0.2 m)
  std::vector<cv::Vec3f> albedo(warp.size());
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const size_t i = static_cast<size_t>(y) * kSize + x;
      // Grain: stripes along u, bent by low-frequency noise.
      const float g = std::sin(2.0f * static_cast<float>(M_PI) * (y / 9.0f + 3.0f * warp[i]));
      albedo[i] = bgr(75, 135, 190) * (1.0f + 0.22f * g + 0.2f * f[i]);
    }
  }
  cv::Mat c = to_canvas(albedo);
  for (int y = 0; y < kSize; y += kPlank) {  // plank joints and nails
    cv::line(c, {0, y}, {kSize - 1, y}, gray(35), 2);
    for (int x = uniform_int(rng, 0, 100); x < kSize; x += uniform_int(rng, 120, 260)) {
      cv::line(c, {x, y}, {x, y + kPlank}, gray(45), 2);
      cv::circle(c, {x + 8, y + 16}, 3, gray(30), cv::FILLED);
      cv::circle(c, {x + 8, y + kPlank - 16}, 3, gray(30), cv::FILLED);
    }
  }
  for (int i = 0; i < 60; ++i) {  // knots
    const cv::Point k = random_texel(rng);
    const int minor = uniform_int(rng, 3, 8);
    const cv::Size axes(uniform_int(rng, 6, 16), minor);
    draw_wrapped(&c, [&](cv::Mat* m, cv::Point o) {
      cv::ellipse(*m, k + o, axes, 0, 0, 360, cv::Scalar(30, 60, 100), cv::FILLED, cv::LINE_AA);
      cv::ellipse(*m, k + o, axes + cv::Size(4, 3), 0, 0, 360, cv::Scalar(40, 80, 130), 2, cv::LINE_AA);
    });
  }
  stains(&c, rng, 50, 15, 70, 0.15f, 0.45f, bgr(30, 50, 70));
  speckles(&c, rng, 6000, 1, 3, [](Rng* r) { return random_colour(r, {20, 70}, {40, 100}, {60, 140}); });
  far_spots(&c, rng, 400);
  grain(&c, rng, 8);
  return c;
}

cv::Mat cardboard(Rng* rng) {
  const Field f = fbm(rng, 4, 6, 0.55f);
  std::vector<cv::Vec3f> albedo(f.size());
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const size_t i = static_cast<size_t>(y) * kSize + x;
      albedo[i] = bgr(95, 150, 192) * (1.0f + 0.2f * f[i]);
    }
  }
  cv::Mat c = to_canvas(albedo);
  for (int i = 0; i < 12; ++i) {  // tape strips
    const int y = uniform_int(rng, 0, kSize - 1), h = uniform_int(rng, 14, 24);
    draw_wrapped(&c, [&](cv::Mat* m, cv::Point o) {
      cv::rectangle(*m, cv::Rect(cv::Point(0, y) + o, cv::Size(kSize, h)), cv::Scalar(120, 175, 205),
                    cv::FILLED);
    });
  }
  // Shipping labels and printed marks, kept to moderate contrast so that they do not outbid the
  // rest of the surface for ORB's strongest corners.
  for (int i = 0; i < 14; ++i) {
    const cv::Scalar ink = gray(rng->uniform(60, 90));
    label(&c, rng, gray(rng->uniform(170, 200)), ink, 50, 130);
  }
  for (int i = 0; i < 50; ++i) {
    const cv::Point at = random_texel(rng);
    const cv::Scalar col = rng->uniform() < 0.7 ? gray(60) : cv::Scalar(50, 50, 140);
    text(&c, rng, at, rng->uniform(0.6, 1.4), 2, col);
  }
  stains(&c, rng, 60, 15, 70, 0.2f, 0.5f, bgr(40, 70, 100));
  speckles(&c, rng, 9000, 1, 3, [](Rng* r) {
    return r->uniform() < 0.7 ? random_colour(r, {10, 50}, {30, 80}, {50, 110})
                              : random_colour(r, {150, 200}, {200, 240}, {220, 255});
  });
  far_spots(&c, rng, 400);
  grain(&c, rng, 8);
  return c;
}

cv::Mat pipe(Rng* rng) {
  const Field f = fbm(rng, 4, 6, 0.55f);
  const Field chips = fbm(rng, 8, 6, 0.65f);
  std::vector<cv::Vec3f> albedo(f.size());
  const cv::Vec3f paint = bgr(30, 150, 215), metal = bgr(70, 70, 75);
  for (size_t i = 0; i < f.size(); ++i) {
    const float m = std::clamp((chips[i] - 0.4f) * 8.0f, 0.0f, 1.0f);  // chipped paint
    albedo[i] = (paint * (1.0f - m) + metal * m) * (1.0f + 0.2f * f[i]);
  }
  cv::Mat c = to_canvas(albedo);
  stains(&c, rng, 60, 10, 70, 0.2f, 0.5f, bgr(30, 40, 50));
  speckles(&c, rng, 7000, 1, 3,
           [](Rng* r) { return gray(r->uniform() < 0.6 ? r->uniform(10, 70) : r->uniform(200, 250)); });
  for (int i = 0; i < 50; ++i) {  // stencilled flow markings
    const cv::Point at = random_texel(rng);
    const cv::Scalar col = rng->uniform() < 0.5 ? gray(20) : gray(245);
    text(&c, rng, at, rng->uniform(0.5, 1.0), 2, col);
  }
  far_spots(&c, rng, 400);
  grain(&c, rng, 8);
  return c;
}

// Level-0 density per material (metres per texel): finer where surfaces are small and close.
constexpr std::array<float, kMaterialCount> kTexelM = {0.004f, 0.004f,  0.0025f, 0.003f,
                                                       0.003f, 0.0025f, 0.0025f};

void fill_texture(const cv::Mat& canvas, float texel_m, Texture* tex) {
  tex->log2_size = kLog2Size;
  tex->levels = kLog2Size - kMinLevelLog2 + 1;
  tex->texels_per_m = 1.0f / texel_m;
  size_t total = 0;
  for (int l = 0; l < tex->levels; ++l) {
    tex->offset[l] = static_cast<uint32_t>(total);
    tex->scale[l] = std::ldexp(1.0f, -l);
    total += static_cast<size_t>(1) << (2 * (kLog2Size - l));
  }
  tex->texels.assign(total, 0);
  uint32_t* level0 = tex->texels.data();
  for (int y = 0; y < kSize; ++y) {
    const auto* row = canvas.ptr<cv::Vec3b>(y);
    for (int x = 0; x < kSize; ++x) {
      level0[texel_index(x, y, kLog2Size)] = row[x][0] | (row[x][1] << 8) | (row[x][2] << 16);
    }
  }
  // Box-filtered mip chain.
  for (int l = 1; l < tex->levels; ++l) {
    const int shift = kLog2Size - l, n = 1 << shift;
    const uint32_t* src = tex->texels.data() + tex->offset[l - 1];
    uint32_t* dst = tex->texels.data() + tex->offset[l];
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const uint32_t a = src[texel_index(2 * x, 2 * y, shift + 1)],
                       b = src[texel_index(2 * x + 1, 2 * y, shift + 1)];
        const uint32_t c = src[texel_index(2 * x, 2 * y + 1, shift + 1)];
        const uint32_t d = src[texel_index(2 * x + 1, 2 * y + 1, shift + 1)];
        uint32_t out = 0;
        for (int s = 0; s < 24; s += 8) {
          const uint32_t sum = ((a >> s) & 255u) + ((b >> s) & 255u) + ((c >> s) & 255u) + ((d >> s) & 255u);
          out |= ((sum + 2) / 4) << s;
        }
        dst[texel_index(x, y, shift)] = out;
      }
    }
  }
}

}  // namespace

void generate_textures(uint64_t seed, const std::array<bool, kMaterialCount>& used,
                       MaterialTextures* textures) {
  for (int m = 0; m < kMaterialCount; ++m) {
    Texture& tex = (*textures)[m];
    tex = Texture{};
    if (!used[m]) continue;
    Rng rng(seed * 0x100000001B3ull + static_cast<uint64_t>(m) * 0x9E3779B97F4A7C15ull);
    cv::Mat canvas;
    switch (static_cast<Material>(m)) {
      case Material::kConcrete:
        canvas = concrete(&rng);
        break;
      case Material::kPaintedWall:
        canvas = painted_wall(&rng);
        break;
      case Material::kSteel:
        canvas = steel(&rng);
        break;
      case Material::kRustySteel:
        canvas = rusty_steel(&rng);
        break;
      case Material::kWood:
        canvas = wood(&rng);
        break;
      case Material::kCardboard:
        canvas = cardboard(&rng);
        break;
      case Material::kPipe:
        canvas = pipe(&rng);
        break;
      case Material::kCount:
        break;
    }
    fill_texture(canvas, kTexelM[m], &tex);
  }
}

cv::Mat texture_level_image(const Texture& texture, int level) {
  if (texture.empty() || level < 0 || level >= texture.levels) return {};
  const int n = 1 << (texture.log2_size - level);
  cv::Mat image(n, n, CV_8UC3);
  const uint32_t* src = texture.texels.data() + texture.offset[level];
  for (int y = 0; y < n; ++y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < n; ++x) {
      const uint32_t t = src[texel_index(x, y, texture.log2_size - level)];
      row[x] = cv::Vec3b(t & 255u, (t >> 8) & 255u, (t >> 16) & 255u);
    }
  }
  return image;
}

}  // namespace hwr::sim::detail
