// u-blox M8T protocol (hal/hw/ubx_protocol.hpp): hardware.md's CFG-RATE / CFG-MSG bytes, hand-computed
// Fletcher sums, ACK/NAK, a hand-built NAV-PVT payload, and the NMEA/UBX stream splitter on clean and
// corrupted streams (noise, truncation at every byte, bit flips, lying lengths, every split).
#include "hwr/hal/hw/ubx_protocol.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace hwr::hal::hw {
namespace {

using Bytes = std::vector<uint8_t>;

// Oracle checksum, written from the UBX definition.
Bytes frame_oracle(uint8_t cls, uint8_t id, const Bytes& payload) {
  Bytes f = {0xB5,
             0x62,
             cls,
             id,
             static_cast<uint8_t>(payload.size() & 0xFF),
             static_cast<uint8_t>(payload.size() >> 8)};
  f.insert(f.end(), payload.begin(), payload.end());
  unsigned a = 0, b = 0;
  for (size_t i = 2; i < f.size(); ++i) {
    a = (a + f[i]) % 256;
    b = (b + a) % 256;
  }
  f.push_back(static_cast<uint8_t>(a));
  f.push_back(static_cast<uint8_t>(b));
  return f;
}

Bytes text(const std::string& s) { return Bytes(s.begin(), s.end()); }

std::string with_checksum(const std::string& body) {  // "GNGGA,..." → "$GNGGA,...*hh"
  uint8_t x = 0;
  for (char c : body) x ^= static_cast<uint8_t>(c);
  char hex[3];
  std::snprintf(hex, sizeof hex, "%02X", x);
  return "$" + body + "*" + hex;
}

void put_le(Bytes* p, size_t off, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) (*p)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}

// A NAV-PVT payload with every documented field set to a distinct value.
Bytes nav_pvt_payload() {
  Bytes p(92, 0);
  put_le(&p, 0, 123456789u, 4);  // iTOW ms
  put_le(&p, 4, 2024, 2);
  p[6] = 5;
  p[7] = 17;
  p[8] = 12;
  p[9] = 34;
  p[10] = 56;
  p[11] = 0x07;  // validDate | validTime | fullyResolved
  p[20] = 3;
  p[21] = 0x01;  // gnssFixOK
  p[23] = 14;
  put_le(&p, 24, static_cast<uint32_t>(103409595), 4);  // lon 10.3409595°
  put_le(&p, 28, static_cast<uint32_t>(633744733), 4);  // lat 63.3744733°
  put_le(&p, 32, static_cast<uint32_t>(207100), 4);     // height 207.1 m
  put_le(&p, 36, static_cast<uint32_t>(167000), 4);     // hMSL 167.0 m
  put_le(&p, 40, 1500u, 4);                             // hAcc 1.5 m
  put_le(&p, 44, 2500u, 4);                             // vAcc 2.5 m
  put_le(&p, 48, static_cast<uint32_t>(1234), 4);       // velN
  put_le(&p, 52, static_cast<uint32_t>(-567), 4);       // velE
  put_le(&p, 56, static_cast<uint32_t>(-89), 4);        // velD
  put_le(&p, 60, static_cast<uint32_t>(1357), 4);       // gSpeed
  put_le(&p, 64, static_cast<uint32_t>(-12345678), 4);  // headMot −123.45678°
  put_le(&p, 76, 156, 2);                               // pDOP 1.56
  return p;
}

struct Seen {
  bool ubx = false;
  uint8_t cls = 0, id = 0;
  Bytes payload;
  std::string nmea;
  bool operator==(const Seen& o) const {
    return ubx == o.ubx && cls == o.cls && id == o.id && payload == o.payload && nmea == o.nmea;
  }
};

Seen ubx_item(uint8_t cls, uint8_t id, const Bytes& payload) { return {true, cls, id, payload, ""}; }
Seen nmea_item(const std::string& s) { return {false, 0, 0, {}, s}; }

