// Handsfree A9 frame parser (hal/hw/a9_protocol.hpp): the vendor sheet's two frames (hardware.md),
// frames built here with a bit-at-a-time CRC, and corrupted streams: noise, truncation at every
// byte, every single bit flipped, lying LEN bytes, frames hidden inside bad ones, every split of the
// stream across push() calls. After every test the byte accounting must close.
#include "hwr/hal/hw/a9_protocol.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/LU>  // determinant

#include "a9_frames.hpp"

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

Bytes from_hex(const std::string& hex) {
  Bytes out;
  for (size_t i = 0; i + 1 < hex.size(); i += 2)
    out.push_back(static_cast<uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  return out;
}

// hardware.md, "Handsfree A9" test vectors.
const Bytes kVendorImu = from_hex(
    "aa552c29ec41004029706b9d66383a508faab9da33c0b9a6e74d3c0267b9bb030480bf25bfac3d4fd40fbdcd4c4a3f5dfb");
const Bytes kVendorAttitude = from_hex("aa551423e04800ac9a1e83839a1c3f6b100341568d29c1170e");

using test::put_f32;
using test::put_u32;
Bytes make_imu_frame(uint32_t t_us, Eigen::Vector3f gyro, Eigen::Vector3f accel, Eigen::Vector3f mag) {
  return test::make_a9_imu_frame(t_us, gyro, accel, mag);
}
Bytes make_attitude_frame(uint32_t t_us, Eigen::Vector3f rpy) {
  return test::make_a9_attitude_frame(t_us, rpy);
}

// A few distinct frames of both types.
std::vector<Bytes> sample_frames() {
  std::vector<Bytes> frames = {kVendorImu, kVendorAttitude};
  for (uint32_t k = 0; k < 6; ++k) {
    const float s = static_cast<float>(k) * 0.25f;
    if (k % 2 == 0) {
      frames.push_back(make_imu_frame(1000u * k + 7u, {0.1f + s, -0.2f, 0.3f}, {0.01f, -0.02f * s, -1.0f},
                                      {0.2f, 0.1f, 0.4f + s}));
    } else {
      frames.push_back(make_attitude_frame(1000u * k + 9u, {1.5f * s, -2.0f, 170.0f - s}));
    }
  }
  return frames;
}

Bytes concat(const std::vector<Bytes>& parts) {
  Bytes out;
  for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

// The packet a frame must decode to, read here straight from the documented offsets.
A9Packet expected_packet(const Bytes& f) {
  auto f32 = [&](size_t off) {
    float v;
    std::memcpy(&v, f.data() + off, 4);
    return static_cast<double>(v);
  };
  uint32_t t;
  std::memcpy(&t, f.data() + 7, 4);
  if (f[2] == 0x2C) {
    A9ImuPacket p;
    p.t_us = t;
    p.gyro_radps = {f32(11), f32(15), f32(19)};
    p.accel_g = {f32(23), f32(27), f32(31)};
    p.mag_raw = {f32(35), f32(39), f32(43)};
    return p;
  }
  A9AttitudePacket p;
  p.t_us = t;
  p.rpy_deg = {f32(11), f32(15), f32(19)};
  return p;
}

bool same(const A9Packet& a, const A9Packet& b) {
  if (a.index() != b.index()) return false;
  if (const auto* x = std::get_if<A9ImuPacket>(&a)) {
    const auto& y = std::get<A9ImuPacket>(b);
    return x->t_us == y.t_us && x->gyro_radps == y.gyro_radps && x->accel_g == y.accel_g &&
           x->mag_raw == y.mag_raw;
  }
  const auto& x = std::get<A9AttitudePacket>(a);
  const auto& y = std::get<A9AttitudePacket>(b);
  return x.t_us == y.t_us && x.rpy_deg == y.rpy_deg;
}

void expect_packets(const std::vector<A9Packet>& got, const std::vector<Bytes>& frames,
                    const std::string& ctx) {
  ASSERT_EQ(got.size(), frames.size()) << ctx;
  for (size_t i = 0; i < frames.size(); ++i)
    EXPECT_TRUE(same(got[i], expected_packet(frames[i]))) << ctx << " #" << i;
}

// Every byte pushed is in an emitted frame, discarded, or buffered.
void expect_accounting_closes(const A9Parser& p) {
  const A9ParserCounters& c = p.counters();
  EXPECT_EQ(c.frames_ok, c.imu_frames + c.attitude_frames);
  EXPECT_EQ(c.bytes_received, c.imu_frames * kA9ImuFrameSize + c.attitude_frames * kA9AttitudeFrameSize +
                                  c.bytes_discarded + p.bytes_buffered());
}

std::vector<A9Packet> push_all(A9Parser& p, const Bytes& bytes) {
  std::vector<A9Packet> got;
  p.push(bytes.data(), bytes.size(), [&](const A9Packet& pk) { got.push_back(pk); });
  return got;
}

TEST(A9Protocol, GivenVendorImuFrame_WhenParsed_ThenHardwareMdValues) {
  A9Parser parser;
  const auto got = push_all(parser, kVendorImu);
  ASSERT_EQ(got.size(), 1u);
  const auto& imu = std::get<A9ImuPacket>(got[0]);
  EXPECT_EQ(imu.t_us, 1802512704u);
  // hardware.md: accel ≈ (0.0126, −0.0057, −1.0001) g.
  EXPECT_NEAR(imu.accel_g.x(), 0.0126, 5e-5);
  EXPECT_NEAR(imu.accel_g.y(), -0.0057, 5e-5);
  EXPECT_NEAR(imu.accel_g.z(), -1.0001, 5e-5);
  // The float32 LE values of those bytes, decoded independently (Python struct.unpack('<f')).
  EXPECT_FLOAT_EQ(static_cast<float>(imu.gyro_radps.x()), 0.0007034333539195359f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.gyro_radps.y()), -0.00032531702890992165f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.gyro_radps.z()), -0.0003665972617454827f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.accel_g.x()), 0.012567436322569847f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.accel_g.z()), -1.0001224279403687f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.mag_raw.x()), 0.08434895426034927f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.mag_raw.y()), -0.035114582628011703f);
  EXPECT_FLOAT_EQ(static_cast<float>(imu.mag_raw.z()), 0.790234386920929f);
  EXPECT_EQ(parser.counters().frames_ok, 1u);
  EXPECT_EQ(parser.counters().imu_frames, 1u);
  EXPECT_EQ(parser.counters().bytes_discarded, 0u);
  EXPECT_EQ(parser.bytes_buffered(), 0u);
  expect_accounting_closes(parser);
}

