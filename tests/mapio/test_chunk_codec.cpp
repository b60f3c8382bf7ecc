// Draco chunk codec (issue #5 item 2). Oracles: the original cloud (per-axis error bound, exact colours,
// flags and ids, matched through unique ids or unique colours when the kd-tree reorders points), the
// 15 bytes/point raw size, Debian's stock draco_decoder for interop, the allocation counter for "a
// forged header must not make the decoder allocate".

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <unordered_map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "hwr/core/alloc_counter.hpp"
#include "hwr/mapio/chunk_codec.hpp"
#include "hwr/mapio/draco_header.hpp"

namespace hwr::mapio {
namespace {

struct Cloud {
  std::vector<ChunkPoint> points;
  std::vector<uint32_t> ids;
};

// n points uniform in [offset, offset + extent]^3 with distinct ids (including ids near 2^32) and a
// distinct (r, g, b) per point for n <= 2^24, so every point can be matched after a kd-tree reorder.
Cloud random_cloud(int n, double extent_m, double offset_m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, extent_m);
  Cloud c;
  c.points.resize(static_cast<size_t>(n));
  c.ids.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    ChunkPoint& p = c.points[static_cast<size_t>(i)];
    p.x_m = static_cast<float>(offset_m + u(rng));
    p.y_m = static_cast<float>(offset_m + u(rng));
    p.z_m = static_cast<float>(offset_m - u(rng));
    const uint32_t colour =
        static_cast<uint32_t>(i) * 2654435761u % (1u << 24);  // odd multiplier: a bijection
    p.r = static_cast<uint8_t>(colour);
    p.g = static_cast<uint8_t>(colour >> 8);
    p.b = static_cast<uint8_t>(colour >> 16);
    p.flags = static_cast<uint8_t>(i % 7 == 0 ? 1 : 0);
    c.ids[static_cast<size_t>(i)] =
        (i % 2 == 0) ? 0xFFFFFFFFu - static_cast<uint32_t>(i) : static_cast<uint32_t>(i);
  }
  return c;
}

uint32_t colour_key(const ChunkPoint& p) { return p.r | (p.g << 8) | (p.b << 16); }

// Checks every decoded point against its original (found through `original_of`), returns the largest
// per-axis error seen.
template <class OriginalOf>
double check_points(const Cloud& in, const DecodedChunk& out, double bound_m, OriginalOf original_of) {
  EXPECT_EQ(out.points.size(), in.points.size());
  std::vector<int> hits(in.points.size(), 0);
  double worst_m = 0.0;
  for (size_t k = 0; k < out.points.size(); ++k) {
    const int i = original_of(k);
    if (i < 0) {
      ADD_FAILURE() << "decoded point " << k << " matches no original";
      return worst_m;
    }
    ++hits[static_cast<size_t>(i)];
    const ChunkPoint& a = in.points[static_cast<size_t>(i)];
    const ChunkPoint& b = out.points[k];
    const double e[3] = {std::fabs(double{a.x_m} - b.x_m), std::fabs(double{a.y_m} - b.y_m),
                         std::fabs(double{a.z_m} - b.z_m)};
    for (double ec : e) {
      worst_m = std::max(worst_m, ec);
      if (ec > bound_m) {
        ADD_FAILURE() << "point " << i << " decoded with error " << ec << " m > bound " << bound_m << " m";
        return worst_m;
      }
    }
    if (a.r != b.r || a.g != b.g || a.b != b.b || a.flags != b.flags) {
      ADD_FAILURE() << "point " << i << " colour/flags changed";
      return worst_m;
    }
  }
  for (size_t i = 0; i < hits.size(); ++i) {
    if (hits[i] != 1) {
      ADD_FAILURE() << "original point " << i << " decoded " << hits[i] << " times";
      break;
    }
  }
  return worst_m;
}

std::vector<uint8_t> encode_or_die(const Cloud& c, const ChunkCodecConfig& cfg,
                                   EncodedChunkInfo* info = nullptr) {
  std::vector<uint8_t> bytes;
  auto r = encode_chunk(c.points.data(), static_cast<int>(c.points.size()),
                        cfg.with_point_ids ? c.ids.data() : nullptr, nullptr, cfg, &bytes);
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  if (r.ok() && info != nullptr) *info = *r;
  return bytes;
}

TEST(QuantizationBits, GivenEdgeCasesThenTheSmallestSufficientQOrMinusOne) {
  EXPECT_EQ(quantization_bits_for(0.0, 0.001), 1);  // one value: any q works, Draco needs q >= 1
  // 1 m at 1 mm: 1/(2^q - 1)/2 <= 0.001 <=> 2^q - 1 >= 500 -> q = 9 (511), q = 8 (255) is too coarse.
  EXPECT_EQ(quantization_bits_for(1.0, 0.001), 9);
  EXPECT_EQ(quantization_bits_for(0.5, 0.001), 8);    // 0.5 / 255 / 2 = 0.98e-3 <= 1 mm
  EXPECT_EQ(quantization_bits_for(0.52, 0.001), 9);   // 0.52 / 255 / 2 = 1.02e-3 > 1 mm
  EXPECT_EQ(quantization_bits_for(0.002, 0.001), 1);  // 0.002 / 1 / 2 = 1 mm
  // 2^30 - 1 steps is the most Draco allows: 2 km at 1 um fits in 30 bits, 2.2 km needs 31.
  EXPECT_EQ(quantization_bits_for(2000.0, 1e-6), 30);
  EXPECT_EQ(quantization_bits_for(2200.0, 1e-6), -1);
  EXPECT_EQ(quantization_bits_for(1e12, 0.001), -1);
  EXPECT_EQ(quantization_bits_for(1.0, 0.0), -1);
  EXPECT_EQ(quantization_bits_for(1.0, -1.0), -1);
  EXPECT_EQ(quantization_bits_for(-1.0, 0.001), -1);
  EXPECT_EQ(quantization_bits_for(std::nan(""), 0.001), -1);
  EXPECT_EQ(quantization_bits_for(1.0, std::numeric_limits<double>::infinity()), -1);
  // Property: q is sufficient and q - 1 is not.
  for (double extent : {0.1, 0.7, 3.0, 25.0, 50.0}) {
    for (double err : {0.0005, 0.001, 0.002}) {
      const int q = quantization_bits_for(extent, err);
      ASSERT_GT(q, 0);
      EXPECT_LE(extent / (std::ldexp(1.0, q) - 1.0) / 2.0, err);
      if (q > 1) {
        EXPECT_GT(extent / (std::ldexp(1.0, q - 1) - 1.0) / 2.0, err);
      }
    }
  }
}

