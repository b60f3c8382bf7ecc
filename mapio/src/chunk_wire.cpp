#include "hwr/mapio/chunk_wire.hpp"

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "lcm_reader.hpp"

namespace hwr::mapio {
namespace {

using detail::BeReader;
using detail::encode_lcm;

// Little-endian writer into a fixed buffer (the canonical CRC form, chunk_wire.hpp).
class LeWriter {
 public:
  void u8(uint8_t v) { buf_[n_++] = v; }
  void u32(uint32_t v) {
    for (int i = 0; i < 4; ++i) buf_[n_++] = static_cast<uint8_t>(v >> (8 * i));
  }
  void u64(uint64_t v) {
    for (int i = 0; i < 8; ++i) buf_[n_++] = static_cast<uint8_t>(v >> (8 * i));
  }
  void i32(int32_t v) { u32(static_cast<uint32_t>(v)); }
  void i64(int64_t v) { u64(static_cast<uint64_t>(v)); }
  void f32(float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    u32(bits);
  }
  void f64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    u64(bits);
  }
  const uint8_t* data() const { return buf_; }
  size_t size() const { return n_; }
  // Room for at least this many more bytes.
  size_t room() const { return sizeof(buf_) - n_; }
  void clear() { n_ = 0; }

 private:
  // The fixed fields after robot_id: 8+8+4+4+4+1+4+12*8+4+1+4+4 = 142 bytes.
  uint8_t buf_[160];
  size_t n_ = 0;
};

uint32_t crc_update(uint32_t crc, const uint8_t* data, size_t size) {
  // zlib's crc32() takes uInt lengths; feed in bounded pieces.
  while (size > 0) {
    const size_t piece = size < (1u << 30) ? size : (1u << 30);
    crc = static_cast<uint32_t>(::crc32(crc, data, static_cast<uInt>(piece)));
    data += piece;
    size -= piece;
  }
  return crc;
}

std::string seq_text(int64_t v) { return std::to_string(v); }

core::Status check_robot_id(const std::string& robot_id, const ChunkWireLimits& limits, const char* what) {
  if (robot_id.empty()) return core::OutOfRange(std::string(what) + ": robot_id is empty");
  if (robot_id.size() > limits.max_robot_id_bytes) {
    return core::OutOfRange(std::string(what) + ": robot_id has " + std::to_string(robot_id.size()) +
                            " bytes, more than the limit of " + std::to_string(limits.max_robot_id_bytes));
  }
  if (robot_id.find('\0') != std::string::npos) {
    return core::InvalidArgument(std::string(what) + ": robot_id contains a NUL byte");
  }
  return core::Status::Ok();
}

core::Status check_message_size(const uint8_t* data, size_t size, const ChunkWireLimits& limits,
                                const char* type) {
  return detail::check_message_size(data, size, limits.max_message_bytes, type);
}

bool is_flag(int8_t v) { return v == 0 || v == 1; }

// CRC32 start value followed by robot_id as the canonical forms begin (uint32 length, bytes).
uint32_t crc_of_robot_id(const std::string& robot_id) {
  uint32_t crc = static_cast<uint32_t>(::crc32(0L, Z_NULL, 0));
  uint8_t id_len[4];
  const uint32_t n = static_cast<uint32_t>(robot_id.size());
  for (int i = 0; i < 4; ++i) id_len[i] = static_cast<uint8_t>(n >> (8 * i));
  crc = crc_update(crc, id_len, 4);
  return crc_update(crc, reinterpret_cast<const uint8_t*>(robot_id.data()), robot_id.size());
}

}  // namespace

uint32_t chunk_crc32(const hwr_lcm::map_chunk_t& c) {
  uint32_t crc = crc_of_robot_id(c.robot_id);

  LeWriter w;
  w.i64(c.run_id);
  w.i64(c.link_seq);
  w.i32(c.segment_id);
  w.i32(c.segment_version);
  w.i32(c.chunk_index);
  w.u8(static_cast<uint8_t>(c.segment_complete));
  w.i32(c.chunk_count);
  for (double v : c.T_world_segment) w.f64(v);
  w.i32(c.num_points);
  w.u8(static_cast<uint8_t>(c.has_normals));
  w.f32(c.max_position_error_m);
  w.i32(c.payload_size);
  crc = crc_update(crc, w.data(), w.size());
  return crc_update(crc, c.payload.data(), c.payload.size());
}

