#include "hwr/mapio/chunk_codec.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <iterator>
#include <memory>
#include <string>

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/expert_encode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>
#include <draco/point_cloud/point_cloud.h>
#include <draco/point_cloud/point_cloud_builder.h>

#include "hwr/mapio/draco_header.hpp"

namespace hwr::mapio {

namespace {

// Attribute unique ids written into the bitstream (chunk_codec.hpp).
constexpr uint32_t kUidPosition = 0;
constexpr uint32_t kUidColor = 1;
constexpr uint32_t kUidFlags = 2;
constexpr uint32_t kUidPointId = 3;
constexpr uint32_t kUidNormal = 4;

constexpr int kMaxQuantizationBits = 30;  // AttributeQuantizationTransform::IsQuantizationValid

// Unit roundoff of float32.
constexpr double kFloatUnitRoundoff = 1.0 / 16777216.0;  // 2^-24

// Float32 rounding budget of Draco's quantize/dequantize path, in metres, for a chunk whose
// coordinates are at most max_abs_m in magnitude and whose largest axis extent is range_m (u = 2^-24;
// AttributeQuantizationTransform, Quantizer, Dequantizer all work in float):
//   quantize    d = fl(x - min)            <= u·R
//               t = fl(d · fl(maxq / R))   <= 3u·maxq steps = 3u·R
//               fl(t + 0.5), then floor    <= u·(maxq + 1) steps <= 2u·R
//   dequantize  fl(q · fl(R / maxq))       <= 2u·R
//               fl(· + min)                <= u·(max|x| + R)
// Sum beyond the half step: 9u·R + u·max|x|. The budget takes 12u·R + 2u·max|x| (fused multiply-adds
// only remove roundings).
double float_rounding_slack_m(double range_m, double max_abs_m) {
  return kFloatUnitRoundoff * (12.0 * range_m + 2.0 * max_abs_m);
}

std::string draco_message(const draco::Status& status) {
  return status.error_msg_string().empty() ? std::string("(no message)") : status.error_msg_string();
}

// Copies n values of `bytes` bytes each (point order) out of a decoded attribute after checking that
// every mapped index lies inside the attribute's buffer: a corrupt stream must not make us read past it.
core::Status copy_attribute(const draco::PointAttribute& att, int n, size_t bytes, uint8_t* dst,
                            size_t dst_stride, const char* what) {
  const draco::DataBuffer* buffer = att.buffer();
  if (buffer == nullptr || att.byte_stride() < static_cast<int64_t>(bytes) || att.byte_offset() < 0) {
    return core::CorruptData(std::string("decoded ") + what + " attribute has no usable storage");
  }
  const size_t stride = static_cast<size_t>(att.byte_stride());
  const size_t offset = static_cast<size_t>(att.byte_offset());
  const size_t num_values = att.size();
  if (buffer->data_size() < offset || (buffer->data_size() - offset) / stride < num_values) {
    return core::CorruptData(std::string("decoded ") + what + " attribute is smaller than its value count");
  }
  const uint8_t* base = buffer->data() + offset;
  for (int i = 0; i < n; ++i) {
    const uint32_t avi = att.mapped_index(draco::PointIndex(static_cast<uint32_t>(i))).value();
    if (avi >= num_values) {
      return core::CorruptData(std::string("decoded ") + what + " attribute maps point " + std::to_string(i) +
                               " to value " + std::to_string(avi) + " of " + std::to_string(num_values));
    }
    std::memcpy(dst + static_cast<size_t>(i) * dst_stride, base + static_cast<size_t>(avi) * stride, bytes);
  }
  return core::Status::Ok();
}

bool is_type(const draco::PointAttribute& att, draco::GeometryAttribute::Type type, draco::DataType data_type,
             int components) {
  return att.attribute_type() == type && att.data_type() == data_type && att.num_components() == components;
}

struct ExpectedAttribute {
  uint32_t unique_id;
  uint8_t attribute_type;  // draco::GeometryAttribute::Type
  uint8_t data_type;       // draco::DataType
  uint8_t num_components;
  const char* name;
};

// What encode_chunk writes (chunk_codec.hpp), in Draco's numbers.
constexpr ExpectedAttribute kChunkAttributes[] = {
    {kUidPosition, draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, 3, "position"},
    {kUidColor, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour"},
    {kUidFlags, draco::GeometryAttribute::GENERIC, draco::DT_UINT8, 1, "flags"},
    {kUidPointId, draco::GeometryAttribute::GENERIC, draco::DT_UINT16, 2, "point id"},
    {kUidNormal, draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, 3, "normal"},
};

// The chunk's attribute descriptors against kChunkAttributes, before Draco creates any attribute.
core::Status check_attribute_layout(const DracoPointCloudPrefix& prefix) {
  bool seen[std::size(kChunkAttributes)] = {};
  for (int i = 0; i < prefix.num_attributes; ++i) {
    const DracoAttributeDescriptor& a = prefix.attributes[static_cast<size_t>(i)];
    if (a.unique_id >= std::size(kChunkAttributes)) {
      return core::CorruptData("decode_chunk: unexpected attribute with unique id " +
                               std::to_string(a.unique_id) + " (chunks carry ids 0..4)");
    }
    const ExpectedAttribute& e = kChunkAttributes[a.unique_id];
    if (a.attribute_type != e.attribute_type || a.data_type != e.data_type ||
        a.num_components != e.num_components || a.normalized) {
      return core::CorruptData(std::string("decode_chunk: the ") + e.name + " attribute (unique id " +
                               std::to_string(a.unique_id) + ") has type " +
                               std::to_string(a.attribute_type) + ", data type " +
                               std::to_string(a.data_type) + ", " + std::to_string(a.num_components) +
                               " components; expected " + std::to_string(e.attribute_type) + ", " +
                               std::to_string(e.data_type) + ", " + std::to_string(e.num_components));
    }
    if (seen[a.unique_id]) {
      return core::CorruptData(std::string("decode_chunk: the ") + e.name + " attribute appears twice");
    }
    seen[a.unique_id] = true;
  }
  if (!seen[kUidPosition]) return core::CorruptData("decode_chunk: the chunk has no position attribute");
  if (!seen[kUidColor]) return core::CorruptData("decode_chunk: the chunk has no colour attribute");
  return core::Status::Ok();
}

}  // namespace

int quantization_bits_for(double extent_m, double max_error_m) {
  if (!std::isfinite(extent_m) || !std::isfinite(max_error_m) || extent_m < 0.0 || max_error_m <= 0.0)
    return -1;
  for (int q = 1; q <= kMaxQuantizationBits; ++q) {
    const double max_quantized = std::ldexp(1.0, q) - 1.0;
    if (extent_m / max_quantized / 2.0 <= max_error_m) return q;
  }
  return -1;
}

core::Expected<EncodedChunkInfo> encode_chunk(const ChunkPoint* points, int n, const uint32_t* ids,
                                              const float* normals_xyz, const ChunkCodecConfig& config,
                                              std::vector<uint8_t>* out) {
  if (out == nullptr) return core::InvalidArgument("encode_chunk: null output buffer");
  out->clear();
  if (points == nullptr || n < 1) {
    return core::InvalidArgument("encode_chunk: a chunk needs at least one point (got n = " +
                                 std::to_string(n) + (points == nullptr ? ", points = null" : "") + ")");
  }
  if (!(config.max_position_error_m > 0.0) || !std::isfinite(config.max_position_error_m)) {
    return core::InvalidArgument(
        "encode_chunk: max_position_error_m must be a positive finite number of metres, got " +
        std::to_string(config.max_position_error_m));
  }
  if (config.speed < 0 || config.speed > 10) {
    return core::InvalidArgument("encode_chunk: speed must be 0..10, got " + std::to_string(config.speed));
  }
  if (config.with_point_ids != (ids != nullptr)) {
    return core::InvalidArgument(config.with_point_ids
                                     ? "encode_chunk: with_point_ids is set but no ids were passed"
                                     : "encode_chunk: ids were passed but with_point_ids is false");
  }
  if (config.color_bits < 1 || config.color_bits > 8) {
    return core::InvalidArgument("encode_chunk: color_bits must be 1..8, got " +
                                 std::to_string(config.color_bits));
  }
  if (normals_xyz != nullptr &&
      (config.normal_quantization_bits < 1 || config.normal_quantization_bits > kMaxQuantizationBits)) {
    return core::InvalidArgument("encode_chunk: normal_quantization_bits must be 1..30, got " +
                                 std::to_string(config.normal_quantization_bits));
  }

  // Bounding box in float32, computed exactly as Draco's AttributeQuantizationTransform::ComputeParameters
  // does, so the range the bits are chosen for is the range Draco quantizes over.
  float min_xyz[3] = {points[0].x_m, points[0].y_m, points[0].z_m};
  float max_xyz[3] = {min_xyz[0], min_xyz[1], min_xyz[2]};
  for (int i = 0; i < n; ++i) {
    const float p[3] = {points[i].x_m, points[i].y_m, points[i].z_m};
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(p[c])) {
        return core::InvalidArgument("encode_chunk: point " + std::to_string(i) +
                                     " has a non-finite coordinate");
      }
      min_xyz[c] = std::min(min_xyz[c], p[c]);
      max_xyz[c] = std::max(max_xyz[c], p[c]);
    }
  }
  if (normals_xyz != nullptr) {
    for (int i = 0; i < 3 * n; ++i) {
      if (!std::isfinite(normals_xyz[i])) {
        return core::InvalidArgument("encode_chunk: normal of point " + std::to_string(i / 3) +
                                     " is not finite");
      }
    }
  }
  float range_f = 0.f;
  double max_abs_m = 0.0;
  for (int c = 0; c < 3; ++c) {
    range_f = std::max(range_f, max_xyz[c] - min_xyz[c]);
    max_abs_m = std::max({max_abs_m, std::fabs(double{min_xyz[c]}), std::fabs(double{max_xyz[c]})});
  }
  if (!std::isfinite(range_f)) {
    return core::InvalidArgument("encode_chunk: the chunk's extent overflows float32");
  }
  const double slack_m = float_rounding_slack_m(range_f, max_abs_m);
  const double budget_m = config.max_position_error_m - slack_m;
  if (budget_m <= 0.0) {
    return core::OutOfRange("encode_chunk: coordinates up to " + std::to_string(max_abs_m) +
                            " m are too large for float32 to hold a " +
                            std::to_string(config.max_position_error_m) +
                            " m error bound; encode the chunk in a local frame");
  }
  const int q = quantization_bits_for(range_f, budget_m);
  if (q < 0) {
    return core::OutOfRange("encode_chunk: an extent of " + std::to_string(range_f) + " m at " +
                            std::to_string(config.max_position_error_m) +
                            " m error needs more than 30 quantization bits (Draco's limit); split the chunk");
  }
  // The guaranteed bound: half a step plus the rounding budget. A zero range quantizes over 1 m in Draco
  // (ComputeParameters) with q = 1, and every value decodes exactly to the origin.
  const double max_quantized = std::ldexp(1.0, q) - 1.0;
  const double bound_m = (range_f > 0.f ? double{range_f} / max_quantized / 2.0 : 0.0) + slack_m;