std::vector<Seen> push_all(GnssStreamParser& p, const Bytes& bytes, size_t chunk = 0) {
  std::vector<Seen> got;
  auto sink = [&](const GnssMessage& m) {
    if (m.kind == GnssMessage::Kind::kUbx) {
      got.push_back(ubx_item(m.ubx.cls, m.ubx.id, Bytes(m.ubx.payload, m.ubx.payload + m.ubx.payload_size)));
    } else {
      got.push_back(nmea_item(std::string(m.nmea)));
    }
  };
  if (chunk == 0) chunk = bytes.size() + 1;
  for (size_t pos = 0; pos < bytes.size(); pos += chunk)
    p.push(bytes.data() + pos, std::min(chunk, bytes.size() - pos), sink);
  return got;
}

void expect_accounting_closes(const GnssStreamParser& p) {
  const GnssStreamCounters& c = p.counters();
  EXPECT_EQ(c.bytes_received, c.bytes_accepted + c.bytes_discarded + p.bytes_buffered());
}

const std::string kGga =
    "$GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45";  // hardware.md
const std::string kRmc = with_checksum("GNRMC,173002.00,A,6322.46840,N,01020.45757,E,0.012,,170524,,,A");

// A mixed stream and what it must yield.
struct Mixed {
  Bytes bytes;
  std::vector<Seen> items;
};
Mixed mixed_stream() {
  Mixed m;
  auto add_ubx = [&](uint8_t cls, uint8_t id, const Bytes& payload) {
    const Bytes f = frame_oracle(cls, id, payload);
    m.bytes.insert(m.bytes.end(), f.begin(), f.end());
    m.items.push_back(ubx_item(cls, id, payload));
  };
  auto add_nmea = [&](const std::string& s, const char* eol) {
    const Bytes t = text(s + eol);
    m.bytes.insert(m.bytes.end(), t.begin(), t.end());
    m.items.push_back(nmea_item(s));
  };
  add_nmea(kGga, "\r\n");
  add_ubx(0x01, 0x07, nav_pvt_payload());
  add_ubx(0x05, 0x01, {0x06, 0x08});
  add_nmea(kRmc, "\r\n");
  add_ubx(0x0A, 0x04, {});  // MON-VER poll form: empty payload
  add_nmea(kGga, "\n");     // LF only
  add_ubx(0x05, 0x00, {0x06, 0x01});
  return m;
}

TEST(UbxProtocol, GivenHardwareMdConfigFrames_WhenBuilt_ThenExactBytes) {
  EXPECT_EQ(make_cfg_rate(100),
            (Bytes{0xB5, 0x62, 0x06, 0x08, 0x06, 0x00, 0x64, 0x00, 0x01, 0x00, 0x01, 0x00, 0x7A, 0x12}));
  EXPECT_EQ(make_cfg_msg(0x01, 0x07, 1),
            (Bytes{0xB5, 0x62, 0x06, 0x01, 0x03, 0x00, 0x01, 0x07, 0x01, 0x13, 0x51}));
}

TEST(UbxProtocol, GivenPollFrame_WhenBuilt_ThenHandComputedFletcher) {
  // 06 08 00 00: A = 06, 0E, 0E, 0E; B = 06, 14, 22, 30.
  EXPECT_EQ(make_ubx_frame(0x06, 0x08, nullptr, 0), (Bytes{0xB5, 0x62, 0x06, 0x08, 0x00, 0x00, 0x0E, 0x30}));
  const uint8_t body[] = {0x06, 0x08, 0x00, 0x00};
  const UbxChecksum ck = ubx_fletcher(body, sizeof body);
  EXPECT_EQ(ck.ck_a, 0x0E);
  EXPECT_EQ(ck.ck_b, 0x30);
}

TEST(UbxProtocol, GivenRandomPayloads_WhenFramed_ThenEqualsOracleIncludingU16Length) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> byte(0, 255);
  for (size_t n : {1u, 2u, 92u, 255u, 256u, 1000u, 4000u}) {
    Bytes payload(n);
    for (auto& b : payload) b = static_cast<uint8_t>(byte(rng));
    EXPECT_EQ(make_ubx_frame(0x02, 0x15, payload.data(), n), frame_oracle(0x02, 0x15, payload)) << n;
  }
}

