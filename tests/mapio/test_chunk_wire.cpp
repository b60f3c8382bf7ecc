// Wire rules of map chunks and acks (mapio/chunk_wire.hpp): the CRC32s against an independent
// bitwise implementation of the documented canonical forms, verify_chunk's and verify_ack's
// rejections, and LCM decoding of truncated, garbage and hostile-length buffers.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hwr/mapio/chunk_wire.hpp"

namespace hwr::mapio {
namespace {

// --- Oracle: bitwise CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320) over the canonical form
// written out field by field as chunk_wire.hpp documents it.
uint32_t reference_crc32(const std::vector<uint8_t>& bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (uint8_t b : bytes) {
    crc ^= b;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return crc ^ 0xFFFFFFFFu;
}

template <class T>
void put_le(std::vector<uint8_t>* out, T v) {
  uint8_t raw[sizeof(T)];
  std::memcpy(raw, &v, sizeof(T));  // the test host is little-endian (x86-64, aarch64)
  out->insert(out->end(), raw, raw + sizeof(T));
}

std::vector<uint8_t> canonical_bytes(const hwr_lcm::map_chunk_t& c) {
  std::vector<uint8_t> b;
  put_le<uint32_t>(&b, static_cast<uint32_t>(c.robot_id.size()));
  b.insert(b.end(), c.robot_id.begin(), c.robot_id.end());
  put_le(&b, c.run_id);
  put_le(&b, c.link_seq);
  put_le(&b, c.segment_id);
  put_le(&b, c.segment_version);
  put_le(&b, c.chunk_index);
  put_le(&b, c.segment_complete);
  put_le(&b, c.chunk_count);
  for (double v : c.T_world_segment) put_le(&b, v);
  put_le(&b, c.num_points);
  put_le(&b, c.has_normals);
  put_le(&b, c.max_position_error_m);
  put_le(&b, c.payload_size);
  b.insert(b.end(), c.payload.begin(), c.payload.end());
  return b;
}

hwr_lcm::map_chunk_t make_chunk(size_t payload_bytes = 1000, uint64_t seed = 7) {
  hwr_lcm::map_chunk_t c;
  c.t_ns = 123456789;
  c.robot_id = "hwr-0";
  c.run_id = 1732477000000000000;
  c.link_seq = 41;
  c.segment_id = 3;
  c.segment_version = 1;
  c.chunk_index = 5;
  c.segment_complete = 0;
  c.chunk_count = 6;
  // R = rotation about (1, 2, 3)/|.| by 0.7 rad (Rodrigues), t = (1.5, -2, 0.25) m.
  const double ax[3] = {1 / std::sqrt(14.0), 2 / std::sqrt(14.0), 3 / std::sqrt(14.0)};
  const double th = 0.7, cs = std::cos(th), sn = std::sin(th);
  const double K[3][3] = {{0, -ax[2], ax[1]}, {ax[2], 0, -ax[0]}, {-ax[1], ax[0], 0}};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) {
      double kk = 0;
      for (int m = 0; m < 3; ++m) kk += K[r][m] * K[m][k];
      c.T_world_segment[4 * r + k] = (r == k ? 1.0 : 0.0) + sn * K[r][k] + (1 - cs) * kk;
    }
  }
  c.T_world_segment[3] = 1.5;
  c.T_world_segment[7] = -2.0;
  c.T_world_segment[11] = 0.25;
  c.num_points = 250;
  c.has_normals = 1;
  c.max_position_error_m = 0.001f;
  std::mt19937_64 rng(seed);
  c.payload.resize(payload_bytes);
  for (auto& b : c.payload) b = static_cast<uint8_t>(rng());
  seal_chunk(&c);
  return c;
}

std::vector<uint8_t> encode(const hwr_lcm::map_chunk_t& c) {
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(encode_chunk_message(c, &bytes).ok());
  return bytes;
}

void put_be32(std::vector<uint8_t>* b, size_t at, int32_t v) {
  const auto u = static_cast<uint32_t>(v);
  for (int i = 0; i < 4; ++i) (*b)[at + i] = static_cast<uint8_t>(u >> (24 - 8 * i));
}
int32_t get_be32(const std::vector<uint8_t>& b, size_t at) {
  uint32_t u = 0;
  for (int i = 0; i < 4; ++i) u = (u << 8) | b[at + i];
  return static_cast<int32_t>(u);
}
// Offsets in the LCM encoding: fingerprint 8, t_ns 8, robot_id (4 + len + 1), then 138 bytes of
// fixed fields up to payload_size.
size_t robot_id_len_offset() { return 16; }
size_t payload_size_offset(const hwr_lcm::map_chunk_t& c) { return 16 + 4 + c.robot_id.size() + 1 + 138; }

TEST(ChunkCrc, ReferenceImplementationKnownVector) {
  const std::string s = "123456789";
  EXPECT_EQ(reference_crc32(std::vector<uint8_t>(s.begin(), s.end())), 0xCBF43926u);
}

TEST(ChunkCrc, MatchesIndependentCanonicalForm) {
  for (size_t n : {size_t{1}, size_t{17}, size_t{1000}, size_t{300 * 1024}}) {
    const auto c = make_chunk(n, n);
    EXPECT_EQ(chunk_crc32(c), reference_crc32(canonical_bytes(c))) << "payload " << n;
    EXPECT_EQ(c.crc32, static_cast<int64_t>(chunk_crc32(c)));
    EXPECT_EQ(c.payload_size, static_cast<int32_t>(n));
  }
}

TEST(ChunkCrc, ChangesOnEveryFlippedHeaderFieldAndPayloadByte) {
  const auto base = make_chunk(1000);
  const uint32_t crc0 = chunk_crc32(base);
  ASSERT_TRUE(verify_chunk(base, ChunkWireLimits{}).ok());
  std::vector<std::pair<std::string, std::function<void(hwr_lcm::map_chunk_t&)>>> flips = {
      {"robot_id", [](auto& c) { c.robot_id[2] ^= 0x01; }},
      {"robot_id length", [](auto& c) { c.robot_id += "x"; }},
      {"run_id", [](auto& c) { c.run_id ^= int64_t{1} << 40; }},
      {"link_seq", [](auto& c) { c.link_seq ^= 1; }},
      {"segment_id", [](auto& c) { c.segment_id ^= 1; }},
      {"segment_version", [](auto& c) { c.segment_version ^= 1; }},
      {"chunk_index", [](auto& c) { c.chunk_index ^= 1; }},
      {"segment_complete", [](auto& c) { c.segment_complete ^= 1; }},
      {"chunk_count", [](auto& c) { c.chunk_count ^= 1; }},
      {"num_points", [](auto& c) { c.num_points ^= 1; }},
      {"has_normals", [](auto& c) { c.has_normals ^= 1; }},
      {"max_position_error_m",
       [](auto& c) { c.max_position_error_m = std::nextafter(c.max_position_error_m, 1.f); }},
  };
  for (int i = 0; i < 12; ++i) {
    flips.push_back({"T_world_segment[" + std::to_string(i) + "]", [i](auto& c) {
                       uint64_t bits;
                       std::memcpy(&bits, &c.T_world_segment[i], 8);
                       bits ^= 1;  // the last mantissa bit
                       std::memcpy(&c.T_world_segment[i], &bits, 8);
                     }});
  }
  for (const auto& [name, flip] : flips) {
    auto c = base;
    flip(c);
    EXPECT_NE(chunk_crc32(c), crc0) << name;
    EXPECT_EQ(chunk_crc32(c), reference_crc32(canonical_bytes(c))) << name;
    const core::Status st = verify_chunk(c, ChunkWireLimits{});
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << name << ": " << st.to_string();
    EXPECT_NE(st.message().find("CRC32 mismatch"), std::string::npos) << name << ": " << st.to_string();
  }
  for (size_t i = 0; i < base.payload.size(); ++i) {
    auto c = base;
    c.payload[i] ^= static_cast<uint8_t>(1u << (i % 8));
    ASSERT_NE(chunk_crc32(c), crc0) << "payload byte " << i;
    ASSERT_EQ(verify_chunk(c, ChunkWireLimits{}).code(), core::ErrorCode::kCorruptData) << i;
  }
  // t_ns is outside the CRC by design (resends are restamped).
  auto c = base;
  c.t_ns += 1000;
  EXPECT_EQ(chunk_crc32(c), crc0);
}

struct BadCase {
  std::string name;
  std::function<void(hwr_lcm::map_chunk_t&)> mutate;
  bool reseal;
  core::ErrorCode code;
  std::string message;
};

TEST(VerifyChunk, RejectsEachMalformedCaseWithItsReason) {
  ChunkWireLimits limits;
  limits.max_payload_bytes = 2000;
  limits.max_points = 10000;
  const auto set_rot = [](hwr_lcm::map_chunk_t& c, int i, double v) { c.T_world_segment[i] = v; };
  const std::vector<BadCase> cases = {
      {"payload_size mismatch", [](auto& c) { c.payload_size += 1; }, false, core::ErrorCode::kCorruptData,
       "payload_size 1001 but 1000 payload bytes"},
      {"crc not 32-bit", [](auto& c) { c.crc32 = -5; }, false, core::ErrorCode::kCorruptData, "not a 32-bit"},
      {"crc wrong", [](auto& c) { c.crc32 ^= 0x10; }, false, core::ErrorCode::kCorruptData, "CRC32 mismatch"},
      {"empty robot_id", [](auto& c) { c.robot_id.clear(); }, true, core::ErrorCode::kOutOfRange,
       "robot_id is empty"},
      {"long robot_id", [](auto& c) { c.robot_id.assign(65, 'r'); }, true, core::ErrorCode::kOutOfRange,
       "robot_id has 65 bytes"},
      {"negative run_id", [](auto& c) { c.run_id = -1; }, true, core::ErrorCode::kOutOfRange, "negative id"},
      {"negative link_seq", [](auto& c) { c.link_seq = -1; }, true, core::ErrorCode::kOutOfRange,
       "negative id"},
      {"negative segment_id", [](auto& c) { c.segment_id = -2; }, true, core::ErrorCode::kOutOfRange,
       "negative id"},
      {"negative version", [](auto& c) { c.segment_version = -1; }, true, core::ErrorCode::kOutOfRange,
       "negative id"},
      {"negative chunk_index", [](auto& c) { c.chunk_index = -1; }, true, core::ErrorCode::kOutOfRange,
       "negative id"},
      {"negative chunk_count", [](auto& c) { c.chunk_count = -1; }, true, core::ErrorCode::kOutOfRange,
       "negative id"},
      {"empty payload", [](auto& c) { c.payload.clear(); }, true, core::ErrorCode::kOutOfRange,
       "payload of 0 bytes"},
      {"payload over limit", [](auto& c) { c.payload.resize(2001); }, true, core::ErrorCode::kOutOfRange,
       "payload of 2001 bytes, allowed 1..2000"},
      {"zero points", [](auto& c) { c.num_points = 0; }, true, core::ErrorCode::kOutOfRange, "num_points 0"},
      {"zero points, no payload, not completing",
       [](auto& c) {
         c.num_points = 0;
         c.payload.clear();
         c.segment_complete = 0;
       },
       true, core::ErrorCode::kOutOfRange, "payload of 0 bytes"},
      {"zero points, completing, but with a payload",
       [](auto& c) {
         c.num_points = 0;
         c.segment_complete = 1;
         c.chunk_index = 0;
         c.chunk_count = 1;
       },
       true, core::ErrorCode::kOutOfRange, "num_points 0"},
      {"too many points", [](auto& c) { c.num_points = 10001; }, true, core::ErrorCode::kOutOfRange,
       "num_points 10001, allowed 1..10000"},
      {"segment_complete 2", [](auto& c) { c.segment_complete = 2; }, true, core::ErrorCode::kInvalidArgument,
       "must be 0 or 1"},
      {"has_normals -1", [](auto& c) { c.has_normals = -1; }, true, core::ErrorCode::kInvalidArgument,
       "must be 0 or 1"},
      {"complete, index == count",
       [](auto& c) {
         c.segment_complete = 1;
         c.chunk_index = c.chunk_count;
       },
       true, core::ErrorCode::kInvalidArgument, "chunk_index 6 >= chunk_count 6"},
      {"error NaN", [](auto& c) { c.max_position_error_m = std::nanf(""); }, true,
       core::ErrorCode::kInvalidArgument, "max_position_error_m"},
      {"error negative", [](auto& c) { c.max_position_error_m = -0.001f; }, true,
       core::ErrorCode::kInvalidArgument, "max_position_error_m"},
      {"T NaN", [&](auto& c) { set_rot(c, 5, std::nan("")); }, true, core::ErrorCode::kInvalidArgument,
       "T_world_segment[5] is not finite"},
      {"t infinite", [&](auto& c) { set_rot(c, 7, std::numeric_limits<double>::infinity()); }, true,
       core::ErrorCode::kInvalidArgument, "T_world_segment[7] is not finite"},
      {"R scaled",
       [](auto& c) {
         for (int r = 0; r < 3; ++r)
           for (int k = 0; k < 3; ++k) c.T_world_segment[4 * r + k] *= 1.001;
       },
       true, core::ErrorCode::kInvalidArgument, "not a rotation"},
      {"R reflection (det -1)",
       [](auto& c) {
         for (int r = 0; r < 3; ++r) c.T_world_segment[4 * r + 0] *= -1;
       },
       true, core::ErrorCode::kInvalidArgument, "det R = -1"},
      {"R off by 3e-6", [](auto& c) { c.T_world_segment[1] += 3e-6; }, true,
       core::ErrorCode::kInvalidArgument, "not a rotation"},
  };
  for (const auto& bc : cases) {
    auto c = make_chunk(1000);
    bc.mutate(c);
    if (bc.reseal) seal_chunk(&c);  // a sealed but wrong chunk
    const core::Status st = verify_chunk(c, limits);
    EXPECT_EQ(st.code(), bc.code) << bc.name << ": " << st.to_string();
    EXPECT_NE(st.message().find(bc.message), std::string::npos)
        << bc.name << ": expected '" << bc.message << "' in: " << st.to_string();
  }
}

TEST(VerifyChunk, AcceptsValidEdgeCases) {
  ChunkWireLimits limits;
  auto c = make_chunk(1000);
  EXPECT_TRUE(verify_chunk(c, limits).ok()) << verify_chunk(c, limits).to_string();
  c.segment_complete = 1;
  c.chunk_index = c.chunk_count - 1;  // the last chunk of a closed segment
  seal_chunk(&c);
  EXPECT_TRUE(verify_chunk(c, limits).ok()) << verify_chunk(c, limits).to_string();
  c.T_world_segment[1] += 1e-8;  // rounding noise well inside the 1e-6 tolerance
  c.num_points = limits.max_points;
  c.robot_id.assign(64, 'r');
  seal_chunk(&c);
  EXPECT_TRUE(verify_chunk(c, limits).ok()) << verify_chunk(c, limits).to_string();
  // A segment's empty completing chunk: nothing was left to send when it closed.
  c.num_points = 0;
  c.payload.clear();
  seal_chunk(&c);
  EXPECT_TRUE(verify_chunk(c, limits).ok()) << verify_chunk(c, limits).to_string();
  const auto bytes = encode(c);
  hwr_lcm::map_chunk_t d;
  ASSERT_TRUE(decode_chunk_message(bytes.data(), bytes.size(), &d).ok());
  EXPECT_TRUE(verify_chunk(d, limits).ok());
}

TEST(DecodeChunkMessage, RoundTripIsExact) {
  const auto c = make_chunk(5000);
  const auto bytes = encode(c);
  hwr_lcm::map_chunk_t d;
  ASSERT_TRUE(decode_chunk_message(bytes.data(), bytes.size(), &d).ok());
  EXPECT_EQ(d.t_ns, c.t_ns);
  EXPECT_EQ(d.robot_id, c.robot_id);
  EXPECT_EQ(d.link_seq, c.link_seq);
  EXPECT_EQ(d.payload, c.payload);
  EXPECT_EQ(0, std::memcmp(d.T_world_segment, c.T_world_segment, sizeof c.T_world_segment));
  EXPECT_EQ(d.crc32, c.crc32);
  EXPECT_TRUE(verify_chunk(d, ChunkWireLimits{}).ok());
  EXPECT_EQ(encode(d), bytes);
}

TEST(DecodeChunkMessage, ReusedOutputLosesStalePayload) {
  // LCM's decode() skips a zero-length array and would leave the previous payload in place.
  auto empty = make_chunk(1000);
  empty.payload.clear();
  seal_chunk(&empty);
  const auto bytes = encode(empty);
  hwr_lcm::map_chunk_t d = make_chunk(3000);
  ASSERT_TRUE(decode_chunk_message(bytes.data(), bytes.size(), &d).ok());
  EXPECT_TRUE(d.payload.empty());
  EXPECT_EQ(verify_chunk(d, ChunkWireLimits{}).code(), core::ErrorCode::kOutOfRange);
}

TEST(DecodeChunkMessage, EveryTruncationFailsCleanly) {
  const auto bytes = encode(make_chunk(200));
  hwr_lcm::map_chunk_t d;
  for (size_t n = 0; n < bytes.size(); ++n) {
    const core::Status st = decode_chunk_message(bytes.data(), n, &d);
    ASSERT_FALSE(st.ok()) << "truncated to " << n;
    ASSERT_EQ(st.code(), core::ErrorCode::kParseError) << n << ": " << st.to_string();
  }
  auto longer = bytes;
  longer.push_back(0);
  const core::Status st = decode_chunk_message(longer.data(), longer.size(), &d);
  EXPECT_NE(st.message().find("unexpected bytes after the end"), std::string::npos) << st.to_string();
}

TEST(DecodeChunkMessage, GarbageFailsCleanly) {
  std::mt19937_64 rng(11);
  hwr_lcm::map_chunk_t d;
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> junk(rng() % 600);
    for (auto& b : junk) b = static_cast<uint8_t>(rng());
    EXPECT_FALSE(decode_chunk_message(junk.data(), junk.size(), &d).ok());
  }
  // Right fingerprint, random rest: must fail or decode to something verify_chunk judges.
  const auto good = encode(make_chunk(100));
  int decoded = 0;
  for (int i = 0; i < 2000; ++i) {
    auto b = good;
    for (size_t k = 8; k < b.size(); ++k) {
      if (rng() % 16 == 0) b[k] = static_cast<uint8_t>(rng());
    }
    if (decode_chunk_message(b.data(), b.size(), &d).ok()) {
      ++decoded;
      (void)verify_chunk(d, ChunkWireLimits{});
    }
  }
  EXPECT_LT(decoded, 2000);
}