TEST(A9Protocol, GivenVendorAttitudeFrame_WhenParsed_ThenHardwareMdRollPitchYaw) {
  A9Parser parser;
  const auto got = push_all(parser, kVendorAttitude);
  ASSERT_EQ(got.size(), 1u);
  const auto& att = std::get<A9AttitudePacket>(got[0]);
  EXPECT_EQ(att.t_us, 2199820972u);  // vendor sheet: ac9a1e83 → 0x831e9aac
  EXPECT_NEAR(att.rpy_deg.x(), 0.61, 0.005);
  EXPECT_NEAR(att.rpy_deg.y(), 8.19, 0.005);
  EXPECT_NEAR(att.rpy_deg.z(), -10.60, 0.005);
  EXPECT_EQ(parser.counters().attitude_frames, 1u);
  expect_accounting_closes(parser);
}

TEST(A9Protocol, GivenFrameCheckers_WhenVendorFrames_ThenCrcOkAndDecodeAgree) {
  EXPECT_TRUE(a9_frame_crc_ok(kVendorImu.data(), kVendorImu.size()));
  EXPECT_TRUE(a9_frame_crc_ok(kVendorAttitude.data(), kVendorAttitude.size()));
  EXPECT_FALSE(a9_frame_crc_ok(kVendorImu.data(), kVendorImu.size() - 1));  // size disagrees with LEN
  A9Packet p;
  EXPECT_TRUE(decode_a9_frame(kVendorAttitude.data(), kVendorAttitude.size(), &p));
  EXPECT_TRUE(same(p, expected_packet(kVendorAttitude)));
  EXPECT_FALSE(decode_a9_frame(kVendorAttitude.data(), kVendorAttitude.size() - 1, &p));
  Bytes bad_len = kVendorAttitude;
  bad_len[2] = 0x15;
  EXPECT_FALSE(decode_a9_frame(bad_len.data(), bad_len.size(), &p));
}