TEST(UbxProtocol, GivenAckAndNak_WhenDecoded_ThenAckedMessageNamed) {
  const uint8_t rate[] = {0x06, 0x08};
  auto ack = decode_ubx_ack(0x05, 0x01, rate, 2);
  ASSERT_TRUE(ack.ok()) << ack.status().to_string();
  EXPECT_TRUE(ack->acknowledged);
  EXPECT_EQ(ack->acked_cls, 0x06);
  EXPECT_EQ(ack->acked_id, 0x08);
  auto nak = decode_ubx_ack(0x05, 0x00, rate, 2);
  ASSERT_TRUE(nak.ok());
  EXPECT_FALSE(nak->acknowledged);

  auto not_ack = decode_ubx_ack(0x01, 0x07, rate, 2);
  ASSERT_FALSE(not_ack.ok());
  EXPECT_EQ(not_ack.status().code(), core::ErrorCode::kInvalidArgument);
  auto short_ack = decode_ubx_ack(0x05, 0x01, rate, 1);
  ASSERT_FALSE(short_ack.ok());
  EXPECT_EQ(short_ack.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(short_ack.status().message().find("2 bytes"), std::string::npos) << short_ack.status().message();
}

TEST(UbxProtocol, GivenHandBuiltNavPvt_WhenDecoded_ThenEveryDocumentedFieldInSi) {
  const Bytes p = nav_pvt_payload();
  auto pvt = decode_nav_pvt(p.data(), p.size());
  ASSERT_TRUE(pvt.ok()) << pvt.status().to_string();
  EXPECT_EQ(pvt->itow_ms, 123456789u);
  EXPECT_EQ(pvt->year, 2024);
  EXPECT_EQ(pvt->month, 5);
  EXPECT_EQ(pvt->day, 17);
  EXPECT_EQ(pvt->hour, 12);
  EXPECT_EQ(pvt->minute, 34);
  EXPECT_EQ(pvt->second, 56);
  EXPECT_EQ(pvt->valid_flags, 0x07);
  EXPECT_TRUE(pvt->valid_date);
  EXPECT_TRUE(pvt->valid_time);
  EXPECT_TRUE(pvt->fully_resolved);
  EXPECT_EQ(pvt->fix_type, 3);
  EXPECT_TRUE(pvt->gnss_fix_ok);
  EXPECT_EQ(pvt->num_sv, 14);
  EXPECT_DOUBLE_EQ(pvt->lon_deg, 103409595 * 1e-7);
  EXPECT_DOUBLE_EQ(pvt->lat_deg, 633744733 * 1e-7);
  EXPECT_NEAR(pvt->lat_deg, 63.3744733, 1e-12);
  EXPECT_DOUBLE_EQ(pvt->height_ellipsoid_m, 207.1);
  EXPECT_DOUBLE_EQ(pvt->height_msl_m, 167.0);
  EXPECT_DOUBLE_EQ(pvt->h_acc_m, 1.5);
  EXPECT_DOUBLE_EQ(pvt->v_acc_m, 2.5);
  EXPECT_DOUBLE_EQ(pvt->vel_north_mps, 1.234);
  EXPECT_DOUBLE_EQ(pvt->vel_east_mps, -0.567);
  EXPECT_DOUBLE_EQ(pvt->vel_down_mps, -0.089);
  EXPECT_DOUBLE_EQ(pvt->ground_speed_mps, 1.357);
  EXPECT_NEAR(pvt->heading_motion_deg, -123.45678, 1e-12);
  EXPECT_DOUBLE_EQ(pvt->pdop, 1.56);

  const hal::GnssFix fix = to_gnss_fix(*pvt, 77);
  EXPECT_EQ(fix.t_ns, 77);
  EXPECT_EQ(fix.fix_type, 3);
  EXPECT_EQ(fix.num_sv, 14);
  EXPECT_DOUBLE_EQ(fix.lat_deg, pvt->lat_deg);
  EXPECT_DOUBLE_EQ(fix.lon_deg, pvt->lon_deg);
  EXPECT_DOUBLE_EQ(fix.height_m, 207.1);  // ellipsoidal, as GnssFix documents
  EXPECT_DOUBLE_EQ(fix.h_acc_m, 1.5);
  EXPECT_DOUBLE_EQ(fix.v_acc_m, 2.5);
}

TEST(UbxProtocol, GivenNavPvtFramedAndStreamed_WhenParsedAndDecoded_ThenRoundTrips) {
  const Bytes p = nav_pvt_payload();
  const Bytes f = make_ubx_frame(kUbxClassNav, kUbxIdNavPvt, p.data(), p.size());
  GnssStreamParser parser;
  int seen = 0;
  parser.push(f.data(), f.size(), [&](const GnssMessage& m) {
    ++seen;
    ASSERT_EQ(m.kind, GnssMessage::Kind::kUbx);
    EXPECT_EQ(m.ubx.cls, kUbxClassNav);
    EXPECT_EQ(m.ubx.id, kUbxIdNavPvt);
    auto pvt = decode_nav_pvt(m.ubx.payload, m.ubx.payload_size);
    ASSERT_TRUE(pvt.ok());
    EXPECT_EQ(pvt->itow_ms, 123456789u);
    EXPECT_DOUBLE_EQ(pvt->pdop, 1.56);
  });
  EXPECT_EQ(seen, 1);
}

TEST(UbxProtocol, GivenFixTypesAndFlags_WhenToGnssFix_ThenMappedAsDocumented) {
  Bytes p = nav_pvt_payload();
  const struct {
    uint8_t fix_type, flags, expected;
  } cases[] = {{3, 0x01, 3}, {3, 0x00, 0}, {2, 0x01, 2}, {4, 0x01, 3},
               {5, 0x01, 0}, {1, 0x01, 0}, {0, 0x01, 0}, {3, 0xFE, 0}};
  for (const auto& c : cases) {
    p[20] = c.fix_type;
    p[21] = c.flags;
    auto pvt = decode_nav_pvt(p.data(), p.size());
    ASSERT_TRUE(pvt.ok());
    EXPECT_EQ(to_gnss_fix(*pvt, 0).fix_type, c.expected)
        << "fixType " << int(c.fix_type) << " flags " << int(c.flags);
  }
}

TEST(UbxProtocol, GivenBadNavPvtPayloads_WhenDecoded_ThenActionableErrors) {
  Bytes p = nav_pvt_payload();
  for (size_t n : {0u, 91u, 93u}) {
    Bytes q = p;
    q.resize(n);
    auto r = decode_nav_pvt(q.data(), n);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), core::ErrorCode::kCorruptData);
    EXPECT_NE(r.status().message().find("92 bytes"), std::string::npos);
  }
  Bytes lat = p;
  put_le(&lat, 28, static_cast<uint32_t>(900000001), 4);
  EXPECT_EQ(decode_nav_pvt(lat.data(), 92).status().code(), core::ErrorCode::kOutOfRange);
  put_le(&lat, 28, static_cast<uint32_t>(-900000000), 4);  // the South Pole itself is fine
  EXPECT_TRUE(decode_nav_pvt(lat.data(), 92).ok());
  Bytes lon = p;
  put_le(&lon, 24, static_cast<uint32_t>(-1800000001), 4);
  EXPECT_EQ(decode_nav_pvt(lon.data(), 92).status().code(), core::ErrorCode::kOutOfRange);
  Bytes fix = p;
  fix[20] = 6;
  EXPECT_EQ(decode_nav_pvt(fix.data(), 92).status().code(), core::ErrorCode::kOutOfRange);
}