TEST(DecodeChunkMessage, HostileLengthsRejectedBeforeAllocation) {
  const auto c = make_chunk(100);
  const auto good = encode(c);
  const size_t ps = payload_size_offset(c);
  ASSERT_EQ(get_be32(good, ps), 100);  // the offset arithmetic is right
  ASSERT_EQ(get_be32(good, robot_id_len_offset()), static_cast<int32_t>(c.robot_id.size() + 1));
  struct Case {
    size_t at;
    int32_t value;
    core::ErrorCode code;
    std::string message;
  };
  const std::vector<Case> cases = {
      {ps, std::numeric_limits<int32_t>::max(), core::ErrorCode::kOutOfRange, "payload_size 2147483647"},
      {ps, -1, core::ErrorCode::kOutOfRange, "payload_size -1"},
      {ps, 101, core::ErrorCode::kParseError, "truncated at crc32"},
      {ps, 200, core::ErrorCode::kParseError, "truncated at payload"},
      {ps, 99, core::ErrorCode::kParseError, "unexpected bytes"},
      {robot_id_len_offset(), 0, core::ErrorCode::kParseError, "robot_id length 0"},
      {robot_id_len_offset(), -7, core::ErrorCode::kParseError, "robot_id length -7"},
      {robot_id_len_offset(), std::numeric_limits<int32_t>::max(), core::ErrorCode::kOutOfRange,
       "robot_id claims"},
      {robot_id_len_offset(), 5, core::ErrorCode::kParseError, "not NUL-terminated"},
  };
  for (const auto& k : cases) {
    auto b = good;
    put_be32(&b, k.at, k.value);
    hwr_lcm::map_chunk_t d;
    const core::Status st = decode_chunk_message(b.data(), b.size(), &d);
    EXPECT_EQ(st.code(), k.code) << k.message << ": " << st.to_string();
    EXPECT_NE(st.message().find(k.message), std::string::npos) << st.to_string();
    EXPECT_EQ(d.payload.capacity(), 0u) << k.message << ": allocated for a rejected message";
  }
  auto b = good;
  b[robot_id_len_offset() + 4 + 1] = 0;  // a NUL inside "hwr-0"
  hwr_lcm::map_chunk_t d;
  EXPECT_NE(decode_chunk_message(b.data(), b.size(), &d).message().find("contains a NUL"), std::string::npos);
  b = good;
  b[0] ^= 1;
  EXPECT_NE(decode_chunk_message(b.data(), b.size(), &d).message().find("not a map_chunk_t"),
            std::string::npos);
  ChunkWireLimits tight;
  tight.max_message_bytes = good.size() - 1;
  EXPECT_EQ(decode_chunk_message(good.data(), good.size(), &d, tight).code(), core::ErrorCode::kOutOfRange);
  tight = ChunkWireLimits{};
  tight.max_payload_bytes = 99;
  EXPECT_EQ(decode_chunk_message(good.data(), good.size(), &d, tight).code(), core::ErrorCode::kOutOfRange);
}