  draco::PointCloudBuilder builder;
  builder.Start(static_cast<draco::PointIndex::ValueType>(n));
  const int att_position = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int att_color = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
  builder.SetAttributeValuesForAllPoints(att_position, &points[0].x_m, sizeof(ChunkPoint));
  if (config.color_bits == 8) {
    builder.SetAttributeValuesForAllPoints(att_color, &points[0].r, sizeof(ChunkPoint));
  } else {
    // Each channel rounded to the nearest of 2^color_bits levels spread over 0..255: fewer distinct
    // values for the entropy coder, still ordinary 8-bit colours for any Draco reader.
    const int levels = (1 << config.color_bits) - 1;
    uint8_t rgb[3];
    for (int i = 0; i < n; ++i) {
      const uint8_t in[3] = {points[i].r, points[i].g, points[i].b};
      for (int c = 0; c < 3; ++c) {
        const int level = (in[c] * levels + 127) / 255;
        rgb[c] = static_cast<uint8_t>((level * 255 + levels / 2) / levels);
      }
      builder.SetAttributeValueForPoint(att_color, draco::PointIndex(static_cast<uint32_t>(i)), rgb);
    }
  }
  // Flags travel only when one is set (the decoder reads a missing flags attribute as zeros).
  const bool any_flags = std::any_of(points, points + n, [](const ChunkPoint& p) { return p.flags != 0; });
  int att_flags = -1;
  if (any_flags) {
    att_flags = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT8);
    builder.SetAttributeValuesForAllPoints(att_flags, &points[0].flags, sizeof(ChunkPoint));
  }
  int att_id = -1;
  std::vector<uint16_t> id_halves;
  if (ids != nullptr) {
    // Two uint16 halves (low, high): Draco's sequential integer coder converts values to int32 and its
    // difference prediction needs max - min < 2^31 (PredictionSchemeWrapTransformBase::
    // InitCorrectionBounds), so a uint32 attribute fails to encode ids above 2^31 - 1; halves always fit.
    id_halves.resize(2 * static_cast<size_t>(n));
    for (size_t i = 0; i < static_cast<size_t>(n); ++i) {
      id_halves[2 * i] = static_cast<uint16_t>(ids[i] & 0xffffu);
      id_halves[2 * i + 1] = static_cast<uint16_t>(ids[i] >> 16);
    }
    att_id = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 2, draco::DT_UINT16);
    builder.SetAttributeValuesForAllPoints(att_id, id_halves.data(), 2 * sizeof(uint16_t));
  }
  int att_normal = -1;
  if (normals_xyz != nullptr) {
    att_normal = builder.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
    builder.SetAttributeValuesForAllPoints(att_normal, normals_xyz, 3 * sizeof(float));
  }
  std::unique_ptr<draco::PointCloud> cloud = builder.Finalize(/*deduplicate_points=*/false);
  if (!cloud) return core::Internal("encode_chunk: Draco's PointCloudBuilder returned no cloud");
  cloud->attribute(att_position)->set_unique_id(kUidPosition);
  cloud->attribute(att_color)->set_unique_id(kUidColor);
  if (att_flags >= 0) cloud->attribute(att_flags)->set_unique_id(kUidFlags);
  if (att_id >= 0) cloud->attribute(att_id)->set_unique_id(kUidPointId);
  if (att_normal >= 0) cloud->attribute(att_normal)->set_unique_id(kUidNormal);

  draco::ExpertEncoder encoder(*cloud);
  encoder.SetSpeedOptions(config.speed, config.speed);
  encoder.SetEncodingMethod(config.preserve_order ? draco::POINT_CLOUD_SEQUENTIAL_ENCODING
                                                  : draco::POINT_CLOUD_KD_TREE_ENCODING);
  // Not SetAttributeExplicitQuantization: Draco keeps an explicit origin and range as option strings
  // (std::to_string, 6 decimals), which moves the origin by up to 5e-7 m. Draco derives from the
  // values the same min and range computed above.
  encoder.SetAttributeQuantization(att_position, q);
  if (att_normal >= 0) encoder.SetAttributeQuantization(att_normal, config.normal_quantization_bits);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeToBuffer(&buffer);
  if (!status.ok()) return core::Internal("encode_chunk: Draco failed to encode: " + draco_message(status));
  if (buffer.size() > config.max_payload_bytes) {
    return core::OutOfRange("encode_chunk: " + std::to_string(n) + " points encode to " +
                            std::to_string(buffer.size()) + " bytes, over the " +
                            std::to_string(config.max_payload_bytes) + "-byte chunk limit; split the chunk");
  }
  const auto* bytes = reinterpret_cast<const uint8_t*>(buffer.data());
  out->assign(bytes, bytes + buffer.size());

  EncodedChunkInfo info;
  info.num_points = n;
  info.quantization_bits = q;
  info.max_position_error_m = bound_m;
  info.bytes = out->size();
  return info;
}