void seal_chunk(hwr_lcm::map_chunk_t* chunk) {
  chunk->payload_size = static_cast<int32_t>(chunk->payload.size());
  chunk->crc32 = static_cast<int64_t>(chunk_crc32(*chunk));
}

uint32_t ack_crc32(const hwr_lcm::chunk_ack_t& a) {
  uint32_t crc = crc_of_robot_id(a.robot_id);
  LeWriter w;
  w.i64(a.run_id);
  w.i64(a.cumulative_seq);
  w.i32(a.num_selective);
  // selective.size() values, fed through the fixed buffer in pieces (no allocation).
  for (int64_t v : a.selective) {
    if (w.room() < 8) {
      crc = crc_update(crc, w.data(), w.size());
      w.clear();
    }
    w.i64(v);
  }
  if (w.room() < 1) {
    crc = crc_update(crc, w.data(), w.size());
    w.clear();
  }
  w.u8(static_cast<uint8_t>(a.resume_report));
  return crc_update(crc, w.data(), w.size());
}

void seal_ack(hwr_lcm::chunk_ack_t* ack) {
  ack->num_selective = static_cast<int32_t>(ack->selective.size());
  ack->crc32 = static_cast<int64_t>(ack_crc32(*ack));
}

core::Status verify_chunk(const hwr_lcm::map_chunk_t& c, const ChunkWireLimits& limits) {
  const std::string where = "chunk link_seq " + seq_text(c.link_seq) + " (segment " +
                            std::to_string(c.segment_id) + " v" + std::to_string(c.segment_version) +
                            " chunk " + std::to_string(c.chunk_index) + ")";
  // Sizes first: the CRC is computed over payload.size() bytes whatever payload_size says.
  if (c.payload_size < 0 || static_cast<size_t>(c.payload_size) != c.payload.size()) {
    return core::CorruptData(where + ": payload_size " + std::to_string(c.payload_size) + " but " +
                             std::to_string(c.payload.size()) + " payload bytes");
  }
  // The CRC next: a chunk damaged in transit is reported as such, not by whichever field broke.
  if (c.crc32 < 0 || c.crc32 > 0xFFFFFFFFll) {
    return core::CorruptData(where + ": crc32 field " + std::to_string(c.crc32) + " is not a 32-bit value");
  }
  const uint32_t crc = chunk_crc32(c);
  if (crc != static_cast<uint32_t>(c.crc32)) {
    return core::CorruptData(where + ": CRC32 mismatch (computed " + std::to_string(crc) + ", message says " +
                             std::to_string(c.crc32) + "): damaged in transit or not sealed by the sender");
  }
  // Then what a correctly sealed but wrong chunk (a sender bug, a hostile peer) could carry.
  HWR_RETURN_IF_ERROR(check_robot_id(c.robot_id, limits, where.c_str()));
  if (c.run_id < 0 || c.link_seq < 0 || c.segment_id < 0 || c.segment_version < 0 || c.chunk_index < 0 ||
      c.chunk_count < 0) {
    return core::OutOfRange(where + ": negative id (run_id " + seq_text(c.run_id) + ", chunk_count " +
                            std::to_string(c.chunk_count) + "); all ids and counts must be >= 0");
  }
  // The one chunk without points: a segment's completing chunk when nothing was left to send
  // (num_points 0, no payload, segment_complete 1).
  const bool empty_completion = c.num_points == 0 && c.payload.empty() && c.segment_complete == 1;
  if (!empty_completion && (c.payload.empty() || c.payload.size() > limits.max_payload_bytes)) {
    return core::OutOfRange(where + ": payload of " + std::to_string(c.payload.size()) +
                            " bytes, allowed 1.." + std::to_string(limits.max_payload_bytes));
  }
  if (!empty_completion && (c.num_points < 1 || c.num_points > limits.max_points)) {
    return core::OutOfRange(where + ": num_points " + std::to_string(c.num_points) + ", allowed 1.." +
                            std::to_string(limits.max_points));
  }
  if (!is_flag(c.segment_complete) || !is_flag(c.has_normals)) {
    return core::InvalidArgument(where + ": segment_complete " + std::to_string(c.segment_complete) +
                                 " / has_normals " + std::to_string(c.has_normals) + " must be 0 or 1");
  }
  if (c.segment_complete == 1 && c.chunk_index >= c.chunk_count) {
    return core::InvalidArgument(where + ": last chunk of a complete segment has chunk_index " +
                                 std::to_string(c.chunk_index) + " >= chunk_count " +
                                 std::to_string(c.chunk_count));
  }
  if (!std::isfinite(c.max_position_error_m) || c.max_position_error_m < 0) {
    return core::InvalidArgument(where + ": max_position_error_m " + std::to_string(c.max_position_error_m) +
                                 " must be finite and >= 0");
  }
  // T_world_segment = [R | t] row by row: R must be a rotation (R^T R = I, det R = +1).
  const double* T = c.T_world_segment;
  for (int i = 0; i < 12; ++i) {
    if (!std::isfinite(T[i])) {
      return core::InvalidArgument(where + ": T_world_segment[" + std::to_string(i) + "] is not finite");
    }
  }
  auto R = [T](int r, int k) { return T[4 * r + k]; };
  constexpr double kRotationTol = 1e-6;
  double max_dev = 0;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      double dot = 0;
      for (int r = 0; r < 3; ++r) dot += R(r, a) * R(r, b);
      max_dev = std::fmax(max_dev, std::fabs(dot - (a == b ? 1.0 : 0.0)));
    }
  }
  const double det = R(0, 0) * (R(1, 1) * R(2, 2) - R(1, 2) * R(2, 1)) -
                     R(0, 1) * (R(1, 0) * R(2, 2) - R(1, 2) * R(2, 0)) +
                     R(0, 2) * (R(1, 0) * R(2, 1) - R(1, 1) * R(2, 0));
  if (max_dev > kRotationTol || std::fabs(det - 1.0) > kRotationTol) {
    return core::InvalidArgument(
        where + ": T_world_segment is not a rotation (max |R^T R - I| = " + std::to_string(max_dev) +
        ", det R = " + std::to_string(det) + ", tolerance 1e-6)");
  }
  return core::Status::Ok();
}