TEST(EncodeChunkMessage, RejectsInconsistentMessages) {
  auto c = make_chunk(100);
  std::vector<uint8_t> out;
  c.payload_size = 99;
  EXPECT_EQ(encode_chunk_message(c, &out).code(), core::ErrorCode::kInvalidArgument);
  c = make_chunk(100);
  c.robot_id = std::string("a\0b", 3);
  EXPECT_EQ(encode_chunk_message(c, &out).code(), core::ErrorCode::kInvalidArgument);
}

hwr_lcm::chunk_ack_t make_ack(std::vector<int64_t> selective) {
  hwr_lcm::chunk_ack_t a;
  a.t_ns = 5;
  a.robot_id = "hwr-0";
  a.run_id = 77;
  a.cumulative_seq = 10;
  a.selective = std::move(selective);
  a.resume_report = 0;
  seal_ack(&a);
  return a;
}

// The ack after a field was changed on purpose: sealed again, so verify_ack judges the field.
hwr_lcm::chunk_ack_t resealed(hwr_lcm::chunk_ack_t a) {
  seal_ack(&a);
  return a;
}

std::vector<uint8_t> canonical_bytes(const hwr_lcm::chunk_ack_t& a) {
  std::vector<uint8_t> b;
  put_le<uint32_t>(&b, static_cast<uint32_t>(a.robot_id.size()));
  b.insert(b.end(), a.robot_id.begin(), a.robot_id.end());
  put_le(&b, a.run_id);
  put_le(&b, a.cumulative_seq);
  put_le(&b, a.num_selective);
  for (int64_t v : a.selective) put_le(&b, v);
  put_le(&b, a.resume_report);
  return b;
}

