// Wire rules of the operator channel (mapio/operator_wire.hpp): messages encoded by LCM's generated
// encode() decode to the same fields; every prefix, hostile count, bad string, leftover byte and wrong
// fingerprint is rejected with the field named; each validation rule rejects exactly its case; random
// bit flips never crash and whatever still decodes re-encodes to the very same bytes.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "hwr/mapio/operator_wire.hpp"

namespace hwr::mapio {
namespace {

using core::ErrorCode;

hwr_lcm::detection_t make_detection(int seam_points = 2) {
  hwr_lcm::detection_t d;  // LCM types leave their scalars uninitialized: set every field
  d.t_ns = 1732477000123456789;
  d.robot_id = "hwr-0";
  d.run_id = 1732477000000000000;
  d.detection_id = 4;
  d.segment_id = 7;
  d.keyframe_t_ns = 1732477000100000000;
  d.source = 1;
  d.state = 0;
  d.confidence = 0.75f;
  const float px[4] = {120.5f, 80.f, 64.f, 32.f};
  std::memcpy(d.box_px, px, sizeof px);
  const double c[3] = {1.25, -0.5, 0.75}, s[3] = {0.4, 0.05, 0.05};
  std::memcpy(d.box_center_world_m, c, sizeof c);
  std::memcpy(d.box_size_m, s, sizeof s);
  // 30 degrees about z: (cos 15deg, 0, 0, sin 15deg).
  const double q[4] = {std::cos(M_PI / 12), 0, 0, std::sin(M_PI / 12)};
  std::memcpy(d.box_q_world_box, q, sizeof q);
  d.num_seam_points = seam_points;
  for (int i = 0; i < seam_points; ++i) d.seam_world_m.push_back({1.0 + 0.1 * i, -0.5, 0.7});
  return d;
}

hwr_lcm::operator_command_t make_command(OperatorCommandKind kind) {
  hwr_lcm::operator_command_t c;
  c.t_ns = 1732477001000000000;
  c.robot_id = "hwr-0";
  c.command_id = 1732477001000000001;
  c.kind = static_cast<int8_t>(kind);
  c.detection_id = 4;
  c.keyframe_t_ns = 0;
  for (float& v : c.box_px) v = 0;
  for (double& v : c.box_center_world_m) v = 0;
  for (double& v : c.box_size_m) v = 0;
  c.box_q_world_box[0] = 1;
  c.box_q_world_box[1] = c.box_q_world_box[2] = c.box_q_world_box[3] = 0;
  if (kind == OperatorCommandKind::kMove) {
    const double center[3] = {1.3, -0.5, 0.75}, size[3] = {0.5, 0.06, 0.06};
    std::memcpy(c.box_center_world_m, center, sizeof center);
    std::memcpy(c.box_size_m, size, sizeof size);
  }
  if (kind == OperatorCommandKind::kAdd) {
    c.detection_id = -1;  // ignored for add
    c.keyframe_t_ns = 1732477000100000000;
    const float px[4] = {10, 20, 30, 40};
    std::memcpy(c.box_px, px, sizeof px);
  }
  return c;
}

hwr_lcm::command_ack_t make_ack(bool accepted = false) {
  hwr_lcm::command_ack_t a;
  a.t_ns = 1732477002000000000;
  a.robot_id = "hwr-0";
  a.command_id = 1732477001000000001;
  a.accepted = accepted ? 1 : 0;
  a.reason = accepted ? "" : "no detection 4";
  a.detection_id = 4;
  return a;
}

// LCM's own encoder, the reference the decoders must agree with.
template <class Msg>
std::vector<uint8_t> lcm_encode(const Msg& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

void put_be32(std::vector<uint8_t>* b, size_t at, int32_t v) {
  for (int i = 0; i < 4; ++i) (*b)[at + i] = static_cast<uint8_t>(static_cast<uint32_t>(v) >> (24 - 8 * i));
}

// Offsets in the encodings (fingerprint 8, t_ns 8, then robot_id's int32 length).
constexpr size_t kRobotIdLengthAt = 16;
size_t num_seam_points_at(const std::vector<uint8_t>& b, int seam_points) {
  return b.size() - 4 - 24 * static_cast<size_t>(seam_points);
}
size_t reason_length_at(const hwr_lcm::command_ack_t& a) {
  return kRobotIdLengthAt + 4 + a.robot_id.size() + 1 + 8 + 1;
}

core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::detection_t* out,
                    const OperatorWireLimits& l = {}) {
  return decode_detection(b.data(), b.size(), out, l);
}
core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::operator_command_t* out,
                    const OperatorWireLimits& l = {}) {
  return decode_operator_command(b.data(), b.size(), out, l);
}
core::Status decode(const std::vector<uint8_t>& b, hwr_lcm::command_ack_t* out,
                    const OperatorWireLimits& l = {}) {
  return decode_command_ack(b.data(), b.size(), out, l);
}

bool mentions(const core::Status& st, const std::string& what) {
  return st.message().find(what) != std::string::npos;
}

// --- valid messages --------------------------------------------------------------------------------

TEST(OperatorWire, GivenLcmEncodedDetectionWhenDecodedThenEveryFieldMatches) {
  const hwr_lcm::detection_t d = make_detection(3);
  hwr_lcm::detection_t out = make_detection(9);  // a reused object with more seam points
  ASSERT_TRUE(decode(lcm_encode(d), &out).ok());
  EXPECT_EQ(out.t_ns, d.t_ns);
  EXPECT_EQ(out.robot_id, d.robot_id);
  EXPECT_EQ(out.run_id, d.run_id);
  EXPECT_EQ(out.detection_id, d.detection_id);
  EXPECT_EQ(out.segment_id, d.segment_id);
  EXPECT_EQ(out.keyframe_t_ns, d.keyframe_t_ns);
  EXPECT_EQ(out.source, d.source);
  EXPECT_EQ(out.state, d.state);
  EXPECT_EQ(out.confidence, d.confidence);
  EXPECT_EQ(0, std::memcmp(out.box_px, d.box_px, sizeof d.box_px));
  EXPECT_EQ(0, std::memcmp(out.box_center_world_m, d.box_center_world_m, sizeof d.box_center_world_m));
  EXPECT_EQ(0, std::memcmp(out.box_size_m, d.box_size_m, sizeof d.box_size_m));
  EXPECT_EQ(0, std::memcmp(out.box_q_world_box, d.box_q_world_box, sizeof d.box_q_world_box));
  EXPECT_EQ(out.num_seam_points, 3);
  EXPECT_EQ(out.seam_world_m, d.seam_world_m);
}

TEST(OperatorWire, GivenEachCommandKindWhenDecodedThenFieldsMatch) {
  for (const auto kind : {OperatorCommandKind::kConfirm, OperatorCommandKind::kReject,
                          OperatorCommandKind::kMove, OperatorCommandKind::kAdd}) {
    SCOPED_TRACE(operator_command_kind_name(static_cast<int>(kind)));
    const hwr_lcm::operator_command_t c = make_command(kind);
    hwr_lcm::operator_command_t out;
    const auto bytes = lcm_encode(c);
    ASSERT_TRUE(decode(bytes, &out).ok()) << decode(bytes, &out).message();
    EXPECT_EQ(out.robot_id, c.robot_id);
    EXPECT_EQ(out.command_id, c.command_id);
    EXPECT_EQ(out.kind, c.kind);
    EXPECT_EQ(out.detection_id, c.detection_id);
    EXPECT_EQ(out.keyframe_t_ns, c.keyframe_t_ns);
    EXPECT_EQ(0, std::memcmp(out.box_px, c.box_px, sizeof c.box_px));
    EXPECT_EQ(0, std::memcmp(out.box_size_m, c.box_size_m, sizeof c.box_size_m));
  }
}

TEST(OperatorWire, GivenAcceptedAndRefusedAcksWhenDecodedThenFieldsMatch) {
  for (const bool accepted : {true, false}) {
    const hwr_lcm::command_ack_t a = make_ack(accepted);
    hwr_lcm::command_ack_t out;
    ASSERT_TRUE(decode(lcm_encode(a), &out).ok());
    EXPECT_EQ(out.robot_id, a.robot_id);
    EXPECT_EQ(out.command_id, a.command_id);
    EXPECT_EQ(out.accepted, a.accepted);
    EXPECT_EQ(out.reason, a.reason);
    EXPECT_EQ(out.detection_id, a.detection_id);
  }
}

TEST(OperatorWire, GivenLimitSizedFieldsThenAcceptedAndOneMoreRejected) {
  const OperatorWireLimits limits;
  hwr_lcm::detection_t d = make_detection(limits.max_seam_points);
  d.robot_id = std::string(limits.max_robot_id_bytes, 'r');
  hwr_lcm::detection_t out;
  EXPECT_TRUE(decode(lcm_encode(d), &out).ok());
  d.robot_id += "r";
  EXPECT_EQ(decode(lcm_encode(d), &out).code(), ErrorCode::kOutOfRange);
  d = make_detection(limits.max_seam_points + 1);
  const core::Status st = decode(lcm_encode(d), &out);
  EXPECT_EQ(st.code(), ErrorCode::kOutOfRange);
  EXPECT_TRUE(mentions(st, "num_seam_points")) << st.message();

  hwr_lcm::command_ack_t a = make_ack();
  a.reason = std::string(limits.max_reason_bytes, 'x');
  hwr_lcm::command_ack_t ack_out;
  EXPECT_TRUE(decode(lcm_encode(a), &ack_out).ok());
  a.reason += "x";
  const core::Status ack_st = decode(lcm_encode(a), &ack_out);
  EXPECT_EQ(ack_st.code(), ErrorCode::kOutOfRange);
  EXPECT_TRUE(mentions(ack_st, "reason")) << ack_st.message();
}

// --- rejected while decoding ----------------------------------------------------------------------

template <class Msg>
void expect_every_prefix_rejected(const std::vector<uint8_t>& bytes) {
  Msg out;
  for (size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    const core::Status st = decode(prefix, &out);
    ASSERT_FALSE(st.ok()) << "prefix of " << n << " bytes accepted";
    EXPECT_EQ(st.code(), ErrorCode::kParseError) << n << ": " << st.message();
    EXPECT_FALSE(st.message().empty());
  }
}

TEST(OperatorWire, GivenEveryTruncationThenRejectedAsParseError) {
  expect_every_prefix_rejected<hwr_lcm::detection_t>(lcm_encode(make_detection(2)));
  expect_every_prefix_rejected<hwr_lcm::operator_command_t>(
      lcm_encode(make_command(OperatorCommandKind::kMove)));
  expect_every_prefix_rejected<hwr_lcm::command_ack_t>(lcm_encode(make_ack()));
}

TEST(OperatorWire, GivenHostileSeamCountThenRejectedBeforeAllocating) {
  const auto good = lcm_encode(make_detection(2));
  hwr_lcm::detection_t out;
  for (const int32_t n :
       {std::numeric_limits<int32_t>::max(), -1, std::numeric_limits<int32_t>::min(), 65, 3}) {
    auto b = good;
    put_be32(&b, num_seam_points_at(good, 2), n);
    const core::Status st = decode(b, &out);
    EXPECT_FALSE(st.ok()) << n;
    EXPECT_TRUE(mentions(st, n == 3 ? "seam_world_m" : "num_seam_points")) << n << ": " << st.message();
    // The object was never resized to the claim.
    EXPECT_LE(out.seam_world_m.capacity(), 64u);
  }
}

TEST(OperatorWire, GivenHostileStringLengthsThenRejectedNamingTheField) {
  hwr_lcm::detection_t det_out;
  hwr_lcm::command_ack_t ack_out;
  const auto det = lcm_encode(make_detection());
  for (const int32_t len : {0, -5, std::numeric_limits<int32_t>::max(), 66}) {
    auto b = det;
    put_be32(&b, kRobotIdLengthAt, len);
    const core::Status st = decode(b, &det_out);
    EXPECT_FALSE(st.ok()) << len;
    EXPECT_TRUE(mentions(st, "robot_id")) << st.message();
  }
  const hwr_lcm::command_ack_t a = make_ack();
  const auto ack = lcm_encode(a);
  for (const int32_t len : {0, -1, std::numeric_limits<int32_t>::max(), 100000}) {
    auto b = ack;
    put_be32(&b, reason_length_at(a), len);
    const core::Status st = decode(b, &ack_out);
    EXPECT_FALSE(st.ok()) << len;
    EXPECT_TRUE(mentions(st, "reason")) << st.message();
  }
}

TEST(OperatorWire, GivenStringWithoutItsNulOrWithNulInsideThenParseError) {
  hwr_lcm::detection_t out;
  auto b = lcm_encode(make_detection());  // robot_id "hwr-0": bytes 20..24, NUL at 25
  b[25] = 'x';
  core::Status st = decode(b, &out);
  EXPECT_EQ(st.code(), ErrorCode::kParseError);
  EXPECT_TRUE(mentions(st, "NUL-terminated")) << st.message();
  b = lcm_encode(make_detection());
  b[22] = 0;
  st = decode(b, &out);
  EXPECT_EQ(st.code(), ErrorCode::kParseError);
  EXPECT_TRUE(mentions(st, "NUL byte")) << st.message();
}

TEST(OperatorWire, GivenLeftoverBytesThenParseError) {
  auto det = lcm_encode(make_detection());
  det.push_back(0);
  hwr_lcm::detection_t d;
  EXPECT_TRUE(mentions(decode(det, &d), "unexpected bytes"));
  auto cmd = lcm_encode(make_command(OperatorCommandKind::kReject));
  cmd.insert(cmd.end(), 8, 0);
  hwr_lcm::operator_command_t c;
  EXPECT_EQ(decode(cmd, &c).code(), ErrorCode::kParseError);
  auto ack = lcm_encode(make_ack());
  ack.push_back(1);
  hwr_lcm::command_ack_t a;
  EXPECT_EQ(decode(ack, &a).code(), ErrorCode::kParseError);
}

TEST(OperatorWire, GivenAnotherTypesMessageThenWrongFingerprint) {
  hwr_lcm::detection_t d;
  hwr_lcm::operator_command_t c;
  hwr_lcm::command_ack_t a;
  const core::Status st = decode(lcm_encode(make_command(OperatorCommandKind::kConfirm)), &d);
  EXPECT_EQ(st.code(), ErrorCode::kParseError);
  EXPECT_TRUE(mentions(st, "not a detection_t")) << st.message();
  EXPECT_TRUE(mentions(decode(lcm_encode(make_ack()), &c), "fingerprint"));
  EXPECT_TRUE(mentions(decode(lcm_encode(make_detection()), &a), "fingerprint"));
}

TEST(OperatorWire, GivenOversizedMessageThenOutOfRangeBeforeParsing) {
  OperatorWireLimits small;
  small.max_message_bytes = 100;
  hwr_lcm::detection_t d;
  const auto bytes = lcm_encode(make_detection(8));
  ASSERT_GT(bytes.size(), 100u);
  EXPECT_EQ(decode(bytes, &d, small).code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(decode_detection(nullptr, 0, &d).code(), ErrorCode::kParseError);
  EXPECT_EQ(decode_detection(nullptr, 10, &d).code(), ErrorCode::kInvalidArgument);
}

// --- validation -----------------------------------------------------------------------------------

template <class Msg, class Mutate>
core::Status decode_mutated(Msg m, Mutate&& mutate) {
  mutate(m);
  Msg out;
  return decode(lcm_encode(m), &out);
}

TEST(OperatorWire, GivenDetectionOutsideItsRangesThenEachRejectedWithItsCode) {
  const auto d = make_detection();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    const char* what;
    ErrorCode code;
    std::function<void(hwr_lcm::detection_t&)> mutate;
  };
  const std::vector<Case> cases = {
      {"source", ErrorCode::kOutOfRange, [](auto& m) { m.source = 3; }},
      {"source", ErrorCode::kOutOfRange, [](auto& m) { m.source = -1; }},
      {"state", ErrorCode::kOutOfRange, [](auto& m) { m.state = 3; }},
      {"confidence", ErrorCode::kOutOfRange, [](auto& m) { m.confidence = 1.01f; }},
      {"confidence", ErrorCode::kOutOfRange, [](auto& m) { m.confidence = -0.01f; }},
      {"confidence", ErrorCode::kInvalidArgument, [](auto& m) { m.confidence = std::nanf(""); }},
      {"box_px[2]", ErrorCode::kInvalidArgument, [](auto& m) { m.box_px[2] = INFINITY; }},
      {"box_px", ErrorCode::kOutOfRange, [](auto& m) { m.box_px[3] = -1; }},
      {"box_center_world_m[1]", ErrorCode::kInvalidArgument, [&](auto& m) { m.box_center_world_m[1] = nan; }},
      {"box_size_m", ErrorCode::kOutOfRange, [](auto& m) { m.box_size_m[2] = -0.01; }},
      {"box_q_world_box", ErrorCode::kInvalidArgument, [](auto& m) { m.box_q_world_box[0] *= 1.01; }},
      {"box_q_world_box", ErrorCode::kInvalidArgument,
       [](auto& m) { m.box_q_world_box[0] = m.box_q_world_box[3] = 0; }},
      {"box_q_world_box[3]", ErrorCode::kInvalidArgument, [&](auto& m) { m.box_q_world_box[3] = nan; }},
      {"seam_world_m[1]", ErrorCode::kInvalidArgument, [&](auto& m) { m.seam_world_m[1][2] = -INFINITY; }},
      {"detection_id", ErrorCode::kOutOfRange, [](auto& m) { m.detection_id = -1; }},
      {"robot_id", ErrorCode::kInvalidArgument, [](auto& m) { m.robot_id = "../x"; }},
      {"robot_id", ErrorCode::kInvalidArgument, [](auto& m) { m.robot_id = "hwr 0"; }},
      {"robot_id is empty", ErrorCode::kOutOfRange, [](auto& m) { m.robot_id = ""; }},
  };
  for (const Case& c : cases) {
    const core::Status st = decode_mutated(d, c.mutate);
    EXPECT_EQ(st.code(), c.code) << c.what << ": " << st.to_string();
    EXPECT_TRUE(mentions(st, c.what)) << c.what << ": " << st.message();
  }
  // Inside the tolerances: a quaternion 5e-4 off unit length, confidence at both ends, zero sizes.
  EXPECT_TRUE(decode_mutated(d, [](auto& m) { m.box_q_world_box[0] *= 1.0005; }).ok());
  EXPECT_TRUE(decode_mutated(d, [](auto& m) { m.confidence = 0; }).ok());
  EXPECT_TRUE(decode_mutated(d, [](auto& m) { m.confidence = 1; }).ok());
  EXPECT_TRUE(decode_mutated(d, [](auto& m) {
                for (double& s : m.box_size_m) s = 0;
                m.num_seam_points = 0;
                m.seam_world_m.clear();
              }).ok());
}

TEST(OperatorWire, GivenCommandOutsideItsRangesThenEachRejectedWithItsCode) {
  using K = OperatorCommandKind;
  struct Case {
    const char* what;
    K kind;
    ErrorCode code;
    std::function<void(hwr_lcm::operator_command_t&)> mutate;
  };
  const std::vector<Case> cases = {
      {"kind 4", K::kConfirm, ErrorCode::kOutOfRange, [](auto& m) { m.kind = 4; }},
      {"kind -1", K::kConfirm, ErrorCode::kOutOfRange, [](auto& m) { m.kind = -1; }},
      {"command_id", K::kReject, ErrorCode::kOutOfRange, [](auto& m) { m.command_id = -3; }},
      {"detection_id", K::kReject, ErrorCode::kOutOfRange, [](auto& m) { m.detection_id = -1; }},
      {"detection_id", K::kMove, ErrorCode::kOutOfRange, [](auto& m) { m.detection_id = -1; }},
      // Ignored by confirm, but a NaN there is an unset field: still rejected.
      {"box_size_m[0]", K::kConfirm, ErrorCode::kInvalidArgument, [](auto& m) { m.box_size_m[0] = NAN; }},
      {"move needs box_size_m > 0", K::kMove, ErrorCode::kOutOfRange, [](auto& m) { m.box_size_m[1] = 0; }},
      {"box_q_world_box", K::kMove, ErrorCode::kInvalidArgument, [](auto& m) { m.box_q_world_box[0] = 0.5; }},
      {"box_center_world_m[2]", K::kMove, ErrorCode::kInvalidArgument,
       [](auto& m) { m.box_center_world_m[2] = INFINITY; }},
      {"add needs box_px", K::kAdd, ErrorCode::kOutOfRange, [](auto& m) { m.box_px[2] = 0; }},
      {"add needs box_px", K::kAdd, ErrorCode::kOutOfRange, [](auto& m) { m.box_px[3] = -4; }},
      {"add needs box_px", K::kAdd, ErrorCode::kOutOfRange, [](auto& m) { m.box_px[0] = -1; }},
      {"add's world box", K::kAdd, ErrorCode::kOutOfRange, [](auto& m) { m.box_size_m[0] = 0.1; }},
      {"box_q_world_box", K::kAdd, ErrorCode::kInvalidArgument,
       [](auto& m) {
         for (double& s : m.box_size_m) s = 0.1;
         m.box_q_world_box[0] = 2;
       }},
      {"robot_id", K::kAdd, ErrorCode::kInvalidArgument, [](auto& m) { m.robot_id = "a.b"; }},
  };
  for (const Case& c : cases) {
    const core::Status st = decode_mutated(make_command(c.kind), c.mutate);
    EXPECT_EQ(st.code(), c.code) << c.what << ": " << st.to_string();
    EXPECT_TRUE(mentions(st, c.what)) << c.what << ": " << st.message();
  }
  // Add with a world box, and confirm whose (ignored) box is anything finite.
  EXPECT_TRUE(decode_mutated(make_command(K::kAdd), [](auto& m) {
                for (double& s : m.box_size_m) s = 0.1;
              }).ok());
  EXPECT_TRUE(decode_mutated(make_command(K::kConfirm), [](auto& m) { m.box_q_world_box[0] = 0; }).ok());
}

TEST(OperatorWire, GivenAckOutsideItsRangesThenRejected) {
  const auto a = make_ack();
  EXPECT_EQ(decode_mutated(a, [](auto& m) { m.accepted = 2; }).code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(decode_mutated(a, [](auto& m) { m.accepted = -1; }).code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(decode_mutated(a, [](auto& m) { m.command_id = -1; }).code(), ErrorCode::kOutOfRange);
  EXPECT_EQ(decode_mutated(a, [](auto& m) { m.robot_id = "x/y"; }).code(), ErrorCode::kInvalidArgument);
  // The detection id of a refused command may be anything (there may be none).
  EXPECT_TRUE(decode_mutated(a, [](auto& m) { m.detection_id = -1; }).ok());
}

TEST(OperatorWire, GivenInconsistentDetectionThenEncodeRefusesInsteadOfReadingPastTheVector) {
  hwr_lcm::detection_t d = make_detection(2);
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_detection(d, &bytes).ok());
  hwr_lcm::detection_t out;
  ASSERT_TRUE(decode(bytes, &out).ok());
  d.num_seam_points = 5;  // LCM's encode() would read 3 rows that do not exist
  EXPECT_EQ(encode_detection(d, &bytes).code(), ErrorCode::kInvalidArgument);
  d = make_detection(2);
  d.seam_world_m[1].pop_back();
  EXPECT_EQ(encode_detection(d, &bytes).code(), ErrorCode::kInvalidArgument);
  hwr_lcm::operator_command_t c = make_command(OperatorCommandKind::kMove);
  c.box_size_m[0] = 0;
  EXPECT_EQ(encode_operator_command(c, &bytes).code(), ErrorCode::kOutOfRange);
  hwr_lcm::command_ack_t a = make_ack();
  a.reason = std::string("a\0b", 3);
  EXPECT_EQ(encode_command_ack(a, &bytes).code(), ErrorCode::kInvalidArgument);
}

TEST(OperatorWire, EnumNames) {
  EXPECT_STREQ(operator_command_kind_name(0), "confirm");
  EXPECT_STREQ(operator_command_kind_name(1), "reject");
  EXPECT_STREQ(operator_command_kind_name(2), "move");
  EXPECT_STREQ(operator_command_kind_name(3), "add");
  EXPECT_STREQ(operator_command_kind_name(4), "unknown");
  EXPECT_STREQ(detection_state_name(0), "proposed");
  EXPECT_STREQ(detection_state_name(1), "confirmed");
  EXPECT_STREQ(detection_state_name(2), "rejected");
  EXPECT_STREQ(detection_state_name(-1), "unknown");
  EXPECT_STREQ(detection_source_name(2), "operator");
}

// --- random damage --------------------------------------------------------------------------------

// Flips 1..8 random bits (sometimes a whole byte to 0xFF, sometimes truncates or extends) and decodes.
// Never a crash or a sanitizer report; a message that still decodes is a valid one, so LCM's encoder
// gives back exactly the bytes decoded.
template <class Msg>
void bit_flip_loop(const std::vector<uint8_t>& good, uint32_t seed, int iterations) {
  std::mt19937 rng(seed);
  Msg out;
  int accepted = 0;
  for (int it = 0; it < iterations; ++it) {
    std::vector<uint8_t> b = good;
    const int flips = 1 + static_cast<int>(rng() % 8);
    for (int f = 0; f < flips; ++f) {
      const size_t at = rng() % b.size();
      if (rng() % 8 == 0) {
        b[at] = 0xFF;
      } else {
        b[at] ^= static_cast<uint8_t>(1u << (rng() % 8));
      }
    }
    if (rng() % 16 == 0) b.resize(rng() % (b.size() + 16), 0x5A);
    const core::Status st = decode(b, &out);
    if (!st.ok()) {
      ASSERT_FALSE(st.message().empty());
      continue;
    }
    ++accepted;
    ASSERT_EQ(lcm_encode(out), b) << "iteration " << it;
  }
  // Flips in t_ns and ids leave valid messages: the loop also covered the accepting path.
  EXPECT_GT(accepted, 0);
}

TEST(OperatorWire, GivenRandomBitFlipsThenNeverCrashesAndAcceptedMessagesRoundTrip) {
  bit_flip_loop<hwr_lcm::detection_t>(lcm_encode(make_detection(4)), 1, 20000);
  bit_flip_loop<hwr_lcm::operator_command_t>(lcm_encode(make_command(OperatorCommandKind::kMove)), 2, 20000);
  bit_flip_loop<hwr_lcm::operator_command_t>(lcm_encode(make_command(OperatorCommandKind::kAdd)), 3, 20000);
  bit_flip_loop<hwr_lcm::command_ack_t>(lcm_encode(make_ack()), 4, 20000);
}

}  // namespace
}  // namespace hwr::mapio