TEST(A9Protocol, GivenStream_WhenSplitAcrossTwoPushesAtEveryBoundary_ThenSamePackets) {
  const auto frames = sample_frames();
  const Bytes stream = concat(frames);
  for (size_t split = 0; split <= stream.size(); ++split) {
    A9Parser parser;
    std::vector<A9Packet> got;
    auto sink = [&](const A9Packet& pk) { got.push_back(pk); };
    parser.push(stream.data(), split, sink);
    parser.push(stream.data() + split, stream.size() - split, sink);
    expect_packets(got, frames, "split " + std::to_string(split));
    EXPECT_EQ(parser.counters().bytes_discarded, 0u);
    expect_accounting_closes(parser);
  }
}

TEST(A9Protocol, GivenStream_WhenPushedByteByByteOrInRandomChunks_ThenSamePacketsEachAtItsLastByte) {
  const auto frames = sample_frames();
  const Bytes stream = concat(frames);
  {
    A9Parser parser;
    std::vector<size_t> emitted_at;
    size_t i = 0;
    for (; i < stream.size(); ++i)
      parser.push(&stream[i], 1, [&](const A9Packet&) { emitted_at.push_back(i); });
    ASSERT_EQ(emitted_at.size(), frames.size());
    size_t end = 0;
    for (size_t k = 0; k < frames.size(); ++k) {
      end += frames[k].size();
      EXPECT_EQ(emitted_at[k], end - 1) << "frame " << k << " must be emitted when its last byte arrives";
    }
  }
  std::mt19937 rng(3);
  std::uniform_int_distribution<size_t> chunk(1, 700);  // also larger than the parser's buffer
  Bytes big;
  for (int rep = 0; rep < 40; ++rep) big.insert(big.end(), stream.begin(), stream.end());
  for (int trial = 0; trial < 20; ++trial) {
    A9Parser parser;
    std::vector<A9Packet> got;
    for (size_t pos = 0; pos < big.size();) {
      const size_t n = std::min(chunk(rng), big.size() - pos);
      parser.push(big.data() + pos, n, [&](const A9Packet& pk) { got.push_back(pk); });
      pos += n;
    }
    ASSERT_EQ(got.size(), 40 * frames.size());
    for (size_t k = 0; k < got.size(); ++k)
      EXPECT_TRUE(same(got[k], expected_packet(frames[k % frames.size()])));
    expect_accounting_closes(parser);
  }
}

TEST(A9Protocol, GivenRandomNoiseBeforeAndBetweenFrames_WhenParsed_ThenAllFramesAndNoiseCounted) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> len(0, 80);
  const auto frames = sample_frames();
  for (int trial = 0; trial < 50; ++trial) {
    Bytes stream;
    size_t noise_bytes = 0;
    for (const Bytes& f : frames) {
      const int n = len(rng);
      for (int k = 0; k < n; ++k) {
        uint8_t b = static_cast<uint8_t>(byte(rng));
        if (k % 7 == 0) b = 0xAA;  // plenty of false first sync bytes
        if (k % 11 == 1) b = 0x55;
        stream.push_back(b);
      }
      noise_bytes += static_cast<size_t>(n);
      stream.insert(stream.end(), f.begin(), f.end());
    }
    A9Parser parser;
    expect_packets(push_all(parser, stream), frames, "trial " + std::to_string(trial));
    EXPECT_EQ(parser.counters().bytes_discarded, noise_bytes);
    EXPECT_EQ(parser.bytes_buffered(), 0u);
    expect_accounting_closes(parser);
  }
}

