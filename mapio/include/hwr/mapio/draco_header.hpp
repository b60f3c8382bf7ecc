#pragma once
// The fixed-size prefix of a Draco point-cloud bitstream, parsed by hand so that a chunk is judged
// before Draco's decoder allocates anything for it (issue #5 item 2: "a chunk claiming 10^9 points
// is rejected"). Draco's own decoder sizes every attribute from the point count (e.g.
// KdTreeAttributesDecoder::DecodePortableAttributes calls PointAttribute::Reset(num_points)) before it
// has read a single attribute value, so the count must be checked first.
//
// Header layout (Draco 1.5.x, src/draco/compression/point_cloud/point_cloud_encoder.cc EncodeHeader and
// point_cloud_{sequential,kd_tree}_encoder.cc EncodeGeometryData; all multi-byte fields little-endian,
// as Draco memcpy's them on the little-endian hosts it supports):
//   offset  0  char[5]  "DRACO"
//   offset  5  uint8    bitstream version major
//   offset  6  uint8    bitstream version minor
//   offset  7  uint8    encoder type      (0 = point cloud, 1 = triangular mesh)
//   offset  8  uint8    encoding method   (point cloud: 0 = sequential, 1 = kd-tree)
//   offset  9  uint16   flags             (0x8000 = geometry metadata follows)
//   offset 11  int32    number of points  (only here when no metadata precedes it: neither point-cloud
//                                          encoder writes encoder data before the geometry data)

#include <array>
#include <cstddef>
#include <cstdint>

#include "hwr/core/status.hpp"

namespace hwr::mapio {

inline constexpr size_t kDracoPointCloudHeaderBytes = 15;

// The only Draco point-cloud bitstream version accepted: 2.3, what Draco 1.4 .. 1.5.7 write. Older
// 2.x bitstreams put the kd-tree's own point count elsewhere, 1.x predate Draco 1.0.
inline constexpr uint8_t kDracoBitstreamMajor = 2;
inline constexpr uint8_t kDracoBitstreamMinor = 3;

enum class DracoPointCloudMethod : uint8_t { kSequential = 0, kKdTree = 1 };

struct DracoPointCloudHeader {
  uint8_t version_major = 0;
  uint8_t version_minor = 0;
  DracoPointCloudMethod method = DracoPointCloudMethod::kSequential;
  uint16_t flags = 0;
  int32_t num_points = 0;
};

// Parses the 15-byte prefix. CorruptData for a buffer shorter than the prefix, a missing "DRACO"
// magic, a version other than 2.3, a mesh, an unknown method, any flag set (metadata is never written
// by this project's encoder and would move the point count) or a negative point count. The count is
// returned unchecked against any limit: the caller owns the limits (decode_chunk).
core::Expected<DracoPointCloudHeader> parse_draco_point_cloud_header(const uint8_t* data, size_t size);

// One attribute descriptor (AttributesDecoder::DecodeAttributesDecoderData): Draco's
// GeometryAttribute::Type and DataType numbers as stored.
struct DracoAttributeDescriptor {
  uint8_t attribute_type = 0;  // 0 position, 1 normal, 2 colour, 3 texture coordinate, 4 generic
  uint8_t data_type = 0;       // 1 int8, 2 uint8, 3 int16, 4 uint16, 5 int32, 6 uint32, ..., 9 float32
  uint8_t num_components = 0;
  bool normalized = false;
  uint32_t unique_id = 0;
};

inline constexpr int kDracoMaxAttributes = 8;

// The header plus everything that follows it up to the first attribute value: the attribute
// descriptors and, for the kd-tree method, the kd-tree coder's own parameters. Layout after the
// header (bitstream 2.3; PointCloudDecoder::DecodePointAttributes):
//   uint8   number of attributes decoders (point clouds: 1)
//   varint  number of attributes, then per attribute uint8 type, uint8 data type, uint8 components,
//           uint8 normalized, varint unique id
//   sequential: uint8 decoder type per attribute (SequentialAttributeDecodersController)
//   kd-tree:    uint8 compression level (KdTreeAttributesDecoder::DecodePortableAttributes), then
//               uint32 bit length and uint32 number of points (DynamicIntegerPointsKdTreeDecoder::
//               DecodePoints)
// Draco itself trusts the kd-tree coder's point count and loops over it before comparing it with
// the header's: a 90-byte chunk claiming 2^32 - 10 points there keeps Draco busy for seconds (found
// by fuzz_chunk_decoder). This parser rejects it.
struct DracoPointCloudPrefix {
  DracoPointCloudHeader header;
  int num_attributes = 0;
  std::array<DracoAttributeDescriptor, kDracoMaxAttributes> attributes{};
  uint8_t kd_tree_compression_level = 0;  // kd-tree only
  uint32_t kd_tree_bit_length = 0;        // kd-tree only
};

// Parses and checks the prefix: everything parse_draco_point_cloud_header checks, exactly one
// attributes decoder, 1..kDracoMaxAttributes attributes with known types, data types and at least one
// component, known sequential decoder types, a kd-tree compression level <= 6, a bit length <= 32 and
// a kd-tree point count equal to the header's. CorruptData otherwise, naming the field.
core::Expected<DracoPointCloudPrefix> parse_draco_point_cloud_prefix(const uint8_t* data, size_t size);

}  // namespace hwr::mapio