// The three payload shapes encode_chunk writes (chunk_codec.hpp): single kd-tree, split kd-tree
// (color_bits < 8), single sequential.
struct Layout {
  const char* name;
  bool preserve_order;
  int color_bits;
};
constexpr Layout kLayouts[] = {{"kd-tree", false, 8}, {"split kd-tree", false, 5}, {"sequential", true, 8}};

ChunkCodecConfig config_for(const Layout& layout) {
  ChunkCodecConfig cfg;
  cfg.preserve_order = layout.preserve_order;
  cfg.color_bits = layout.color_bits;
  return cfg;
}

// The 8-bit value color_bits keeps of a channel (chunk_codec.hpp: nearest of 2^bits levels).
uint8_t reduced(uint8_t v, int bits) {
  if (bits == 8) return v;
  const int levels = (1 << bits) - 1;
  const int level = (v * levels + 127) / 255;
  return static_cast<uint8_t>((level * 255 + levels / 2) / levels);
}

TEST(ChunkCodec, GivenRandomCloudsThenEveryAxisStaysWithinTheBoundAndColoursFlagsIdsAreExact) {
  struct Case {
    int n;
    double extent_m;
    double err_m;
  };
  const Case cases[] = {{1, 0.1, 0.0005},      {1, 50.0, 0.002},      {7, 0.1, 0.0005},
                        {7, 50.0, 0.0005},     {7, 50.0, 0.002},      {1000, 0.1, 0.0005},
                        {1000, 3.0, 0.001},    {1000, 50.0, 0.0005},  {1000, 50.0, 0.002},
                        {100000, 0.1, 0.0005}, {100000, 10.0, 0.001}, {100000, 50.0, 0.002}};
  for (const Case& tc : cases) {
    {
      const double err = tc.err_m;
      for (bool preserve_order : {false, true}) {
        SCOPED_TRACE("n=" + std::to_string(tc.n) + " extent=" + std::to_string(tc.extent_m) +
                     " err=" + std::to_string(err) + " preserve_order=" + std::to_string(preserve_order));
        const Cloud c = random_cloud(tc.n, tc.extent_m, /*offset_m=*/-0.3 * tc.extent_m, 17u + tc.n);
        ChunkCodecConfig cfg;
        cfg.max_position_error_m = err;
        cfg.preserve_order = preserve_order;
        cfg.with_point_ids = true;
        cfg.max_payload_bytes = size_t{8} << 20;  // uniform noise with random ids: ~14 bytes/point
        EncodedChunkInfo info;
        const std::vector<uint8_t> bytes = encode_or_die(c, cfg, &info);
        EXPECT_EQ(info.num_points, tc.n);
        EXPECT_EQ(info.bytes, bytes.size());
        EXPECT_LE(info.max_position_error_m, err);
        if (tc.n >= 1000) {
          EXPECT_GE(info.quantization_bits, quantization_bits_for(tc.extent_m * 0.99, err));
        }
        DecodedChunk out;
        ChunkDecodeLimits limits;
        limits.max_payload_bytes = cfg.max_payload_bytes;
        const core::Status st = decode_chunk(bytes.data(), bytes.size(), tc.n, limits, &out);
        ASSERT_TRUE(st.ok()) << st.to_string();
        ASSERT_EQ(out.ids.size(), c.ids.size());
        EXPECT_TRUE(out.normals_xyz.empty());
        std::unordered_map<uint32_t, int> index_of_id;
        for (size_t i = 0; i < c.ids.size(); ++i) index_of_id[c.ids[i]] = static_cast<int>(i);
        const double worst_m = check_points(c, out, err, [&](size_t k) {
          const auto it = index_of_id.find(out.ids[k]);
          return it == index_of_id.end() ? -1 : it->second;
        });
        EXPECT_LE(worst_m, info.max_position_error_m);
        if (preserve_order) {
          EXPECT_EQ(out.ids, c.ids) << "sequential encoding must keep the point order";
        }
      }
    }
  }
}

TEST(ChunkCodec, GivenKdTreeWithoutIdsThenPointsAreReorderedButEachOneIsKept) {
  const Cloud c = random_cloud(2000, 4.0, 0.0, 5);
  ChunkCodecConfig cfg;  // kd-tree, no ids
  const std::vector<uint8_t> bytes = encode_or_die(c, cfg);
  DecodedChunk out;
  ASSERT_TRUE(decode_chunk(bytes.data(), bytes.size(), -1, ChunkDecodeLimits{}, &out).ok());
  EXPECT_TRUE(out.ids.empty());
  std::map<uint32_t, int> index_of_colour;
  for (size_t i = 0; i < c.points.size(); ++i) index_of_colour[colour_key(c.points[i])] = static_cast<int>(i);
  check_points(c, out, cfg.max_position_error_m, [&](size_t k) {
    const auto it = index_of_colour.find(colour_key(out.points[k]));
    return it == index_of_colour.end() ? -1 : it->second;
  });
  // The kd-tree order is spatial, not the input order: this is why ids travel as an attribute.
  size_t same_place = 0;
  for (size_t k = 0; k < out.points.size(); ++k)
    same_place += colour_key(out.points[k]) == colour_key(c.points[k]);
  EXPECT_LT(same_place, out.points.size() / 2);
}

TEST(ChunkCodec, GivenCoordinatesFarFromTheOriginThenFloatRoundingStaysInsideTheBound) {
  // 1.2 km from the origin float32 spacing is 1.2e-4 m, so Draco's float quantizer adds up to ~1e-4 m
  // to the half step. An extent of 32.76 m makes the half step of q = 14 bits 0.9998 mm, just under
  // 1 mm: an encoder that ignored the rounding would pick q = 14 and overshoot the bound.
  const Cloud c = random_cloud(20000, 32.76, 1200.0, 9);
  for (bool preserve_order : {false, true}) {
    ChunkCodecConfig cfg;  // 1 mm
    cfg.preserve_order = preserve_order;
    cfg.with_point_ids = true;
    EncodedChunkInfo info;
    const std::vector<uint8_t> bytes = encode_or_die(c, cfg, &info);
    EXPECT_EQ(info.quantization_bits, 15);
    DecodedChunk out;
    ASSERT_TRUE(decode_chunk(bytes.data(), bytes.size(), 20000, ChunkDecodeLimits{}, &out).ok());
    std::unordered_map<uint32_t, int> index_of_id;
    for (size_t i = 0; i < c.ids.size(); ++i) index_of_id[c.ids[i]] = static_cast<int>(i);
    check_points(c, out, cfg.max_position_error_m, [&](size_t k) { return index_of_id.at(out.ids[k]); });
  }
}