TEST(AckCrc, HandWrittenCanonicalBytesOfASmallAck) {
  hwr_lcm::chunk_ack_t a;
  a.t_ns = 999;  // not covered
  a.robot_id = "r1";
  a.run_id = 0x0102030405060708;
  a.cumulative_seq = -1;
  a.selective = {0x1122};
  a.resume_report = 1;
  seal_ack(&a);
  EXPECT_EQ(a.num_selective, 1);
  // chunk_wire.hpp's canonical form, written out byte by byte (little-endian).
  const std::vector<uint8_t> bytes = {
      0x02, 0x00, 0x00, 0x00, 'r',  '1',               // robot_id
      0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // run_id
      0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,  // cumulative_seq -1
      0x01, 0x00, 0x00, 0x00,                          // num_selective
      0x22, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // selective[0]
      0x01,                                            // resume_report
  };
  EXPECT_EQ(canonical_bytes(a), bytes);  // the test's own writer agrees with the hand-written form
  EXPECT_EQ(ack_crc32(a), reference_crc32(bytes));
  EXPECT_EQ(a.crc32, static_cast<int64_t>(reference_crc32(bytes)));
  // t_ns is outside the CRC: a restamped ack still verifies.
  a.t_ns = 12345;
  EXPECT_TRUE(verify_ack(a, ChunkWireLimits{}).ok());
}