core::Status decode_chunk(const uint8_t* data, size_t size, int expected_points,
                          const ChunkDecodeLimits& limits, DecodedChunk* out) {
  if (out == nullptr) return core::InvalidArgument("decode_chunk: null output");
  if (data == nullptr && size > 0)
    return core::InvalidArgument("decode_chunk: null data with a non-zero size");
  if (expected_points < -1) {
    return core::InvalidArgument("decode_chunk: expected_points must be >= 0, or -1 for no check; got " +
                                 std::to_string(expected_points));
  }
  if (size == 0) return core::CorruptData("decode_chunk: the chunk payload is empty");
  if (size > limits.max_payload_bytes) {
    return core::OutOfRange("decode_chunk: payload of " + std::to_string(size) + " bytes is over the " +
                            std::to_string(limits.max_payload_bytes) + "-byte limit");
  }
  auto header = parse_draco_point_cloud_header(data, size);
  if (!header.ok()) return header.status();
  const int n = header->num_points;
  if (n == 0)
    return core::CorruptData("decode_chunk: the Draco header claims 0 points; a chunk holds at least one");
  if (n > limits.max_points) {
    return core::OutOfRange("decode_chunk: the Draco header claims " + std::to_string(n) +
                            " points, over the limit of " + std::to_string(limits.max_points) +
                            "; rejected before decoding");
  }
  if (expected_points >= 0 && n != expected_points) {
    return core::CorruptData("decode_chunk: the Draco header claims " + std::to_string(n) +
                             " points but the chunk message says " + std::to_string(expected_points));
  }
  // Everything up to the first attribute value, before Draco sees the buffer (draco_header.hpp).
  auto prefix = parse_draco_point_cloud_prefix(data, size);
  if (!prefix.ok()) return core::CorruptData("decode_chunk: " + prefix.status().message());
  HWR_RETURN_IF_ERROR(check_attribute_layout(*prefix));

  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(data), size);
  draco::Decoder decoder;
  auto decoded = decoder.DecodePointCloudFromBuffer(&buffer);
  if (!decoded.ok()) {
    return core::CorruptData("decode_chunk: Draco could not decode the chunk: " +
                             draco_message(decoded.status()));
  }
  const std::unique_ptr<draco::PointCloud> cloud = std::move(decoded).value();
  if (!cloud || static_cast<int64_t>(cloud->num_points()) != n) {
    return core::CorruptData("decode_chunk: Draco decoded " +
                             std::to_string(cloud ? cloud->num_points() : 0) + " points, the header claims " +
                             std::to_string(n));
  }

  const draco::PointAttribute* position = nullptr;
  const draco::PointAttribute* color = nullptr;
  const draco::PointAttribute* flags = nullptr;
  const draco::PointAttribute* point_id = nullptr;
  const draco::PointAttribute* normal = nullptr;
  for (int i = 0; i < cloud->num_attributes(); ++i) {
    const draco::PointAttribute* att = cloud->attribute(i);
    if (att == nullptr) continue;
    const draco::PointAttribute** slot = nullptr;
    bool type_ok = false;
    switch (att->unique_id()) {
      case kUidPosition:
        slot = &position;
        type_ok = is_type(*att, draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, 3);
        break;
      case kUidColor:
        slot = &color;
        type_ok = is_type(*att, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3);
        break;
      case kUidFlags:
        slot = &flags;
        type_ok = is_type(*att, draco::GeometryAttribute::GENERIC, draco::DT_UINT8, 1);
        break;
      case kUidPointId:
        slot = &point_id;
        type_ok = is_type(*att, draco::GeometryAttribute::GENERIC, draco::DT_UINT16, 2);
        break;
      case kUidNormal:
        slot = &normal;
        type_ok = is_type(*att, draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, 3);
        break;
      default:
        return core::CorruptData("decode_chunk: unexpected attribute with unique id " +
                                 std::to_string(att->unique_id()) + " (chunks carry ids 0..4)");
    }
    if (!type_ok) {
      return core::CorruptData("decode_chunk: attribute with unique id " + std::to_string(att->unique_id()) +
                               " has the wrong type, data type or component count");
    }
    if (*slot != nullptr) {
      return core::CorruptData("decode_chunk: attribute with unique id " + std::to_string(att->unique_id()) +
                               " appears twice");
    }
    *slot = att;
  }
  if (position == nullptr) return core::CorruptData("decode_chunk: the chunk has no position attribute");
  if (color == nullptr) return core::CorruptData("decode_chunk: the chunk has no colour attribute");

  const size_t count = static_cast<size_t>(n);
  out->points.resize(count);
  auto* point_bytes = reinterpret_cast<uint8_t*>(out->points.data());
  HWR_RETURN_IF_ERROR(copy_attribute(*position, n, 3 * sizeof(float), point_bytes + offsetof(ChunkPoint, x_m),
                                     sizeof(ChunkPoint), "position"));
  HWR_RETURN_IF_ERROR(
      copy_attribute(*color, n, 3, point_bytes + offsetof(ChunkPoint, r), sizeof(ChunkPoint), "colour"));
  if (flags != nullptr) {
    HWR_RETURN_IF_ERROR(
        copy_attribute(*flags, n, 1, point_bytes + offsetof(ChunkPoint, flags), sizeof(ChunkPoint), "flags"));
  } else {
    for (ChunkPoint& p : out->points) p.flags = 0;
  }
  for (size_t i = 0; i < count; ++i) {
    const ChunkPoint& p = out->points[i];
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) {
      return core::CorruptData("decode_chunk: decoded point " + std::to_string(i) +
                               " has a non-finite coordinate");
    }
  }
  out->ids.clear();
  if (point_id != nullptr) {
    // The halves (low, high) land in the uint32 slots, then are joined in place.
    out->ids.resize(count);
    HWR_RETURN_IF_ERROR(copy_attribute(*point_id, n, 2 * sizeof(uint16_t),
                                       reinterpret_cast<uint8_t*>(out->ids.data()), sizeof(uint32_t),
                                       "point id"));
    for (uint32_t& id : out->ids) {
      uint16_t halves[2];
      std::memcpy(halves, &id, sizeof halves);
      id = static_cast<uint32_t>(halves[0]) | (static_cast<uint32_t>(halves[1]) << 16);
    }
  }
  out->normals_xyz.clear();
  if (normal != nullptr) {
    out->normals_xyz.resize(3 * count);
    HWR_RETURN_IF_ERROR(copy_attribute(*normal, n, 3 * sizeof(float),
                                       reinterpret_cast<uint8_t*>(out->normals_xyz.data()), 3 * sizeof(float),
                                       "normal"));
    for (size_t i = 0; i < 3 * count; ++i) {
      if (!std::isfinite(out->normals_xyz[i])) {
        return core::CorruptData("decode_chunk: decoded normal of point " + std::to_string(i / 3) +
                                 " is not finite");
      }
    }
  }
  return core::Status::Ok();
}

}  // namespace hwr::mapio