TEST(ChunkCodec, GivenIdenticalPointsThenAllDecodeExactly) {
  Cloud c = random_cloud(50, 1.0, 0.0, 3);
  for (ChunkPoint& p : c.points) {
    p.x_m = 1.25f;
    p.y_m = -3.5f;
    p.z_m = 0.0f;
  }
  ChunkCodecConfig cfg;
  cfg.with_point_ids = true;
  EncodedChunkInfo info;
  const std::vector<uint8_t> bytes = encode_or_die(c, cfg, &info);
  EXPECT_EQ(info.quantization_bits, 1);
  DecodedChunk out;
  ASSERT_TRUE(decode_chunk(bytes.data(), bytes.size(), 50, ChunkDecodeLimits{}, &out).ok());
  for (const ChunkPoint& p : out.points) {
    EXPECT_EQ(p.x_m, 1.25f);
    EXPECT_EQ(p.y_m, -3.5f);
    EXPECT_EQ(p.z_m, 0.0f);
  }
}

TEST(ChunkCodec, GivenNormalsThenTheyTravelWithTheirPoints) {
  const Cloud c = random_cloud(3000, 2.0, 0.0, 11);
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  std::vector<float> normals(3 * c.points.size());
  for (size_t i = 0; i < c.points.size(); ++i) {
    double v[3] = {g(rng), g(rng), g(rng)};
    const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) normals[3 * i + static_cast<size_t>(k)] = static_cast<float>(v[k] / len);
  }
  for (bool preserve_order : {false, true}) {
    ChunkCodecConfig cfg;
    cfg.preserve_order = preserve_order;
    cfg.with_point_ids = true;
    std::vector<uint8_t> bytes;
    auto r = encode_chunk(c.points.data(), 3000, c.ids.data(), normals.data(), cfg, &bytes);
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    DecodedChunk out;
    ASSERT_TRUE(decode_chunk(bytes.data(), bytes.size(), 3000, ChunkDecodeLimits{}, &out).ok());
    ASSERT_EQ(out.normals_xyz.size(), normals.size());
    std::map<uint32_t, size_t> index_of_id;
    for (size_t i = 0; i < c.ids.size(); ++i) index_of_id[c.ids[i]] = i;
    double worst_cos = 1.0;
    for (size_t k = 0; k < out.points.size(); ++k) {
      const size_t i = index_of_id.at(out.ids[k]);
      double dot = 0, len2 = 0;
      for (int a = 0; a < 3; ++a) {
        dot +=
            double{normals[3 * i + static_cast<size_t>(a)]} * out.normals_xyz[3 * k + static_cast<size_t>(a)];
        len2 += double{out.normals_xyz[3 * k + static_cast<size_t>(a)]} *
                out.normals_xyz[3 * k + static_cast<size_t>(a)];
      }
      worst_cos = std::min(worst_cos, dot / std::sqrt(len2));
    }
    // 10-bit quantization: well under 1 degree either way (octahedral for sequential, per-component for
    // kd-tree).
    EXPECT_GT(worst_cos, std::cos(1.0 * M_PI / 180.0)) << "preserve_order=" << preserve_order;
  }
}

// Split layout (kd-tree, color_bits < 8): positions and the other attributes travel in two Draco
// clouds and are joined again by the decoded order. Every point keeps its id, flags, normal and
// its colour reduced exactly as documented, including points that share quantized coordinates.
TEST(ChunkCodecSplit, GivenFewerColourBitsOnAKdTreeChunkThenEveryPointKeepsItsOwnAttributes) {
  struct Case {
    int n;
    double extent_m;
    int color_bits;
    bool normals;
  };
  const Case cases[] = {{1, 0.1, 5, false},   {7, 50.0, 5, true},    {1000, 3.0, 1, false},
                        {1000, 3.0, 7, true}, {20000, 8.0, 5, true}, {20000, 0.004, 5, false}};
  for (const Case& tc : cases) {
    SCOPED_TRACE("n=" + std::to_string(tc.n) + " extent=" + std::to_string(tc.extent_m) +
                 " bits=" + std::to_string(tc.color_bits));
    // extent 4 mm at 1 mm: q = 2, so thousands of points share each quantized cell.
    const Cloud c = random_cloud(tc.n, tc.extent_m, 0.0, 31u + static_cast<uint32_t>(tc.n));
    std::vector<float> normals(3 * c.points.size());
    for (size_t i = 0; i < c.points.size(); ++i) {
      const double a = 0.001 * static_cast<double>(i), b = 0.0007 * static_cast<double>(i);
      normals[3 * i] = static_cast<float>(std::cos(a) * std::cos(b));
      normals[3 * i + 1] = static_cast<float>(std::sin(a) * std::cos(b));
      normals[3 * i + 2] = static_cast<float>(std::sin(b));
    }
    ChunkCodecConfig cfg;
    cfg.color_bits = tc.color_bits;
    cfg.with_point_ids = true;
    cfg.max_payload_bytes = size_t{8} << 20;
    std::vector<uint8_t> bytes;
    auto info =
        encode_chunk(c.points.data(), tc.n, c.ids.data(), tc.normals ? normals.data() : nullptr, cfg, &bytes);
    ASSERT_TRUE(info.ok()) << info.status().to_string();
    EXPECT_TRUE(info->split);
    // The first cloud is positions alone, the second (after it) sequential with colour levels.
    auto first = parse_draco_point_cloud_prefix(bytes.data(), bytes.size());
    ASSERT_TRUE(first.ok()) << first.status().to_string();
    EXPECT_EQ(first->num_attributes, 1);
    EXPECT_EQ(first->header.method, DracoPointCloudMethod::kKdTree);
    DecodedChunk out;
    ChunkDecodeLimits limits;
    limits.max_payload_bytes = cfg.max_payload_bytes;
    const core::Status st = decode_chunk(bytes.data(), bytes.size(), tc.n, limits, &out);
    ASSERT_TRUE(st.ok()) << st.to_string();
    ASSERT_EQ(out.ids.size(), c.ids.size());
    ASSERT_EQ(out.normals_xyz.size(), tc.normals ? normals.size() : 0u);
    std::unordered_map<uint32_t, size_t> index_of_id;
    for (size_t i = 0; i < c.ids.size(); ++i) index_of_id[c.ids[i]] = i;
    std::vector<int> hits(c.points.size(), 0);
    for (size_t k = 0; k < out.points.size(); ++k) {
      const auto it = index_of_id.find(out.ids[k]);
      ASSERT_NE(it, index_of_id.end()) << "decoded id " << out.ids[k] << " was never sent";
      const size_t i = it->second;
      ++hits[i];
      const ChunkPoint& a = c.points[i];
      const ChunkPoint& b = out.points[k];
      ASSERT_LE(std::fabs(double{a.x_m} - b.x_m), info->max_position_error_m) << "point " << i;
      ASSERT_LE(std::fabs(double{a.y_m} - b.y_m), info->max_position_error_m) << "point " << i;
      ASSERT_LE(std::fabs(double{a.z_m} - b.z_m), info->max_position_error_m) << "point " << i;
      ASSERT_EQ(b.r, reduced(a.r, tc.color_bits)) << "point " << i;
      ASSERT_EQ(b.g, reduced(a.g, tc.color_bits)) << "point " << i;
      ASSERT_EQ(b.b, reduced(a.b, tc.color_bits)) << "point " << i;
      ASSERT_EQ(b.flags, a.flags) << "point " << i;
      if (tc.normals) {
        double dot = 0;
        for (size_t d = 0; d < 3; ++d) dot += double{normals[3 * i + d]} * out.normals_xyz[3 * k + d];
        ASSERT_GT(dot, std::cos(1.0 * M_PI / 180.0)) << "point " << i << ": normal of another point?";
      }
    }
    EXPECT_EQ(std::count(hits.begin(), hits.end(), 1), static_cast<std::ptrdiff_t>(hits.size()));
  }
}