TEST(AckCrc, MatchesIndependentCanonicalFormAcrossSizes) {
  // Sizes around the 160-byte buffer the implementation feeds selective values through.
  for (size_t n : {size_t{0}, size_t{1}, size_t{17}, size_t{18}, size_t{19}, size_t{40}, size_t{4096}}) {
    std::vector<int64_t> sel(n);
    for (size_t i = 0; i < n; ++i) sel[i] = 11 + 3 * static_cast<int64_t>(i);
    const auto a = make_ack(sel);
    EXPECT_EQ(ack_crc32(a), reference_crc32(canonical_bytes(a))) << n;
    EXPECT_TRUE(verify_ack(a, ChunkWireLimits{}).ok()) << n;
  }
}

TEST(AckCrc, DamageIsCorruptData) {
  const auto good = make_ack({12, 13, 20});
  ASSERT_TRUE(verify_ack(good, ChunkWireLimits{}).ok());
  auto a = good;
  a.selective[1] = 14;  // still a valid-looking ack: only the CRC can tell
  core::Status st = verify_ack(a, ChunkWireLimits{});
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << st.to_string();
  EXPECT_NE(st.message().find("CRC"), std::string::npos) << st.to_string();
  a = good;
  a.robot_id[2] ^= 0x01;  // one bit of one robot_id byte: "hwr-0" -> "hws-0"
  st = verify_ack(a, ChunkWireLimits{});
  EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << st.to_string();
  EXPECT_NE(st.message().find("CRC"), std::string::npos) << st.to_string();
  for (auto field : {&hwr_lcm::chunk_ack_t::run_id, &hwr_lcm::chunk_ack_t::cumulative_seq}) {
    a = good;
    a.*field += 1;
    EXPECT_EQ(verify_ack(a, ChunkWireLimits{}).code(), core::ErrorCode::kCorruptData);
  }
  a = good;
  a.resume_report = 1;
  EXPECT_EQ(verify_ack(a, ChunkWireLimits{}).code(), core::ErrorCode::kCorruptData);
  a = good;
  a.crc32 ^= 1;
  EXPECT_EQ(verify_ack(a, ChunkWireLimits{}).code(), core::ErrorCode::kCorruptData);
  for (int64_t bad : {int64_t{-1}, int64_t{1} << 32}) {
    a = good;
    a.crc32 = bad;
    st = verify_ack(a, ChunkWireLimits{});
    EXPECT_EQ(st.code(), core::ErrorCode::kCorruptData) << bad;
    EXPECT_NE(st.message().find("not a 32-bit value"), std::string::npos) << st.to_string();
  }
}