TEST(A9Protocol, GivenFrameTruncatedAtEveryByte_WhenFollowedByValidFrame_ThenOnlyTheValidFrame) {
  for (const Bytes& cut_from : {kVendorImu, kVendorAttitude}) {
    for (size_t k = 1; k < cut_from.size(); ++k) {
      // Alone: every prefix of a frame is a frame in progress, kept and waited for.
      A9Parser waiting;
      EXPECT_TRUE(
          push_all(waiting, Bytes(cut_from.begin(), cut_from.begin() + static_cast<long>(k))).empty());
      EXPECT_EQ(waiting.bytes_buffered(), k);
      // Then valid frames: the truncated one is dropped once the bytes it claims have arrived (a live
      // port keeps sending), and the valid ones behind it are all decoded.
      for (const Bytes& next : {kVendorImu, kVendorAttitude}) {
        Bytes stream(cut_from.begin(), cut_from.begin() + static_cast<long>(k));
        for (const Bytes& f : {next, kVendorImu}) stream.insert(stream.end(), f.begin(), f.end());
        A9Parser parser;
        expect_packets(push_all(parser, stream), {next, kVendorImu}, "cut at " + std::to_string(k));
        EXPECT_EQ(parser.counters().bytes_discarded, k);
        expect_accounting_closes(parser);
      }
    }
  }
}

TEST(A9Protocol, GivenEverySingleBitFlip_WhenFollowedByValidFrame_ThenCorruptFrameDroppedValidOneDecoded) {
  for (const Bytes& good : {kVendorImu, kVendorAttitude}) {
    for (size_t bit = 0; bit < 8 * good.size(); ++bit) {
      Bytes bad = good;
      bad[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
      Bytes stream = bad;
      stream.insert(stream.end(), kVendorImu.begin(), kVendorImu.end());
      stream.insert(stream.end(), kVendorAttitude.begin(), kVendorAttitude.end());
      A9Parser parser;
      // CRC-16 detects every single-bit error: only the two valid frames come out.
      expect_packets(push_all(parser, stream), {kVendorImu, kVendorAttitude}, "bit " + std::to_string(bit));
      const A9ParserCounters& c = parser.counters();
      EXPECT_EQ(c.bytes_discarded, bad.size());
      if (bit >= 16) {
        EXPECT_GE(c.crc_errors + c.unknown_length, 1u) << "bit " << bit;
      }
      expect_accounting_closes(parser);
    }
  }
}

TEST(A9Protocol, GivenValidFrameHiddenInsideBadOne_WhenParsedByteByByte_ThenFoundWithinOneFrame) {
  // A header that claims an IMU frame, cut short after 9 bytes; an attitude frame follows at once,
  // then more data. The failed candidate spans 49 bytes; the hidden frame must still come out, no
  // later than one maximum frame length after its last byte.
  Bytes stream(kVendorImu.begin(), kVendorImu.begin() + 9);
  const size_t hidden_end = stream.size() + kVendorAttitude.size();
  stream.insert(stream.end(), kVendorAttitude.begin(), kVendorAttitude.end());
  stream.insert(stream.end(), kVendorImu.begin(), kVendorImu.end());
  A9Parser parser;
  std::vector<A9Packet> got;
  std::vector<size_t> at;
  for (size_t i = 0; i < stream.size(); ++i) {
    parser.push(&stream[i], 1, [&](const A9Packet& pk) {
      got.push_back(pk);
      at.push_back(i);
    });
  }
  expect_packets(got, {kVendorAttitude, kVendorImu}, "hidden");
  ASSERT_EQ(at.size(), 2u);
  EXPECT_LE(at[0] + 1 - hidden_end, kA9MaxFrameSize);
  EXPECT_EQ(parser.counters().crc_errors, 1u);
  EXPECT_EQ(parser.counters().bytes_discarded, 9u);
  expect_accounting_closes(parser);
}

TEST(A9Protocol, GivenLyingLengths_WhenParsed_ThenCountedAndFollowingFramesKept) {
  {
    // An attitude frame whose LEN says IMU: 49 bytes are waited for, the CRC fails, the parser
    // resyncs and finds the frames that followed.
    Bytes lying = kVendorAttitude;
    lying[2] = kA9LenImu;
    A9Parser parser;
    expect_packets(push_all(parser, concat({lying, kVendorAttitude, kVendorImu})),
                   {kVendorAttitude, kVendorImu}, "short frame claiming 0x2C");
    EXPECT_EQ(parser.counters().crc_errors, 1u);
    EXPECT_EQ(parser.counters().bytes_discarded, lying.size());
    expect_accounting_closes(parser);
  }
  {
    // An IMU frame whose LEN says attitude: the 25-byte candidate fails its CRC.
    Bytes lying = kVendorImu;
    lying[2] = kA9LenAttitude;
    A9Parser parser;
    expect_packets(push_all(parser, concat({lying, kVendorImu})), {kVendorImu}, "long frame claiming 0x14");
    EXPECT_GE(parser.counters().crc_errors, 1u);
    EXPECT_EQ(parser.counters().bytes_discarded, lying.size());
    expect_accounting_closes(parser);
  }
  for (int len : {0x00, 0x01, 0x13, 0x15, 0x2B, 0x2D, 0xFF}) {
    Bytes lying = kVendorImu;
    lying[2] = static_cast<uint8_t>(len);
    A9Parser parser;
    expect_packets(push_all(parser, concat({lying, kVendorAttitude})), {kVendorAttitude},
                   "LEN " + std::to_string(len));
    EXPECT_EQ(parser.counters().unknown_length, 1u);
    EXPECT_EQ(parser.counters().crc_errors, 0u);
    EXPECT_EQ(parser.counters().bytes_discarded, lying.size());
    expect_accounting_closes(parser);
  }
}

TEST(A9Protocol, GivenFrameWithValidCrcButNaN_WhenParsed_ThenDroppedAndCountedNonFinite) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const Bytes nan_imu = make_imu_frame(5, {0, 0, 0}, {0, nan, -1}, {0, 0, 0});
  const Bytes inf_att = make_attitude_frame(6, {0, inf, 0});
  A9Parser parser;
  expect_packets(push_all(parser, concat({nan_imu, kVendorImu, inf_att, kVendorAttitude})),
                 {kVendorImu, kVendorAttitude}, "non-finite");
  EXPECT_EQ(parser.counters().non_finite, 2u);
  EXPECT_EQ(parser.counters().crc_errors, 0u);
  EXPECT_EQ(parser.counters().bytes_discarded, nan_imu.size() + inf_att.size());
  expect_accounting_closes(parser);
}