// Kilometres from the origin float32 no longer separates neighbouring quantization steps (its
// spacing at 7 km is 0.5 mm, the half step 0.5 mm), so the decoded order cannot be tied back to the
// points: the chunk goes in the single layout, colours still reduced as configured.
TEST(ChunkCodecSplit, GivenCoordinatesKilometresOutThenTheSingleLayoutWithReducedColours) {
  const Cloud c = random_cloud(5000, 5.0, 7000.0, 43);
  ChunkCodecConfig cfg;
  cfg.color_bits = 5;
  cfg.with_point_ids = true;
  EncodedChunkInfo info;
  const std::vector<uint8_t> bytes = encode_or_die(c, cfg, &info);
  EXPECT_FALSE(info.split);
  DecodedChunk out;
  ASSERT_TRUE(decode_chunk(bytes.data(), bytes.size(), 5000, ChunkDecodeLimits{}, &out).ok());
  std::unordered_map<uint32_t, size_t> index_of_id;
  for (size_t i = 0; i < c.ids.size(); ++i) index_of_id[c.ids[i]] = i;
  for (size_t k = 0; k < out.points.size(); ++k) {
    const ChunkPoint& a = c.points[index_of_id.at(out.ids[k])];
    ASSERT_EQ(out.points[k].r, reduced(a.r, 5));
    ASSERT_EQ(out.points[k].g, reduced(a.g, 5));
    ASSERT_EQ(out.points[k].b, reduced(a.b, 5));
    ASSERT_LE(std::fabs(double{a.x_m} - out.points[k].x_m), info.max_position_error_m);
  }
  // Near the origin the same cloud takes the split layout.
  const Cloud near = random_cloud(5000, 5.0, 0.0, 43);
  encode_or_die(near, cfg, &info);
  EXPECT_TRUE(info.split);
}

// What the split buys: with coarser colour a kd-tree chunk shrinks by ~1 byte/point, where the single
// layout (colour as kd-tree dimensions) gains almost nothing. The room cloud below, 5-bit colour.
Cloud room_cloud();
TEST(ChunkCodecSplit, GivenCoarserColourThenTheSplitLayoutIsSmallerThanOneKdTreeCloud) {
  const Cloud c = room_cloud();
  ChunkCodecConfig lossless;
  const size_t lossless_bytes = encode_or_die(c, lossless).size();
  ChunkCodecConfig five;
  five.color_bits = 5;
  EncodedChunkInfo info;
  const size_t split_bytes = encode_or_die(c, five, &info).size();
  EXPECT_TRUE(info.split);
  const double per_point = 1.0 / static_cast<double>(c.points.size());
  std::printf("[ split ] room cloud: lossless kd-tree %.2f bytes/point, 5-bit split %.2f bytes/point\n",
              static_cast<double>(lossless_bytes) * per_point, static_cast<double>(split_bytes) * per_point);
  EXPECT_LT(static_cast<double>(split_bytes), 0.85 * static_cast<double>(lossless_bytes));
}