TEST(GnssStreamParser, GivenMixedStream_WhenSplitAcrossTwoPushesAtEveryBoundary_ThenSameItems) {
  const Mixed m = mixed_stream();
  for (size_t split = 0; split <= m.bytes.size(); ++split) {
    GnssStreamParser parser;
    std::vector<Seen> got =
        push_all(parser, Bytes(m.bytes.begin(), m.bytes.begin() + static_cast<long>(split)));
    const auto rest = push_all(parser, Bytes(m.bytes.begin() + static_cast<long>(split), m.bytes.end()));
    got.insert(got.end(), rest.begin(), rest.end());
    ASSERT_EQ(got, m.items) << "split " << split;
    EXPECT_EQ(parser.counters().bytes_discarded, 0u);
    EXPECT_EQ(parser.counters().ubx_frames, 4u);
    EXPECT_EQ(parser.counters().nmea_sentences, 3u);
    expect_accounting_closes(parser);
  }
}

TEST(GnssStreamParser, GivenMixedStream_WhenPushedInChunksOfEverySize_ThenSameItems) {
  const Mixed m = mixed_stream();
  Bytes big;
  std::vector<Seen> want;
  for (int rep = 0; rep < 8; ++rep) {
    big.insert(big.end(), m.bytes.begin(), m.bytes.end());
    want.insert(want.end(), m.items.begin(), m.items.end());
  }
  for (size_t chunk : {1u, 2u, 3u, 7u, 64u, 100u, 1000u, 1600u, 5000u}) {
    GnssStreamParser parser;
    EXPECT_EQ(push_all(parser, big, chunk), want) << "chunk " << chunk;
    EXPECT_EQ(parser.bytes_buffered(), 0u);
    expect_accounting_closes(parser);
  }
}