TEST(AckCrc, SealedAckRoundTripsThroughLcmAndEveryFlippedBitIsCaught) {
  const auto a = make_ack({12, 13, 20});
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_ack_message(a, &bytes).ok());
  hwr_lcm::chunk_ack_t d;
  ASSERT_TRUE(decode_ack_message(bytes.data(), bytes.size(), &d).ok());
  EXPECT_EQ(d.crc32, a.crc32);
  EXPECT_TRUE(verify_ack(d, ChunkWireLimits{}).ok());
  // Every single-bit flip after t_ns (fingerprint 8 + t_ns 8) either fails to decode or to verify.
  int decoded_but_rejected = 0;
  for (size_t byte = 16; byte < bytes.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      auto b = bytes;
      b[byte] ^= static_cast<uint8_t>(1u << bit);
      if (!decode_ack_message(b.data(), b.size(), &d).ok()) continue;
      EXPECT_FALSE(verify_ack(d, ChunkWireLimits{}).ok()) << "byte " << byte << " bit " << bit;
      ++decoded_but_rejected;
    }
  }
  EXPECT_GT(decoded_but_rejected, 100);  // most flips decode fine: the CRC is what catches them
}

TEST(AckMessage, RoundTripTruncationAndHostileCount) {
  const auto a = make_ack({12, 13, 20});
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_ack_message(a, &bytes).ok());
  hwr_lcm::chunk_ack_t d = make_ack({1, 2, 3, 4, 5, 6, 7, 8, 9});
  ASSERT_TRUE(decode_ack_message(bytes.data(), bytes.size(), &d).ok());
  EXPECT_EQ(d.selective, a.selective);
  EXPECT_EQ(d.cumulative_seq, 10);
  EXPECT_TRUE(verify_ack(d, ChunkWireLimits{}).ok());
  for (size_t n = 0; n < bytes.size(); ++n) {
    ASSERT_EQ(decode_ack_message(bytes.data(), n, &d).code(), core::ErrorCode::kParseError) << n;
  }
  // num_selective sits after fingerprint, t_ns, robot_id, run_id, cumulative_seq.
  const size_t ns = 16 + 4 + a.robot_id.size() + 1 + 16;
  ASSERT_EQ(get_be32(bytes, ns), 3);
  for (int32_t v : {std::numeric_limits<int32_t>::max(), -1, 4097}) {
    auto b = bytes;
    put_be32(&b, ns, v);
    hwr_lcm::chunk_ack_t e;
    const core::Status st = decode_ack_message(b.data(), b.size(), &e);
    EXPECT_EQ(st.code(), core::ErrorCode::kOutOfRange) << v << ": " << st.to_string();
    EXPECT_NE(st.message().find("num_selective"), std::string::npos) << st.to_string();
    EXPECT_EQ(e.selective.capacity(), 0u);
  }
  auto b = bytes;
  put_be32(&b, ns, 4);  // claims one more than present
  EXPECT_EQ(decode_ack_message(b.data(), b.size(), &d).code(), core::ErrorCode::kParseError);
  // A chunk is not an ack.
  const auto chunk = encode(make_chunk(10));
  EXPECT_NE(decode_ack_message(chunk.data(), chunk.size(), &d).message().find("not a chunk_ack_t"),
            std::string::npos);
}