TEST(A9Protocol, GivenPartialFrameBuffered_WhenReset_ThenCountedDiscardedAndNextFrameParses) {
  A9Parser parser;
  EXPECT_TRUE(push_all(parser, Bytes(kVendorImu.begin(), kVendorImu.begin() + 20)).empty());
  parser.reset();
  EXPECT_EQ(parser.bytes_buffered(), 0u);
  EXPECT_EQ(parser.counters().bytes_discarded, 20u);
  expect_packets(push_all(parser, kVendorAttitude), {kVendorAttitude}, "after reset");
  expect_accounting_closes(parser);
}

TEST(A9Protocol, GivenVendorImuAtRest_WhenToImuSample_ThenSpecificForcePlusGOnZUp) {
  A9Parser parser;
  const auto got = push_all(parser, kVendorImu);
  ASSERT_EQ(got.size(), 1u);
  const auto& imu = std::get<A9ImuPacket>(got[0]);
  const hal::ImuSample s = to_imu_sample(imu, 123456789);
  EXPECT_EQ(s.t_ns, 123456789);
  // R_x(π) and g = 9.80665: (x, −y, −z) · g.
  EXPECT_DOUBLE_EQ(s.accel_mps2.x(), imu.accel_g.x() * 9.80665);
  EXPECT_DOUBLE_EQ(s.accel_mps2.y(), -imu.accel_g.y() * 9.80665);
  EXPECT_DOUBLE_EQ(s.accel_mps2.z(), -imu.accel_g.z() * 9.80665);
  EXPECT_NEAR(s.accel_mps2.z(), 9.81, 0.01);  // ImuSample's contract: +9.81 on z at rest, level
  EXPECT_NEAR(s.accel_mps2.norm(), 9.80665 * imu.accel_g.norm(), 1e-9);
  EXPECT_DOUBLE_EQ(s.gyro_radps.x(), imu.gyro_radps.x());
  EXPECT_DOUBLE_EQ(s.gyro_radps.y(), -imu.gyro_radps.y());
  EXPECT_DOUBLE_EQ(s.gyro_radps.z(), -imu.gyro_radps.z());
}