TEST(GnssStreamParser, GivenNoiseBetweenMessages_WhenParsed_ThenAllItemsAndNoiseCounted) {
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> len(0, 60);
  const Mixed m = mixed_stream();
  // Split the mixed stream back into its messages to interleave noise.
  std::vector<Bytes> parts;
  {
    GnssStreamParser splitter;
    size_t consumed = 0;
    for (size_t i = 0; i < m.bytes.size(); ++i) {
      splitter.push(&m.bytes[i], 1, [&](const GnssMessage&) {
        parts.emplace_back(m.bytes.begin() + static_cast<long>(consumed),
                           m.bytes.begin() + static_cast<long>(i + 1));
        consumed = i + 1;
      });
    }
    ASSERT_EQ(parts.size(), m.items.size());
  }
  for (int trial = 0; trial < 50; ++trial) {
    Bytes stream;
    size_t noise = 0;
    for (const Bytes& part : parts) {
      const int n = len(rng);
      for (int k = 0; k < n; ++k) {
        uint8_t b = static_cast<uint8_t>(byte(rng));
        if (k % 9 == 0) b = 0xB5;
        if (k % 13 == 1) b = '$';
        if (k % 5 == 2) b = static_cast<uint8_t>('A' + k % 26);
        stream.push_back(b);
      }
      noise += static_cast<size_t>(n);
      stream.insert(stream.end(), part.begin(), part.end());
    }
    GnssStreamParser parser;
    ASSERT_EQ(push_all(parser, stream), m.items) << "trial " << trial;
    EXPECT_EQ(parser.counters().bytes_discarded, noise);
    expect_accounting_closes(parser);
  }
}

TEST(GnssStreamParser, GivenMessageTruncatedAtEveryByte_WhenFollowedByValidMessages_ThenOnlyTheValidOnes) {
  const Bytes pvt = frame_oracle(0x01, 0x07, nav_pvt_payload());
  const Bytes gga = text(kGga + "\r\n");
  const Bytes ack = frame_oracle(0x05, 0x01, {0x06, 0x08});
  const std::vector<Seen> tail_items = {nmea_item(kGga), ubx_item(0x05, 0x01, {0x06, 0x08})};
  for (const Bytes& cut_from : {pvt, gga}) {
    for (size_t k = 1; k < cut_from.size(); ++k) {
      Bytes stream(cut_from.begin(), cut_from.begin() + static_cast<long>(k));
      stream.insert(stream.end(), gga.begin(), gga.end());
      stream.insert(stream.end(), ack.begin(), ack.end());
      // A truncated UBX frame waits for its claimed length: pad the stream with more messages so
      // that candidate completes and fails, as on a live port.
      for (int rep = 0; rep < 2; ++rep) stream.insert(stream.end(), gga.begin(), gga.end());
      GnssStreamParser parser;
      const auto got = push_all(parser, stream);
      ASSERT_EQ(got.size(), 4u) << "cut at " << k;
      EXPECT_EQ(got[0], tail_items[0]) << "cut at " << k;
      EXPECT_EQ(got[1], tail_items[1]) << "cut at " << k;
      EXPECT_EQ(parser.counters().bytes_discarded, k) << "cut at " << k;
      expect_accounting_closes(parser);
    }
  }
}