TEST(AckMessage, VerifyRejectsInconsistentAcks) {
  // Each case is sealed after its change, so the field itself (not the CRC) is what fails.
  ChunkWireLimits limits;
  limits.max_selective = 4;
  EXPECT_TRUE(verify_ack(make_ack({11, 15}), limits).ok());
  auto a = make_ack({10});
  EXPECT_NE(verify_ack(a, limits).message().find("not above cumulative_seq"), std::string::npos);
  a = make_ack({11, 12, 13, 14, 15});
  EXPECT_NE(verify_ack(a, limits).message().find("more than the limit"), std::string::npos);
  a = make_ack({11});
  a.num_selective = 2;  // checked before the CRC (which covers selective.size() values)
  EXPECT_EQ(verify_ack(a, limits).code(), core::ErrorCode::kInvalidArgument);
  a = make_ack({});
  a.cumulative_seq = -2;
  EXPECT_EQ(verify_ack(resealed(a), limits).code(), core::ErrorCode::kOutOfRange);
  a = make_ack({});
  a.resume_report = 2;
  EXPECT_EQ(verify_ack(resealed(a), limits).code(), core::ErrorCode::kInvalidArgument);
  a = make_ack({});
  a.robot_id.clear();
  EXPECT_EQ(verify_ack(resealed(a), limits).code(), core::ErrorCode::kOutOfRange);
  a = make_ack({});
  a.run_id = -1;
  EXPECT_EQ(verify_ack(resealed(a), limits).code(), core::ErrorCode::kOutOfRange);
}

}  // namespace
}  // namespace hwr::mapio
