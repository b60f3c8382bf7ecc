#pragma once
// The map store's two binary files (map_store.hpp), little-endian, each a 48-byte header and a
// payload:
//
//   keyframes.bin header                       cloud.bin header
//    0  char[8] magic "HWRKF001"                0  char[8] magic "HWRPC001"
//    8  u32 version (1)                         8  u32 version (1)
//   12  u32 header bytes (48)                  12  u32 header bytes (48)
//   16  u32 keyframe count                     16  u32 bytes per point (16)
//   20  u32 descriptor bytes per feature       20  u32 reserved (0)
//   24  u64 feature count (all keyframes)      24  u64 point count
//   32  u64 payload bytes                      32  u64 payload bytes
//   40  u32 CRC32 of the payload               40  u32 CRC32 of the payload
//   44  u32 CRC32 of header bytes 0..43        44  u32 CRC32 of header bytes 0..43
//
// keyframes.bin payload, per keyframe in order: a 168-byte record
//    0 i32 id, 4 u32 feature count n, 8 i64 t_ns, 16 f64[12] T_world_cam rows of [R | t],
//  112 u8 gnss_valid, 113 u8 mag_valid, 114 6 zero bytes, 120 f64 lat_deg, lon_deg, alt_m,
//  144 f64[3] mag_imu_uT,
// then n features of 16 bytes (f32 u_px, v_px, depth_m, u8 octave, 3 zero bytes), then n *
// descriptor-bytes descriptor bytes.
// cloud.bin payload: point count CloudPoints of 16 bytes (f32 x_m, y_m, z_m, u8 r, g, b, flags).
//
// Poses are the 12 doubles of the 3x4 matrix, so they round-trip bit-exactly. CRC32 is zlib's
// (ISO-HDLC / IEEE 802.3, reflected polynomial 0xEDB88320).
// Readers validate magic, header CRC, version, the payload size against the file length and the
// counts against the payload size before allocating anything, then the payload CRC, then every
// record while parsing; any failure is kCorruptData naming the file.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/map_store.hpp"

namespace hwr::recon::store_detail {

constexpr size_t kBinHeaderBytes = 48;
constexpr size_t kKeyframeRecordBytes = 168;
constexpr size_t kFeatureBytes = 16;
constexpr size_t kCloudPointBytes = 16;
constexpr uint32_t kBinVersion = 1;
constexpr uint32_t kMaxDescriptorBytes = 4096;  // a sanity bound on a header field (ORB: 32)

using BinHeader = std::array<uint8_t, kBinHeaderBytes>;

// CRC32 continued from `crc` (0 to start).
uint32_t crc32_bytes(const void* data, size_t n, uint32_t crc = 0);

// keyframes.bin: header and payload. kInvalidArgument when a keyframe's descriptors are not
// features.size() * descriptor_bytes, or a count does not fit the format.
core::Status encode_keyframes(const std::vector<StoredKeyframe>& keyframes, int descriptor_bytes,
                              BinHeader* header, std::vector<uint8_t>* payload, uint32_t* payload_crc32);

// cloud.bin: the header only; the payload is the points' own bytes (CloudPoint is 16 packed
// bytes, and the host little-endian).
BinHeader encode_cloud_header(const std::vector<CloudPoint>& points, uint32_t* payload_crc32);

// What segment.yaml says about a binary file; the header must agree.
struct BinExpectation {
  uint64_t count = 0;  // keyframes or points
  uint32_t payload_crc32 = 0;
};

core::Status read_keyframes_file(const std::string& path, int descriptor_bytes, const BinExpectation& expect,
                                 std::vector<StoredKeyframe>* out);
core::Status read_cloud_file(const std::string& path, const BinExpectation& expect,
                             std::vector<CloudPoint>* out);

}  // namespace hwr::recon::store_detail