TEST(GnssStreamParser, GivenEverySingleBitFlipInAFrame_WhenParsed_ThenCorruptOneDroppedRestKept) {
  const Bytes ack = frame_oracle(0x05, 0x01, {0x06, 0x08});
  const Bytes gga = text(kGga + "\r\n");
  for (const Bytes& good : {ack, gga}) {
    for (size_t bit = 0; bit < 8 * good.size(); ++bit) {
      Bytes stream = good;
      stream[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
      const size_t bad_size = stream.size();
      // A flipped length bit can claim up to 1024 payload bytes (the limit): enough traffic behind
      // it for that candidate to complete and fail.
      std::vector<Seen> want;
      while (stream.size() < bad_size + 1100) {
        stream.insert(stream.end(), gga.begin(), gga.end());
        stream.insert(stream.end(), ack.begin(), ack.end());
        want.push_back(nmea_item(kGga));
        want.push_back(ubx_item(0x05, 0x01, {0x06, 0x08}));
      }
      GnssStreamParser parser;
      const auto got = push_all(parser, stream);
      ASSERT_EQ(got, want) << "bit " << bit << (good == ack ? " of the ACK" : " of the GGA");
      EXPECT_EQ(parser.counters().bytes_discarded, bad_size) << "bit " << bit;
      expect_accounting_closes(parser);
    }
  }
}

TEST(GnssStreamParser, GivenLyingUbxLengths_WhenParsed_ThenDiscardedAndFollowingMessagesFound) {
  const Bytes gga = text(kGga + "\r\n");
  const Bytes ack = frame_oracle(0x05, 0x01, {0x06, 0x08});
  for (uint16_t claimed :
       {uint16_t{0}, uint16_t{1}, uint16_t{500}, uint16_t{1024}, uint16_t{1025}, uint16_t{0xFFFF}}) {
    Bytes lying = frame_oracle(0x01, 0x07, nav_pvt_payload());
    lying[4] = static_cast<uint8_t>(claimed & 0xFF);
    lying[5] = static_cast<uint8_t>(claimed >> 8);
    Bytes stream = lying;
    std::vector<Seen> want;
    // Enough valid traffic behind it for a claimed 1024-byte payload to complete and fail.
    while (stream.size() < lying.size() + 1100) {
      stream.insert(stream.end(), gga.begin(), gga.end());
      stream.insert(stream.end(), ack.begin(), ack.end());
      want.push_back(nmea_item(kGga));
      want.push_back(ubx_item(0x05, 0x01, {0x06, 0x08}));
    }
    GnssStreamParser parser;
    ASSERT_EQ(push_all(parser, stream, 37), want) << "claimed " << claimed;
    const GnssStreamCounters& c = parser.counters();
    EXPECT_EQ(c.bytes_discarded, lying.size()) << "claimed " << claimed;
    if (claimed > 1024) {
      EXPECT_EQ(c.ubx_oversize, 1u);
    } else {
      EXPECT_GE(c.ubx_checksum_errors, 1u);
    }
    expect_accounting_closes(parser);
  }
}

TEST(GnssStreamParser, GivenPayloadAtAndAboveTheLimit_WhenParsed_ThenLimitInclusive) {
  GnssStreamLimits limits;
  limits.max_ubx_payload = 100;
  const Bytes at = frame_oracle(0x02, 0x13, Bytes(100, 0x5A));
  const Bytes above = frame_oracle(0x02, 0x13, Bytes(101, 0x5A));
  GnssStreamParser parser(limits);
  Bytes stream = at;
  stream.insert(stream.end(), above.begin(), above.end());
  const auto got = push_all(parser, stream);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].payload.size(), 100u);
  EXPECT_EQ(parser.counters().ubx_oversize, 1u);
  EXPECT_EQ(parser.counters().bytes_discarded, above.size());
  expect_accounting_closes(parser);
}