core::Status verify_ack(const hwr_lcm::chunk_ack_t& a, const ChunkWireLimits& limits) {
  if (a.num_selective < 0 || static_cast<size_t>(a.num_selective) != a.selective.size()) {
    return core::InvalidArgument("chunk_ack_t: num_selective " + std::to_string(a.num_selective) + " but " +
                                 std::to_string(a.selective.size()) + " selective values");
  }
  // The CRC before the ranges, as for chunks: damage in transit is reported as such.
  if (a.crc32 < 0 || a.crc32 > 0xFFFFFFFFll) {
    return core::CorruptData("chunk_ack_t: crc32 field " + std::to_string(a.crc32) +
                             " is not a 32-bit value");
  }
  const uint32_t crc = ack_crc32(a);
  if (crc != static_cast<uint32_t>(a.crc32)) {
    return core::CorruptData("chunk_ack_t (cumulative_seq " + seq_text(a.cumulative_seq) +
                             "): CRC32 mismatch (computed " + std::to_string(crc) + ", message says " +
                             std::to_string(a.crc32) + "): damaged in transit or not sealed by the sender");
  }
  HWR_RETURN_IF_ERROR(check_robot_id(a.robot_id, limits, "chunk_ack_t"));
  if (a.run_id < 0) return core::OutOfRange("chunk_ack_t: run_id " + seq_text(a.run_id) + " < 0");
  if (a.cumulative_seq < -1) {
    return core::OutOfRange("chunk_ack_t: cumulative_seq " + seq_text(a.cumulative_seq) + " < -1");
  }
  if (a.num_selective > limits.max_selective) {
    return core::OutOfRange("chunk_ack_t: " + std::to_string(a.num_selective) +
                            " selective values, more than the limit of " +
                            std::to_string(limits.max_selective));
  }
  for (int64_t s : a.selective) {
    if (s <= a.cumulative_seq) {
      return core::OutOfRange("chunk_ack_t: selective value " + seq_text(s) +
                              " is not above cumulative_seq " + seq_text(a.cumulative_seq));
    }
  }
  if (!is_flag(a.resume_report)) {
    return core::InvalidArgument("chunk_ack_t: resume_report " + std::to_string(a.resume_report) +
                                 " must be 0 or 1");
  }
  return core::Status::Ok();
}

