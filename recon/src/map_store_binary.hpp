#pragma once
// The map store's three binary files (map_store.hpp), little-endian, each a 48-byte header and a
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
//   fine.bin header (segment format 2 on)
//    0  char[8] magic "HWRFN001"
//    8  u32 version (1)
//   12  u32 header bytes (48)
//   16  u32 bytes per fine point (20)
//   20  u32 weld region count
//   24  u64 fine point count
//   32  u64 payload bytes (regions x 304 + fine points x 20)
//   40  u32 CRC32 of the payload
//   44  u32 CRC32 of header bytes 0..43
//
// keyframes.bin payload, per keyframe in order: a 168-byte record
//    0 i32 id, 4 u32 feature count n, 8 i64 t_ns, 16 f64[12] T_world_cam rows of [R | t],
//  112 u8 gnss_valid, 113 u8 mag_valid, 114 6 zero bytes, 120 f64 lat_deg, lon_deg, alt_m,
//  144 f64[3] mag_imu_uT,
// then n features of 16 bytes (f32 u_px, v_px, depth_m, u8 octave, 3 zero bytes), then n *
// descriptor-bytes descriptor bytes.
// cloud.bin payload: point count CloudPoints of 16 bytes (f32 x_m, y_m, z_m, u8 r, g, b, flags).
// fine.bin payload (SegmentRecord's weld_regions, fine_points_segment and fine_counts; its
// fine_voxel_m is in segment.yaml): region count 304-byte records (StoredWeldRegion)
//    0 u32 id, 4 u8 source (WeldRegionSource, 0..3), 5 3 zero bytes, 8 f32 confidence,
//   12 char[32] label (the array as it is; at least one NUL), 44 i32 keyframe_id, 48 i64 t_ns,
//   56 f64[12] T_cam_region rows of [R | t], 152 f64[3] half_size_m,
//  176 f64[12] T_segment_region rows of [R | t], 272 i64 fine_points, 280 f64[3] viewpoint_segment,
// then fine point count 20-byte fine points: the CloudPoint's 16 bytes (as in cloud.bin, segment
// frame) and its u32 count (points merged into that voxel, >= 1).
// A record is valid when its source is a known value, its label holds a NUL, both poses are rigid
// (core::rigid_transform_problem), its half sizes are positive and finite, its viewpoint finite and
// fine_points >= 0; a
// fine point when its coordinates are finite and its count >= 1; fine points need fine_voxel_m > 0.
// The writer refuses (kInvalidArgument) what the reader would refuse (kCorruptData).
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
constexpr size_t kWeldRegionRecordBytes = 304;
constexpr size_t kFinePointBytes = 20;  // CloudPoint + u32 count
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

// fine.bin: header and payload of a segment's fine data. kInvalidArgument (naming the segment and
// the region or point) when fine_counts and fine_points_segment differ in size, a region or fine
// point is one the reader would refuse (header comment), fine_voxel_m is negative or not finite,
// or there are fine points and fine_voxel_m is not > 0.
core::Status encode_fine(const SegmentRecord& segment, BinHeader* header, std::vector<uint8_t>* payload,
                         uint32_t* payload_crc32);

// What segment.yaml says about a binary file; the header must agree.
struct BinExpectation {
  uint64_t count = 0;  // keyframes or points
  uint32_t payload_crc32 = 0;
};

core::Status read_keyframes_file(const std::string& path, int descriptor_bytes, const BinExpectation& expect,
                                 std::vector<StoredKeyframe>* out);
core::Status read_cloud_file(const std::string& path, const BinExpectation& expect,
                             std::vector<CloudPoint>* out);

// What segment.yaml says about fine.bin.
struct FineExpectation {
  uint64_t regions = 0;
  uint64_t points = 0;
  uint32_t payload_crc32 = 0;
  double fine_voxel_m = 0;
};

// Reads fine.bin into the three vectors (replaced only on success).
core::Status read_fine_file(const std::string& path, const FineExpectation& expect,
                            std::vector<StoredWeldRegion>* regions, std::vector<CloudPoint>* points,
                            std::vector<uint32_t>* counts);

}  // namespace hwr::recon::store_detail