TEST(GnssStreamParser, GivenBrokenNmea_WhenParsed_ThenCountedAndNextSentenceKept) {
  const Bytes gga = text(kGga + "\r\n");
  struct Case {
    std::string name;
    Bytes bad;
    uint64_t GnssStreamCounters::*counter;
  };
  std::string wrong_sum = kGga;
  wrong_sum[wrong_sum.size() - 1] = '6';
  const std::vector<Case> cases = {
      {"bad checksum", text(wrong_sum + "\r\n"), &GnssStreamCounters::nmea_checksum_errors},
      {"no checksum", text("$GNGGA,173002.00,,,,,0,00,99.99,,,,,,\r\n"), &GnssStreamCounters::nmea_malformed},
      {"too long", text("$" + std::string(300, 'A')), &GnssStreamCounters::nmea_malformed},
      {"cut by a new sentence", text("$GNGGA,1730"), &GnssStreamCounters::nmea_malformed},
      {"binary inside", Bytes{'$', 'G', 'N', 0x01, 0x02}, &GnssStreamCounters::nmea_malformed},
      {"CR without LF", text("$GNTXT*00\rX"), &GnssStreamCounters::nmea_malformed},
  };
  for (const Case& c : cases) {
    Bytes stream = c.bad;
    stream.insert(stream.end(), gga.begin(), gga.end());
    GnssStreamParser parser;
    ASSERT_EQ(push_all(parser, stream), std::vector<Seen>{nmea_item(kGga)}) << c.name;
    EXPECT_GE(parser.counters().*c.counter, 1u) << c.name;
    EXPECT_EQ(parser.counters().bytes_discarded, c.bad.size()) << c.name;
    expect_accounting_closes(parser);
  }
}

TEST(GnssStreamParser, GivenSentenceInterruptedByUbxFrame_WhenParsed_ThenFrameAndNextSentenceKept) {
  // The M8T writes UBX and NMEA on one port; a sentence cut off by a frame must not swallow it.
  Bytes stream = text("$GNGGA,173002.00,6322.468");
  const Bytes ack = frame_oracle(0x05, 0x01, {0x06, 0x08});
  stream.insert(stream.end(), ack.begin(), ack.end());
  const Bytes gga = text(kGga + "\r\n");
  stream.insert(stream.end(), gga.begin(), gga.end());
  GnssStreamParser parser;
  EXPECT_EQ(push_all(parser, stream, 1),
            (std::vector<Seen>{ubx_item(0x05, 0x01, {0x06, 0x08}), nmea_item(kGga)}));
  EXPECT_EQ(parser.counters().nmea_malformed, 1u);
  expect_accounting_closes(parser);
}

TEST(GnssStreamParser, GivenLowercaseChecksumAndLongestSentence_WhenParsed_ThenAcceptedUpToTheLimit) {
  // GNTXT,01,01,02,ANTSTATUS=INIT has checksum 3B: sent as "3b" it must still verify.
  const std::string lower = "$GNTXT,01,01,02,ANTSTATUS=INIT*3b";
  // With CR LF exactly max_nmea_chars (128) long, and one character longer.
  const std::string longest = with_checksum("GNTXT," + std::string(128 - 2 - 1 - 6 - 3, 'x'));
  const std::string too_long = with_checksum("GNTXT," + std::string(128 - 2 - 1 - 6 - 3 + 1, 'x'));
  ASSERT_EQ(longest.size() + 2, 128u);
  GnssStreamParser parser;
  const auto got =
      push_all(parser, text(lower + "\r\n" + longest + "\r\n" + too_long + "\r\n" + longest + "\n"));
  EXPECT_EQ(got, (std::vector<Seen>{nmea_item(lower), nmea_item(longest), nmea_item(longest)}));
  EXPECT_EQ(parser.counters().nmea_malformed, 1u);
  EXPECT_EQ(parser.counters().nmea_checksum_errors, 0u);
  EXPECT_EQ(parser.counters().bytes_discarded, too_long.size() + 2);
  expect_accounting_closes(parser);
}

}  // namespace
}  // namespace hwr::hal::hw