TEST(A9Protocol, GivenRotationAboutDeviceAxes_WhenToImuSample_ThenMappingIsAProperRotation) {
  // A mirror would flip the handedness (det = −1) and make gyro and accel disagree; R_x(π) must not.
  A9ImuPacket p;
  Eigen::Matrix3d M;
  for (int c = 0; c < 3; ++c) {
    p.accel_g = Eigen::Vector3d::Unit(c);
    M.col(c) = to_imu_sample(p, 0).accel_mps2 / kA9StandardGravityMps2;
  }
  EXPECT_NEAR(M.determinant(), 1.0, 1e-12);
  EXPECT_TRUE((M * M.transpose()).isApprox(Eigen::Matrix3d::Identity()));
  for (int c = 0; c < 3; ++c) {
    p.gyro_radps = Eigen::Vector3d::Unit(c);
    EXPECT_TRUE(to_imu_sample(p, 0).gyro_radps.isApprox(M.col(c))) << "gyro and accel axes must map alike";
  }
}

TEST(A9Protocol, GivenClockWrap_WhenUnwrapped_ThenTimelineContinuesMonotonically) {
  A9TimestampUnwrapper u;
  EXPECT_EQ(u.unwrap_us(4294967000u), 4294967000);  // the first stamp maps to itself
  EXPECT_EQ(u.unwrap_us(4294967295u), 4294967295);
  EXPECT_EQ(u.unwrap_us(0u), 4294967296);  // 2^32: one tick after the last
  EXPECT_EQ(u.unwrap_us(6666u), 4294967296 + 6666);
  EXPECT_EQ(u.wraps(), 1u);
  // Round the clock again in steps under 2^31 µs, then a second wrap.
  EXPECT_EQ(u.unwrap_us(2000000000u), 4294967296 + 2000000000);
  EXPECT_EQ(u.unwrap_us(4000000000u), 4294967296 + 4000000000);
  EXPECT_EQ(u.unwrap_us(4294960000u), 4294967296 + 4294960000);
  EXPECT_EQ(u.unwrap_us(3000u), 2 * 4294967296LL + 3000);
  EXPECT_EQ(u.wraps(), 2u);
  EXPECT_EQ(u.backward_steps(), 0u);
}

TEST(A9Protocol, GivenStepBackwards_WhenUnwrapped_ThenPassedThroughAndCounted) {
  A9TimestampUnwrapper u;
  EXPECT_EQ(u.unwrap_us(1000000u), 1000000);
  EXPECT_EQ(u.unwrap_us(999000u), 999000);  // not disguised as a wrap
  EXPECT_EQ(u.backward_steps(), 1u);
  EXPECT_EQ(u.wraps(), 0u);
  u.reset();
  EXPECT_EQ(u.unwrap_us(42u), 42);
}

TEST(A9Protocol, GivenAMinuteOfStampsAcrossTheWrap_WhenUnwrapped_ThenEqualsTrueTime) {
  // Oracle: the true 64-bit time at 150 Hz from near the wrap, truncated to u32 as the device sends.
  A9TimestampUnwrapper u;
  const int64_t start = 4294967296LL - 3'000'000;
  for (int64_t k = 0; k < 150 * 60; ++k) {
    const int64_t t = start + k * 6667;
    ASSERT_EQ(u.unwrap_us(static_cast<uint32_t>(t)), t);
  }
}

}  // namespace
}  // namespace hwr::hal::hw
