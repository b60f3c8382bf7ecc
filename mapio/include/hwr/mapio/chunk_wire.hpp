#pragma once
// The wire rules of a map chunk (issue #5 item 3): its CRC32, the checks a receiver runs before it
// trusts a chunk, and LCM decoding that cannot be made to allocate by a hostile length field.
//
// CRC32 (zlib / IEEE 802.3 polynomial 0xEDB88320, init and final xor 0xFFFFFFFF) of a map_chunk_t
// is computed over this canonical byte string, every integer and float little-endian, the fields
// in their map_chunk_t.lcm order, leaving out t_ns (a resend keeps the CRC while the transport may
// restamp the time) and crc32 itself:
//   robot_id               uint32 byte length, then the bytes (no terminating NUL)
//   run_id, link_seq       int64 each
//   segment_id, segment_version, chunk_index        int32 each
//   segment_complete       int8
//   chunk_count            int32
//   T_world_segment[0..11] IEEE-754 binary64 bit patterns
//   num_points             int32
//   has_normals            int8
//   max_position_error_m   IEEE-754 binary32 bit pattern
//   payload_size           int32
//   payload                payload.size() bytes
// The canonical form is independent of LCM's big-endian encoding, so a stored chunk can be checked
// without LCM. The message's crc32 field holds the value as a non-negative int64 (0 .. 2^32-1).
//
// An acknowledgement (chunk_ack_t) is sealed the same way (same CRC32, same conventions), over the
// fields in their chunk_ack_t.lcm order, leaving out t_ns (stamped when sent) and crc32:
//   robot_id               uint32 byte length, then the bytes (no terminating NUL)
//   run_id, cumulative_seq int64 each
//   num_selective          int32
//   selective[0..]         int64 each, selective.size() values
//   resume_report          int8
// A damaged ack that still decoded would otherwise release chunks the ground station never stored.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/chunk_ack_t.hpp"
#include "hwr_lcm/map_chunk_t.hpp"

namespace hwr::mapio {

// What a receiver accepts. The defaults fit the codec's chunks (<= 1 MiB, <= 2^20 points) with
// margin; a message over a limit is rejected before anything is allocated for it.
struct ChunkWireLimits {
  size_t max_message_bytes = 8u << 20;  // a whole LCM-encoded message
  size_t max_payload_bytes = 4u << 20;  // map_chunk_t.payload
  int max_points = 1 << 20;             // map_chunk_t.num_points
  size_t max_robot_id_bytes = 64;       // robot_id, without LCM's terminating NUL
  int max_selective = 4096;             // chunk_ack_t.num_selective
};

// CRC32 of the canonical serialization above.
uint32_t chunk_crc32(const hwr_lcm::map_chunk_t& chunk);
// Sets chunk->payload_size = payload.size() and chunk->crc32 = chunk_crc32(*chunk).
void seal_chunk(hwr_lcm::map_chunk_t* chunk);
// CRC32 of an ack's canonical serialization above.
uint32_t ack_crc32(const hwr_lcm::chunk_ack_t& ack);
// Sets ack->num_selective = selective.size() and ack->crc32 = ack_crc32(*ack). Every ack sent is
// sealed (AckTracker::make_ack does it); t_ns may be stamped afterwards.
void seal_ack(hwr_lcm::chunk_ack_t* ack);

// A received chunk is trusted only when this returns OK. kCorruptData: CRC mismatch or payload_size
// != payload.size(); kOutOfRange: a count, size or id outside its range, robot_id empty or too long;
// kInvalidArgument: T_world_segment not finite or not a rotation (|R^T R - I| and |det R - 1| within
// 1e-6), a flag not 0/1, chunk_index >= chunk_count on a segment_complete chunk. The one chunk
// allowed without points or payload is a segment's empty completing chunk (segment_complete 1).
core::Status verify_chunk(const hwr_lcm::map_chunk_t& chunk, const ChunkWireLimits& limits);
// Same for an acknowledgement, in this order: kInvalidArgument when num_selective !=
// selective.size(); kCorruptData on a CRC mismatch (or a crc32 field outside 0 .. 2^32-1); then
// robot_id as above, run_id >= 0, cumulative_seq >= -1, num_selective <= max_selective, every
// selective value > cumulative_seq, resume_report 0/1.
core::Status verify_ack(const hwr_lcm::chunk_ack_t& ack, const ChunkWireLimits& limits);

// LCM decoding with every length field (robot_id, payload_size, num_selective) checked against the
// bytes actually present and against `limits` first: LCM 1.3.1's generated decode() resizes a vector
// to whatever a length field claims and mishandles a string length <= 0. Also rejected: the wrong
// type fingerprint, a robot_id with a NUL inside or without its terminating NUL, bytes left over
// after the message. `out` is overwritten (vectors keep their capacity); on error its contents are
// unspecified. kParseError / kOutOfRange with the offending field and offset in the message.
// Decoding does not verify: call verify_chunk / verify_ack afterwards.
core::Status decode_chunk_message(const uint8_t* data, size_t size, hwr_lcm::map_chunk_t* out,
                                  const ChunkWireLimits& limits = {});
core::Status decode_ack_message(const uint8_t* data, size_t size, hwr_lcm::chunk_ack_t* out,
                                const ChunkWireLimits& limits = {});

// LCM encoding into `out` (resized to the message; capacity kept). kInvalidArgument when the message
// is inconsistent (payload_size != payload.size(), num_selective != selective.size()) or too large
// for LCM's int sizes. Encoding does not seal: call seal_chunk / seal_ack first.
core::Status encode_chunk_message(const hwr_lcm::map_chunk_t& chunk, std::vector<uint8_t>* out);
core::Status encode_ack_message(const hwr_lcm::chunk_ack_t& ack, std::vector<uint8_t>* out);

}  // namespace hwr::mapio
