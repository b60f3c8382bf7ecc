// The simulator's procedural textures are the same texels on every platform and compiler: every
// sim figure (tracking, detection, mapping) depends on them, and the AGX build runs the same
// scenarios. texture.cpp draws one random value per statement (a call's arguments are evaluated in
// an order each compiler picks) and is built without fused multiply-adds.

#include <array>
#include <cstdint>

#include <gtest/gtest.h>

#include "texture.hpp"

namespace hwr::sim::detail {
namespace {

uint64_t fnv1a(const std::vector<uint32_t>& texels) {
  uint64_t h = 1469598103934665603ull;
  for (const uint32_t v : texels) {
    h ^= v;
    h *= 1099511628211ull;
  }
  return h;
}

// GIVEN seed 1 and every material
// WHEN the textures are generated
// THEN each material's texels (all mip levels) hash to what the x86-64 GCC build made before and
//      after the draws were sequenced (FNV-1a over the packed texels). Checked on 2026-12-04 with
//      GCC on x86-64, GCC on aarch64 under qemu and clang on x86-64 (OpenCV's drawing and libm come
//      from each platform: another platform could still differ).
TEST(Textures, GivenSeedOneThenEveryMaterialHasTheTexelsOfTheReferenceBuild) {
  constexpr std::array<uint64_t, kMaterialCount> kReference = {
      0x427e3601f3cca516ull,  // concrete
      0xfe04397d5195a8baull,  // painted_wall
      0xf1d8820727b90824ull,  // steel
      0xc661ed89cea94d65ull,  // rusty_steel
      0xd12bdfa088796e16ull,  // wood
      0xa8a188fc14e57ba0ull,  // cardboard
      0x7764cd76e788eaf2ull,  // pipe
  };
  std::array<bool, kMaterialCount> used;
  used.fill(true);
  MaterialTextures textures;
  generate_textures(1, used, &textures);
  for (int m = 0; m < kMaterialCount; ++m) {
    ASSERT_FALSE(textures[static_cast<size_t>(m)].empty()) << "material " << m;
    EXPECT_EQ(fnv1a(textures[static_cast<size_t>(m)].texels), kReference[static_cast<size_t>(m)])
        << "material " << m;
  }
  // Another seed gives other texels.
  MaterialTextures other;
  generate_textures(2, used, &other);
  EXPECT_NE(fnv1a(other[0].texels), kReference[0]);
}

}  // namespace
}  // namespace hwr::sim::detail
