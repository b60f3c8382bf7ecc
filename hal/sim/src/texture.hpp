#pragma once
// Procedural, tileable material textures of the simulator (private to hwr_sim). One square
// power-of-two BGR tile per material with its mip chain, generated once from the scene's
// texture_seed, so ORB finds well-spread corners on every surface at 0.5-5 m. Sampling is one
// bilinear lookup in the mip level chosen from the pixel footprint.

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "hwr/sim/scene_spec.hpp"

namespace hwr::sim::detail {

constexpr int kMaterialCount = static_cast<int>(Material::kCount);

// Index of texel (x, y) in a level of side 1 << shift stored in 4x4 blocks.
inline uint32_t texel_index(uint32_t x, uint32_t y, int shift) {
  return ((((y >> 2) << (shift - 2)) + (x >> 2)) << 4) | ((y & 3u) << 2) | (x & 3u);
}

struct Texture {
  int log2_size = 0;       // level 0 is (1 << log2_size) texels square
  int levels = 0;          // mip levels stored, level l is (1 << (log2_size - l)) square
  float texels_per_m = 0;  // level-0 texel density on the surface
  // All levels, texel = b | g << 8 | r << 16, each level stored in 4x4-texel blocks (one cache
  // line) in row-major block order, so that lookups walking any direction over the texture touch
  // few lines and pages.
  std::vector<uint32_t> texels;
  std::array<uint32_t, 16> offset{};
  std::array<float, 16> scale{};  // 2^-level

  bool empty() const { return texels.empty(); }
};

using MaterialTextures = std::array<Texture, kMaterialCount>;

// Generates the textures of the materials flagged in `used` (others stay empty). Deterministic
// in (seed, material).
void generate_textures(uint64_t seed, const std::array<bool, kMaterialCount>& used,
                       MaterialTextures* textures);

// Level `level` of a texture as a CV_8UC3 image (tests, debugging).
cv::Mat texture_level_image(const Texture& texture, int level);

// Bilinear lookup at fixed-point texel coordinates (xi, yi) = 256 (u 2^-level - 1/2, v ...) of
// level `level`, wrapping, times a shading factor k16 = k * 65535 (k in [0, 1]); writes 3 bytes of
// BGR. 8-bit bilinear weights, so the SSE2 and the portable paths give identical bytes.
inline void sample_shaded_fixed(const Texture& tex, int level, int xi, int yi, uint32_t k16, uint8_t* bgr) {
  const int shift = tex.log2_size - level;
  const uint32_t mask = (1u << shift) - 1u;
  const uint32_t x0 = static_cast<uint32_t>(xi >> 8) & mask, x1 = static_cast<uint32_t>((xi >> 8) + 1) & mask;
  const uint32_t y0 = static_cast<uint32_t>(yi >> 8) & mask, y1 = static_cast<uint32_t>((yi >> 8) + 1) & mask;
  const uint32_t fx = static_cast<uint32_t>(xi) & 255u, fy = static_cast<uint32_t>(yi) & 255u;
  const uint32_t* texels = tex.texels.data() + tex.offset[level];
  const uint32_t t00 = texels[texel_index(x0, y0, shift)], t01 = texels[texel_index(x1, y0, shift)];
  const uint32_t t10 = texels[texel_index(x0, y1, shift)], t11 = texels[texel_index(x1, y1, shift)];
  const uint32_t w00 = ((256u - fx) * (256u - fy)) >> 8, w01 = (fx * (256u - fy)) >> 8;
  const uint32_t w10 = ((256u - fx) * fy) >> 8, w11 = (fx * fy) >> 8;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  const __m128i top = _mm_unpacklo_epi8(
      _mm_unpacklo_epi32(_mm_cvtsi32_si128(static_cast<int>(t00)), _mm_cvtsi32_si128(static_cast<int>(t01))),
      zero);
  const __m128i bottom = _mm_unpacklo_epi8(
      _mm_unpacklo_epi32(_mm_cvtsi32_si128(static_cast<int>(t10)), _mm_cvtsi32_si128(static_cast<int>(t11))),
      zero);
  const __m128i w_top = _mm_unpacklo_epi64(_mm_set1_epi16(static_cast<int16_t>(w00)),
                                           _mm_set1_epi16(static_cast<int16_t>(w01)));
  const __m128i w_bottom = _mm_unpacklo_epi64(_mm_set1_epi16(static_cast<int16_t>(w10)),
                                              _mm_set1_epi16(static_cast<int16_t>(w11)));
  __m128i sum =
      _mm_add_epi16(_mm_mullo_epi16(top, w_top), _mm_mullo_epi16(bottom, w_bottom));  // <= 255 * 256
  sum = _mm_add_epi16(sum, _mm_srli_si128(sum, 8));
  sum = _mm_mulhi_epu16(sum, _mm_set1_epi16(static_cast<int16_t>(k16)));
  sum = _mm_srli_epi16(_mm_add_epi16(sum, _mm_set1_epi16(128)), 8);
  const uint32_t packed = static_cast<uint32_t>(_mm_cvtsi128_si32(_mm_packus_epi16(sum, sum)));
  bgr[0] = static_cast<uint8_t>(packed);
  bgr[1] = static_cast<uint8_t>(packed >> 8);
  bgr[2] = static_cast<uint8_t>(packed >> 16);
#else
  for (int c = 0; c < 3; ++c) {
    const int s = 8 * c;
    const uint32_t sum = (w00 * ((t00 >> s) & 255u) + w01 * ((t01 >> s) & 255u) + w10 * ((t10 >> s) & 255u) +
                          w11 * ((t11 >> s) & 255u)) &
                         0xffffu;
    bgr[c] = static_cast<uint8_t>((((sum * k16) >> 16) + 128u) >> 8);
  }
#endif
}

// The same at (u, v) in level-0 texel units (texel centres at integer + 0.5).
inline void sample_shaded(const Texture& tex, int level, float u, float v, uint32_t k16, uint8_t* bgr) {
  // 24.8 fixed point; the shift in the lookup floors negative coordinates too (error < 1/256 texel).
  const int xi = static_cast<int>((u * tex.scale[level] - 0.5f) * 256.0f);
  const int yi = static_cast<int>((v * tex.scale[level] - 0.5f) * 256.0f);
  sample_shaded_fixed(tex, level, xi, yi, k16, bgr);
}

}  // namespace hwr::sim::detail