// Bytes after the Draco data, a split chunk cut after its positions, and an attribute cloud of
// another size are each a named error.
TEST(ChunkCodecSplit, GivenTrailingBytesAMissingOrForeignAttributeCloudThenCorruptData) {
  const Cloud c = random_cloud(300, 1.0, 0.0, 41);
  DecodedChunk out;
  for (const Layout& layout : kLayouts) {
    SCOPED_TRACE(layout.name);
    std::vector<uint8_t> bytes = encode_or_die(c, config_for(layout));
    bytes.push_back(0);
    const core::Status st = decode_chunk(bytes.data(), bytes.size(), 300, ChunkDecodeLimits{}, &out);
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
    EXPECT_NE(st.message().find("1 bytes follow"), std::string::npos) << st.message();
  }
  ChunkCodecConfig five;
  five.color_bits = 5;
  // The position cloud alone: the split payload cut where its second "DRACO" starts.
  const std::vector<uint8_t> split = encode_or_die(c, five);
  const std::string text(split.begin(), split.end());
  const size_t second = text.find("DRACO", 5);
  ASSERT_NE(second, std::string::npos);
  const std::vector<uint8_t> positions(split.begin(), split.begin() + static_cast<std::ptrdiff_t>(second));
  core::Status st = decode_chunk(positions.data(), positions.size(), 300, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(st.message().find("no attribute cloud"), std::string::npos) << st.message();
  // The attribute cloud of a 299-point chunk behind 300 positions.
  const Cloud fewer = random_cloud(299, 1.0, 0.0, 42);
  const std::vector<uint8_t> other = encode_or_die(fewer, five);
  const size_t other_second = std::string(other.begin(), other.end()).find("DRACO", 5);
  ASSERT_NE(other_second, std::string::npos);
  std::vector<uint8_t> foreign = positions;
  foreign.insert(foreign.end(), other.begin() + static_cast<std::ptrdiff_t>(other_second), other.end());
  st = decode_chunk(foreign.data(), foreign.size(), 300, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(st.message().find("attribute cloud claims 299 points"), std::string::npos) << st.message();
  // Two split position clouds back to back: the second one carries positions.
  std::vector<uint8_t> doubled = positions;
  doubled.insert(doubled.end(), positions.begin(), positions.end());
  st = decode_chunk(doubled.data(), doubled.size(), 300, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << st.to_string();
}

// A 5 m x 4 m floor and two 5 m x 2 m walls sampled every 2 cm (100 000 points) with 1 mm of depth
// noise and camera-like colour: a smooth shading gradient plus +-3 levels of noise. Shuffled: a chunk
// drawn from a voxel map has no scan order for the sequential coder's delta prediction to exploit.
Cloud room_cloud() {
  std::mt19937 rng(21);
  std::normal_distribution<double> noise_m(0.0, 0.001);
  std::uniform_int_distribution<int> colour_noise(-3, 3);
  Cloud c;
  auto add = [&](double x, double y, double z, int base) {
    ChunkPoint p;
    p.x_m = static_cast<float>(x);
    p.y_m = static_cast<float>(y);
    p.z_m = static_cast<float>(z);
    const int shade = base + static_cast<int>(20.0 * std::sin(0.7 * x + 0.3 * y + 0.5 * z));
    p.r = static_cast<uint8_t>(std::clamp(shade + colour_noise(rng), 0, 255));
    p.g = static_cast<uint8_t>(std::clamp(shade - 10 + colour_noise(rng), 0, 255));
    p.b = static_cast<uint8_t>(std::clamp(shade - 25 + colour_noise(rng), 0, 255));
    p.flags = 0;
    c.points.push_back(p);
  };
  const double s = 0.02;
  for (int i = 0; i < 250; ++i)
    for (int j = 0; j < 200; ++j) add(i * s, j * s, noise_m(rng), 120);  // floor z = 0
  for (int i = 0; i < 250; ++i)
    for (int k = 0; k < 100; ++k) add(i * s, noise_m(rng), k * s, 180);  // wall y = 0
  for (int i = 0; i < 250; ++i)
    for (int k = 0; k < 100; ++k) add(i * s, 4.0 + noise_m(rng), k * s, 160);  // wall y = 4
  std::shuffle(c.points.begin(), c.points.end(), rng);
  return c;
}

TEST(ChunkCodec, GivenARealisticRoomCloudThenItCompressesToUnderAQuarterOfRawAt1mm) {
  const Cloud c = room_cloud();
  ASSERT_EQ(c.points.size(), 100000u);
  const double raw_bytes = 15.0 * static_cast<double>(c.points.size());  // float xyz + rgb
  for (bool preserve_order : {false, true}) {
    ChunkCodecConfig cfg;  // 1 mm
    cfg.preserve_order = preserve_order;
    EncodedChunkInfo info;
    const std::vector<uint8_t> bytes = encode_or_die(c, cfg, &info);
    const double ratio = raw_bytes / static_cast<double>(bytes.size());
    std::printf(
        "[ room cloud ] %s: %zu points -> %zu bytes (%.2f bytes/point), q=%d, ratio vs raw xyz+rgb %.2f\n",
        preserve_order ? "sequential" : "kd-tree", c.points.size(), bytes.size(),
        static_cast<double>(bytes.size()) / static_cast<double>(c.points.size()), info.quantization_bits,
        ratio);
    if (!preserve_order) {
      EXPECT_GT(ratio, 4.0) << "the issue's goal: >= 4x fewer bytes than raw at <= 1 mm";
    }
    DecodedChunk out;
    EXPECT_TRUE(decode_chunk(bytes.data(), bytes.size(), 100000, ChunkDecodeLimits{}, &out).ok());
  }
}

// color_bits < 8 rounds each channel to 2^bits levels: bounded colour error, fewer bytes; positions
// keep their bound.
TEST(ChunkCodec, GivenFewerColourBitsThenColoursStayWithinHalfALevelAndThePayloadShrinks) {
  const Cloud c = room_cloud();
  ChunkCodecConfig cfg;
  const std::vector<uint8_t> full = encode_or_die(c, cfg, nullptr);
  for (int bits : {4, 5, 6}) {
    cfg.color_bits = bits;
    cfg.preserve_order = true;  // point i decodes as point i: compare colours one to one
    const std::vector<uint8_t> lossy = encode_or_die(c, cfg, nullptr);
    DecodedChunk out;
    ASSERT_TRUE(decode_chunk(lossy.data(), lossy.size(), 100000, ChunkDecodeLimits{}, &out).ok());
    const double bound = 255.0 / (2.0 * ((1 << bits) - 1)) + 0.5;
    double worst = 0;
    for (size_t i = 0; i < c.points.size(); ++i) {
      worst = std::max({worst, std::abs(static_cast<double>(out.points[i].r) - c.points[i].r),
                        std::abs(static_cast<double>(out.points[i].g) - c.points[i].g),
                        std::abs(static_cast<double>(out.points[i].b) - c.points[i].b)});
      ASSERT_LE(std::abs(double{out.points[i].x_m} - c.points[i].x_m), cfg.max_position_error_m);
    }
    EXPECT_LE(worst, bound) << bits << " bits";
    EXPECT_GT(worst, 0.0) << bits << " bits: the colours were not reduced";
    cfg.preserve_order = false;
    EXPECT_LT(encode_or_die(c, cfg, nullptr).size(), full.size()) << bits << " bits";
  }
  cfg.color_bits = 0;
  std::vector<uint8_t> bytes;
  EXPECT_EQ(encode_chunk(c.points.data(), static_cast<int>(c.points.size()), nullptr, nullptr, cfg, &bytes)
                .status()
                .code(),
            core::ErrorCode::kInvalidArgument);
}

// ---- rejection -----------------------------------------------------------------------------------

// A decode that succeeds must hand back something that passes the documented checks.
// A decode that succeeds must hand back something that passes the documented checks. Returns whether
// the chunk was rejected.
bool expect_error_or_valid(const std::vector<uint8_t>& bytes, int expected_points, const std::string& what) {
  DecodedChunk out;
  const core::Status st =
      decode_chunk(bytes.data(), bytes.size(), expected_points, ChunkDecodeLimits{}, &out);
  if (!st.ok()) {
    EXPECT_FALSE(st.message().empty()) << what;
    EXPECT_TRUE(st.code() == core::ErrorCode::kCorruptData || st.code() == core::ErrorCode::kOutOfRange)
        << what << ": " << st.to_string();
    return true;
  }
  EXPECT_EQ(out.points.size(), static_cast<size_t>(expected_points)) << what;
  for (const ChunkPoint& p : out.points) {
    EXPECT_TRUE(std::isfinite(p.x_m) && std::isfinite(p.y_m) && std::isfinite(p.z_m)) << what;
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) break;
  }
  EXPECT_TRUE(out.ids.empty() || out.ids.size() == out.points.size()) << what;
  return false;
}

TEST(ChunkCodecReject, GivenEmptyTruncatedOrGarbageBuffersThenAClearError) {
  DecodedChunk out;
  const core::Status empty = decode_chunk(nullptr, 0, -1, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(empty.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(empty.message().find("empty"), std::string::npos) << empty.message();
  EXPECT_EQ(decode_chunk(nullptr, 10, -1, ChunkDecodeLimits{}, &out).code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(decode_chunk(nullptr, 0, -1, ChunkDecodeLimits{}, nullptr).code(),
            core::ErrorCode::kInvalidArgument);

  const Cloud c = random_cloud(500, 2.0, 0.0, 8);
  for (const Layout& layout : kLayouts) {
    SCOPED_TRACE(layout.name);
    ChunkCodecConfig cfg = config_for(layout);
    cfg.with_point_ids = true;
    const std::vector<uint8_t> bytes = encode_or_die(c, cfg);
    // Every proper prefix.
    for (size_t len = 1; len < bytes.size(); ++len) {
      const std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(len));
      const core::Status st = decode_chunk(prefix.data(), prefix.size(), 500, ChunkDecodeLimits{}, &out);
      ASSERT_FALSE(st.ok()) << "a " << len << "-byte prefix of a " << bytes.size() << "-byte chunk decoded";
      if (len < kDracoPointCloudHeaderBytes) {
        EXPECT_NE(st.message().find("truncated"), std::string::npos);
      }
    }
  }
  // Random garbage, with and without a valid-looking header in front.
  std::mt19937 rng(99);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint8_t> junk(static_cast<size_t>(1 + trial * 7));
    for (uint8_t& b : junk) b = static_cast<uint8_t>(byte(rng));
    const core::Status st = decode_chunk(junk.data(), junk.size(), -1, ChunkDecodeLimits{}, &out);
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
    const char* reason = junk.size() < kDracoPointCloudHeaderBytes ? "truncated" : "DRACO";
    EXPECT_NE(st.message().find(reason), std::string::npos) << st.message();
    if (junk.size() >= kDracoPointCloudHeaderBytes) {
      const uint8_t header[] = {'D', 'R', 'A', 'C', 'O', 2, 3, 0, static_cast<uint8_t>(trial % 2),
                                0,   0,   100, 0,   0,   0};
      std::memcpy(junk.data(), header, sizeof header);
      expect_error_or_valid(junk, 100, "garbage behind a valid header, trial " + std::to_string(trial));
    }
  }
}

TEST(ChunkCodecReject, GivenFlippedBytesAtEveryOffsetThenErrorOrAValidDecode) {
  const Cloud c = random_cloud(200, 1.5, 0.0, 12);
  for (const Layout& layout : kLayouts) {
    ChunkCodecConfig cfg = config_for(layout);
    cfg.with_point_ids = true;
    const std::vector<uint8_t> bytes = encode_or_die(c, cfg);
    int rejected = 0;
    for (size_t off = 0; off < bytes.size(); ++off) {
      for (uint8_t mask : {uint8_t{0x01}, uint8_t{0xff}}) {
        std::vector<uint8_t> bad = bytes;
        bad[off] ^= mask;
        const bool was_rejected = expect_error_or_valid(
            bad, 200, "offset " + std::to_string(off) + " mask " + std::to_string(mask));
        rejected += was_rejected;
        // Every header field is checked.
        if (off < kDracoPointCloudHeaderBytes) {
          EXPECT_TRUE(was_rejected) << "header byte " << off << " ^ " << int{mask} << " was accepted";
        }
      }
    }
    // Draco carries no checksum: many payload flips decode to a different, valid cloud. The link's
    // CRC32 is what catches those; the codec only guarantees no crash and a well-formed result.
    std::printf("[ flips ] %s: %zu offsets x 2 masks, %d rejected, %d decoded to a valid cloud\n",
                layout.name, bytes.size(), rejected, static_cast<int>(2 * bytes.size()) - rejected);
  }
}

std::vector<uint8_t> with_point_count(std::vector<uint8_t> bytes, int32_t n) {
  std::memcpy(bytes.data() + 11, &n, sizeof n);  // little-endian hosts, as Draco itself
  return bytes;
}

TEST(ChunkCodecReject, GivenAHeaderClaimingABillionPointsThenRejectedWithoutAllocating) {
  const Cloud c = random_cloud(1000, 2.0, 0.0, 13);
  for (const Layout& layout : kLayouts) {
    const ChunkCodecConfig cfg = config_for(layout);
    const std::vector<uint8_t> forged = with_point_count(encode_or_die(c, cfg), 1000000000);
    DecodedChunk out;
    out.points.reserve(1000);  // the output's own storage is not what we measure
    core::AllocationScope scope;
    const core::Status st = decode_chunk(forged.data(), forged.size(), -1, ChunkDecodeLimits{}, &out);
    const uint64_t bytes_allocated = scope.bytes();
    EXPECT_EQ(st.code(), core::ErrorCode::kOutOfRange) << st.to_string();
    EXPECT_NE(st.message().find("1000000000"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find("before decoding"), std::string::npos) << st.message();
    EXPECT_LT(bytes_allocated, 4096u) << "only the error message may be allocated";
  }
  // A tight limit is enforced on an honest chunk the same way.
  const std::vector<uint8_t> honest = encode_or_die(c, ChunkCodecConfig{});
  ChunkDecodeLimits tight;
  tight.max_points = 999;
  DecodedChunk out;
  const core::Status st = decode_chunk(honest.data(), honest.size(), -1, tight, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(st.message().find("claims 1000 points, over the limit of 999"), std::string::npos)
      << st.message();
  tight.max_points = 1000;
  EXPECT_TRUE(decode_chunk(honest.data(), honest.size(), -1, tight, &out).ok());
  // Negative and zero counts.
  EXPECT_EQ(
      decode_chunk(with_point_count(honest, -5).data(), honest.size(), -1, ChunkDecodeLimits{}, &out).code(),
      core::ErrorCode::kCorruptData);
  const core::Status zero =
      decode_chunk(with_point_count(honest, 0).data(), honest.size(), -1, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(zero.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(zero.message().find("0 points"), std::string::npos) << zero.message();
  // A count that disagrees with the attributes that follow fails in Draco or in the count check, never
  // yields a cloud of the wrong size.
  expect_error_or_valid(with_point_count(honest, 1001), 1001, "count 1001 over 1000 encoded points");
  expect_error_or_valid(with_point_count(honest, 999), 999, "count 999 over 1000 encoded points");
}

TEST(ChunkCodecReject, GivenAPointCountMismatchOrOversizeThenRejected) {
  const Cloud c = random_cloud(100, 1.0, 0.0, 14);
  const std::vector<uint8_t> bytes = encode_or_die(c, ChunkCodecConfig{});
  DecodedChunk out;
  const core::Status mismatch = decode_chunk(bytes.data(), bytes.size(), 99, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(mismatch.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(mismatch.message().find("claims 100 points but the chunk message says 99"), std::string::npos)
      << mismatch.message();
  EXPECT_EQ(decode_chunk(bytes.data(), bytes.size(), -2, ChunkDecodeLimits{}, &out).code(),
            core::ErrorCode::kInvalidArgument);
  ChunkDecodeLimits small;
  small.max_payload_bytes = bytes.size() - 1;
  const core::Status oversize = decode_chunk(bytes.data(), bytes.size(), 100, small, &out);
  EXPECT_EQ(oversize.code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(oversize.message().find("over the"), std::string::npos) << oversize.message();
}

TEST(DracoPrefix, GivenEveryShapeTheCodecWritesThenThePrefixParsesToIt) {
  const Cloud c = random_cloud(64, 1.0, 0.0, 20);
  const std::vector<float> normals(3 * 64, 0.57735f);
  for (int variant = 0; variant < 8; ++variant) {
    SCOPED_TRACE("variant " + std::to_string(variant));
    ChunkCodecConfig cfg;
    cfg.preserve_order = (variant & 1) != 0;
    cfg.with_point_ids = (variant & 2) != 0;
    const bool with_normals = (variant & 4) != 0;
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(encode_chunk(c.points.data(), 64, cfg.with_point_ids ? c.ids.data() : nullptr,
                             with_normals ? normals.data() : nullptr, cfg, &bytes)
                    .ok());
    auto prefix = parse_draco_point_cloud_prefix(bytes.data(), bytes.size());
    ASSERT_TRUE(prefix.ok()) << prefix.status().to_string();
    EXPECT_EQ(prefix->header.version_major, 2);
    EXPECT_EQ(prefix->header.version_minor, 3);
    EXPECT_EQ(prefix->header.method,
              cfg.preserve_order ? DracoPointCloudMethod::kSequential : DracoPointCloudMethod::kKdTree);
    EXPECT_EQ(prefix->header.flags, 0);
    EXPECT_EQ(prefix->header.num_points, 64);
    EXPECT_EQ(prefix->num_attributes, 3 + int{cfg.with_point_ids} + int{with_normals});
    // Position first: float32 (Draco data type 9) x3, unique id 0.
    EXPECT_EQ(prefix->attributes[0].attribute_type, 0);
    EXPECT_EQ(prefix->attributes[0].data_type, 9);
    EXPECT_EQ(prefix->attributes[0].num_components, 3);
    EXPECT_EQ(prefix->attributes[0].unique_id, 0u);
    if (!cfg.preserve_order) {
      EXPECT_EQ(prefix->kd_tree_compression_level, 6);  // speed 4 (chunk_codec.hpp)
      EXPECT_LE(prefix->kd_tree_bit_length, 32u);
    }
  }
}

TEST(ChunkCodecReject, GivenHeaderFieldsOutsideWhatTheCodecWritesThenNamedInTheError) {
  const Cloud c = random_cloud(20, 1.0, 0.0, 15);
  const std::vector<uint8_t> good = encode_or_die(c, ChunkCodecConfig{});
  // Kd-tree chunk without ids: header (15), 1 decoder (1), 3 attributes (1 + 3 x 5), compression
  // level (1), bit length (4), kd-tree point count (4).
  ASSERT_GT(good.size(), 41u);
  struct Patch {
    size_t offset;
    uint8_t value;
    const char* expect_in_message;
  };
  const Patch patches[] = {
      {0, 'X', "DRACO"},
      {5, 1, "version 1.3"},
      {6, 2, "version 2.2"},
      {7, 1, "mesh"},
      {8, 2, "method 2"},
      {10, 0x80, "flags 0x8000"},
      {15, 2, "2 attributes"},
      {16, 9, "9 attributes"},
      {17, 7, "unknown type 7"},
      {18, 0, "data type 0"},
      {19, 0, "0 components"},
      {19, 4, "position attribute"},
      {21, 9, "unique id 9"},
      {21, 1, "colour attribute"},
      {32, 7, "compression level 7"},
      {33, 33, "bit length"},
      {37, 21, "kd-tree coder claims 21 points, the header 20"},
  };
  for (const Patch& p : patches) {
    std::vector<uint8_t> bad = good;
    bad[p.offset] = p.value;
    DecodedChunk out;
    const core::Status st = decode_chunk(bad.data(), bad.size(), -1, ChunkDecodeLimits{}, &out);
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << "offset " << p.offset;
    EXPECT_NE(st.message().find(p.expect_in_message), std::string::npos) << st.message();
  }
}

TEST(ChunkCodecReject, GivenTheFuzzersSlowUnitThenRejectedBeforeDraco) {
  // Found by fuzz_chunk_decoder (90 bytes): a 1-point kd-tree chunk whose kd-tree coder claims
  // 4294967286 points; Draco 1.5.5 loops over that count before comparing it with the header's
  // (4 s in a release build). The prefix check rejects it without calling Draco.
  const uint8_t slow_unit[] = {0x44, 0x52, 0x41, 0x43, 0x4f, 0x02, 0x03, 0x00, 0x01, 0x00, 0x00, 0x01, 0x00,
                               0x00, 0x00, 0x01, 0x03, 0x00, 0x09, 0x03, 0x00, 0x00, 0x02, 0x02, 0x13, 0x00,
                               0x01, 0x04, 0x02, 0x01, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf6, 0xff,
                               0xff, 0xff, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00,
                               0x00, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
                               0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1f, 0xee, 0xd8, 0xbf, 0x36,
                               0x9a, 0x8b, 0xbf, 0x84, 0x51, 0x8f, 0x3f, 0x00, 0x00, 0x80, 0x3f, 0x01};
  DecodedChunk out;
  const core::Status st = decode_chunk(slow_unit, sizeof slow_unit, -1, ChunkDecodeLimits{}, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(st.message().find("kd-tree coder claims 4294967286 points"), std::string::npos) << st.message();
}

TEST(ChunkCodecEncode, GivenBadInputsThenInvalidArgumentOrOutOfRange) {
  Cloud c = random_cloud(10, 1.0, 0.0, 16);
  std::vector<uint8_t> out(7, 0);
  const ChunkCodecConfig cfg;
  EXPECT_EQ(encode_chunk(c.points.data(), 0, nullptr, nullptr, cfg, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_TRUE(out.empty()) << "the output is cleared even on error";
  EXPECT_EQ(encode_chunk(nullptr, 10, nullptr, nullptr, cfg, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(encode_chunk(c.points.data(), 10, nullptr, nullptr, cfg, nullptr).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(encode_chunk(c.points.data(), 10, c.ids.data(), nullptr, cfg, &out).status().code(),
            core::ErrorCode::kInvalidArgument);  // ids without with_point_ids
  ChunkCodecConfig bad = cfg;
  bad.with_point_ids = true;
  EXPECT_EQ(encode_chunk(c.points.data(), 10, nullptr, nullptr, bad, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
  bad = cfg;
  bad.speed = 11;
  EXPECT_EQ(encode_chunk(c.points.data(), 10, nullptr, nullptr, bad, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
  bad = cfg;
  bad.max_position_error_m = 0.0;
  EXPECT_EQ(encode_chunk(c.points.data(), 10, nullptr, nullptr, bad, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
  c.points[3].y_m = std::numeric_limits<float>::quiet_NaN();
  const auto nan = encode_chunk(c.points.data(), 10, nullptr, nullptr, cfg, &out);
  EXPECT_EQ(nan.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(nan.status().message().find("point 3"), std::string::npos) << nan.status().message();
  // 40 km across at 1 mm: float32 cannot hold the bound that far out; the error says what to do.
  c.points[3].y_m = 40000.0f;
  const auto huge = encode_chunk(c.points.data(), 10, nullptr, nullptr, cfg, &out);
  EXPECT_EQ(huge.status().code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(huge.status().message().find("local frame"), std::string::npos) << huge.status().message();
  // The same chunk at 1 m error encodes.
  bad = cfg;
  bad.max_position_error_m = 1.0;
  EXPECT_TRUE(encode_chunk(c.points.data(), 10, nullptr, nullptr, bad, &out).ok());
  // A payload over the chunk limit is refused so the caller splits it.
  const Cloud big = random_cloud(20000, 10.0, 0.0, 17);
  bad = cfg;
  bad.max_payload_bytes = 1000;
  const auto over = encode_chunk(big.points.data(), 20000, nullptr, nullptr, bad, &out);
  EXPECT_EQ(over.status().code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(over.status().message().find("split"), std::string::npos) << over.status().message();
}

TEST(ChunkCodecEncode, GivenAReusedOutputBufferThenItsCapacityIsKept) {
  const Cloud c = random_cloud(5000, 3.0, 0.0, 18);
  std::vector<uint8_t> out;
  ASSERT_TRUE(encode_chunk(c.points.data(), 5000, nullptr, nullptr, ChunkCodecConfig{}, &out).ok());
  const size_t capacity = out.capacity();
  const uint8_t* storage = out.data();
  ASSERT_TRUE(encode_chunk(c.points.data(), 2000, nullptr, nullptr, ChunkCodecConfig{}, &out).ok());
  EXPECT_EQ(out.capacity(), capacity);
  EXPECT_EQ(out.data(), storage);
}

// ---- interop with Debian's stock draco_decoder ----------------------------------------------------

std::string find_tool(const char* name) {
  for (const char* dir : {"/usr/bin/", "/usr/local/bin/"}) {
    const std::string path = std::string(dir) + name;
    if (::access(path.c_str(), X_OK) == 0) return path;
  }
  return {};
}

// Stock draco_decoder reads every layout: all points, with colour in the single layouts.
TEST(ChunkCodecInterop, GivenAChunkOnDiskThenDracoDecoderWritesAPlyWithEveryPoint) {
  const std::string tool = find_tool("draco_decoder");
  if (tool.empty())
    GTEST_SKIP() << "draco_decoder not installed (Debian package 'draco'); interop not checked";
  char dir_template[] = "/tmp/hwr_chunk_codec_XXXXXX";
  const char* dir = ::mkdtemp(dir_template);
  ASSERT_NE(dir, nullptr);
  const Cloud c = random_cloud(1234, 5.0, 0.0, 19);
  for (const Layout& layout : kLayouts) {
    SCOPED_TRACE(layout.name);
    ChunkCodecConfig cfg = config_for(layout);
    cfg.with_point_ids = true;
    const std::vector<uint8_t> bytes = encode_or_die(c, cfg);
    const std::string drc = std::string(dir) + "/chunk.drc";
    const std::string ply = std::string(dir) + "/chunk.ply";
    {
      std::ofstream f(drc, std::ios::binary);
      f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
      ASSERT_TRUE(f.good());
    }
    const std::string cmd = tool + " -i " + drc + " -o " + ply + " > " + dir + "/log.txt 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(ply, std::ios::binary);
    std::string line;
    long vertices = -1;
    bool has_red = false;
    while (std::getline(in, line) && line != "end_header") {
      if (line.rfind("element vertex ", 0) == 0) vertices = std::stol(line.substr(15));
      if (line.find("property uchar red") != std::string::npos) has_red = true;
    }
    EXPECT_EQ(line, "end_header");
    EXPECT_EQ(vertices, 1234);
    // The split layout's first cloud is the positions alone; stock tools stop there.
    EXPECT_EQ(has_red, layout.color_bits == 8) << "the single layouts' PLY carries the colour";
    std::remove(drc.c_str());
    std::remove(ply.c_str());
  }
  std::remove((std::string(dir) + "/log.txt").c_str());
  ::rmdir(dir);
}

}  // namespace
}  // namespace hwr::mapio