core::Status decode_chunk_message(const uint8_t* data, size_t size, hwr_lcm::map_chunk_t* out,
                                  const ChunkWireLimits& limits) {
  constexpr const char* kType = "map_chunk_t";
  HWR_RETURN_IF_ERROR(check_message_size(data, size, limits, kType));
  // Walk the encoding (map_chunk_t.lcm order) and bound every length before LCM sees it.
  BeReader r(data, size, kType);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::map_chunk_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  // run_id, link_seq, segment_id, segment_version, chunk_index, segment_complete, chunk_count,
  // T_world_segment, num_points, has_normals, max_position_error_m.
  HWR_RETURN_IF_ERROR(r.skip(8 + 8 + 4 + 4 + 4 + 1 + 4 + 12 * 8 + 4 + 1 + 4, "header fields"));
  const size_t payload_size_at = r.pos();
  int32_t payload_size = 0;
  HWR_RETURN_IF_ERROR(r.i32(&payload_size, "payload_size"));
  if (payload_size < 0 || static_cast<size_t>(payload_size) > limits.max_payload_bytes) {
    return core::OutOfRange("map_chunk_t: payload_size " + std::to_string(payload_size) + " at offset " +
                            std::to_string(payload_size_at) + ", allowed 0.." +
                            std::to_string(limits.max_payload_bytes));
  }
  HWR_RETURN_IF_ERROR(r.skip(static_cast<size_t>(payload_size), "payload"));
  HWR_RETURN_IF_ERROR(r.skip(8, "crc32"));
  HWR_RETURN_IF_ERROR(r.check_end());

  // LCM leaves a vector untouched when its length field is 0: clear what a reused `out` held.
  out->payload.clear();
  return detail::decode_walked(data, size, kType, out);
}

core::Status decode_ack_message(const uint8_t* data, size_t size, hwr_lcm::chunk_ack_t* out,
                                const ChunkWireLimits& limits) {
  constexpr const char* kType = "chunk_ack_t";
  HWR_RETURN_IF_ERROR(check_message_size(data, size, limits, kType));
  BeReader r(data, size, kType);
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::chunk_ack_t::getHash()));
  HWR_RETURN_IF_ERROR(r.skip(8, "t_ns"));
  HWR_RETURN_IF_ERROR(r.string(limits.max_robot_id_bytes, "robot_id"));
  HWR_RETURN_IF_ERROR(r.skip(8 + 8, "run_id, cumulative_seq"));
  const size_t num_at = r.pos();
  int32_t num_selective = 0;
  HWR_RETURN_IF_ERROR(r.i32(&num_selective, "num_selective"));
  if (num_selective < 0 || num_selective > limits.max_selective) {
    return core::OutOfRange("chunk_ack_t: num_selective " + std::to_string(num_selective) + " at offset " +
                            std::to_string(num_at) + ", allowed 0.." + std::to_string(limits.max_selective));
  }
  HWR_RETURN_IF_ERROR(r.skip(8 * static_cast<size_t>(num_selective), "selective"));
  HWR_RETURN_IF_ERROR(r.skip(1, "resume_report"));
  HWR_RETURN_IF_ERROR(r.skip(8, "crc32"));
  HWR_RETURN_IF_ERROR(r.check_end());

  out->selective.clear();
  return detail::decode_walked(data, size, kType, out);
}

core::Status encode_chunk_message(const hwr_lcm::map_chunk_t& chunk, std::vector<uint8_t>* out) {
  // LCM encodes robot_id up to its first NUL but sizes it by size(): they must agree.
  if (chunk.robot_id.find('\0') != std::string::npos) {
    return core::InvalidArgument("map_chunk_t: robot_id contains a NUL byte");
  }
  if (chunk.payload_size < 0 || static_cast<size_t>(chunk.payload_size) != chunk.payload.size()) {
    return core::InvalidArgument("map_chunk_t: payload_size " + std::to_string(chunk.payload_size) + " but " +
                                 std::to_string(chunk.payload.size()) +
                                 " payload bytes (seal_chunk sets it)");
  }
  return encode_lcm(chunk, "map_chunk_t", out);
}

core::Status encode_ack_message(const hwr_lcm::chunk_ack_t& ack, std::vector<uint8_t>* out) {
  if (ack.robot_id.find('\0') != std::string::npos) {
    return core::InvalidArgument("chunk_ack_t: robot_id contains a NUL byte");
  }
  if (ack.num_selective < 0 || static_cast<size_t>(ack.num_selective) != ack.selective.size()) {
    return core::InvalidArgument("chunk_ack_t: num_selective " + std::to_string(ack.num_selective) + " but " +
                                 std::to_string(ack.selective.size()) + " selective values");
  }
  return encode_lcm(ack, "chunk_ack_t", out);
}

}  // namespace hwr::mapio
