#include "hwr/mapio/chunk_codec.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <iterator>
#include <memory>
#include <string>

#include <draco/attributes/attribute_quantization_transform.h>
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
// Split layout, color_bits b < 8: colour as levels 0..2^b - 1 under unique id 4 + b (5..11), so the
// sequential coder sees consecutive integers (rescaled 8-bit values would leave 8 - b noise-like low
// bits in every residual) and the payload says its own precision.
constexpr uint32_t kUidColorLevelsBase = 4;
constexpr uint32_t kUidColorLevelsFirst = kUidColorLevelsBase + 1;
constexpr uint32_t kUidColorLevelsLast = kUidColorLevelsBase + 7;
bool is_color_levels(uint32_t uid) { return uid >= kUidColorLevelsFirst && uid <= kUidColorLevelsLast; }

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
    {5, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (1-bit levels)"},
    {6, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (2-bit levels)"},
    {7, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (3-bit levels)"},
    {8, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (4-bit levels)"},
    {9, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (5-bit levels)"},
    {10, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (6-bit levels)"},
    {11, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3, "colour (7-bit levels)"},
};
static_assert(std::size(kChunkAttributes) == kUidColorLevelsLast + 1, "one entry per unique id");

// Which Draco point cloud of a payload a prefix belongs to (chunk_codec.hpp, layouts (a) and (b)).
enum class CloudRole { kSingle, kSplitPositions, kSplitAttributes };

// The cloud's attribute descriptors against kChunkAttributes and its role, before Draco creates any
// attribute.
core::Status check_attribute_layout(const DracoPointCloudPrefix& prefix, CloudRole role) {
  bool seen[std::size(kChunkAttributes)] = {};
  for (int i = 0; i < prefix.num_attributes; ++i) {
    const DracoAttributeDescriptor& a = prefix.attributes[static_cast<size_t>(i)];
    if (a.unique_id >= std::size(kChunkAttributes)) {
      return core::CorruptData("decode_chunk: unexpected attribute with unique id " +
                               std::to_string(a.unique_id) + " (chunks carry ids 0..11)");
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
    if (is_color_levels(a.unique_id) && role != CloudRole::kSplitAttributes)
      return core::CorruptData("decode_chunk: colour levels appear outside a split chunk's attribute cloud");
  }
  const int colors =
      static_cast<int>(std::count(std::begin(seen) + kUidColorLevelsFirst, std::end(seen), true)) +
      int{seen[kUidColor]};
  if (colors > 1) return core::CorruptData("decode_chunk: the chunk carries more than one colour attribute");
  if (role != CloudRole::kSplitAttributes && !seen[kUidPosition])
    return core::CorruptData("decode_chunk: the chunk has no position attribute");
  if (role == CloudRole::kSplitAttributes && seen[kUidPosition])
    return core::CorruptData("decode_chunk: the split chunk's attribute cloud carries positions");
  if (role != CloudRole::kSplitPositions && colors == 0)
    return core::CorruptData("decode_chunk: the chunk has no colour attribute");
  return core::Status::Ok();
}

// Each channel rounded to the nearest of 2^bits levels spread over 0..255 (ChunkCodecConfig::color_bits):
// its level 0..2^bits - 1, and the 8-bit value a level stands for.
uint8_t color_level(uint8_t v, int bits) {
  const int levels = (1 << bits) - 1;
  return static_cast<uint8_t>((v * levels + 127) / 255);
}
uint8_t level_color(uint8_t level, int bits) {
  const int levels = (1 << bits) - 1;
  return static_cast<uint8_t>((level * 255 + levels / 2) / levels);
}
}  // namespace

uint8_t reduce_color_channel(uint8_t v, int bits) {
  return bits >= 8 ? v : level_color(color_level(v, bits), bits);
}

namespace {

// A Draco point cloud of n points with the positions (with_position) and/or the other attributes
// (with_attributes) of points, ids, normals (each optional), unique ids as in chunk_codec.hpp.
std::unique_ptr<draco::PointCloud> build_cloud(const ChunkPoint* points, int n, const uint32_t* ids,
                                               const float* normals_xyz, int color_bits, bool with_position,
                                               bool with_attributes, bool color_as_levels) {
  draco::PointCloudBuilder builder;
  builder.Start(static_cast<draco::PointIndex::ValueType>(n));
  std::vector<std::pair<int, uint32_t>> unique_ids;  // builder attribute -> unique id
  if (with_position) {
    const int att = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    builder.SetAttributeValuesForAllPoints(att, &points[0].x_m, sizeof(ChunkPoint));
    unique_ids.emplace_back(att, kUidPosition);
  }
  std::vector<uint16_t> id_halves;
  if (with_attributes) {
    const int att_color = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8);
    if (color_bits == 8) {
      unique_ids.emplace_back(att_color, kUidColor);
      builder.SetAttributeValuesForAllPoints(att_color, &points[0].r, sizeof(ChunkPoint));
    } else if (color_as_levels) {
      unique_ids.emplace_back(att_color, kUidColorLevelsBase + static_cast<uint32_t>(color_bits));
      for (int i = 0; i < n; ++i) {
        const uint8_t levels[3] = {color_level(points[i].r, color_bits), color_level(points[i].g, color_bits),
                                   color_level(points[i].b, color_bits)};
        builder.SetAttributeValueForPoint(att_color, draco::PointIndex(static_cast<uint32_t>(i)), levels);
      }
    } else {
      unique_ids.emplace_back(att_color, kUidColor);
      // Fewer distinct values for the entropy coder, still ordinary 8-bit colours for any Draco reader.
      for (int i = 0; i < n; ++i) {
        const uint8_t rgb[3] = {reduce_color_channel(points[i].r, color_bits),
                                reduce_color_channel(points[i].g, color_bits),
                                reduce_color_channel(points[i].b, color_bits)};
        builder.SetAttributeValueForPoint(att_color, draco::PointIndex(static_cast<uint32_t>(i)), rgb);
      }
    }
    // Flags travel only when one is set (the decoder reads a missing flags attribute as zeros).
    if (std::any_of(points, points + n, [](const ChunkPoint& p) { return p.flags != 0; })) {
      const int att = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT8);
      builder.SetAttributeValuesForAllPoints(att, &points[0].flags, sizeof(ChunkPoint));
      unique_ids.emplace_back(att, kUidFlags);
    }
    if (ids != nullptr) {
      // Two uint16 halves (low, high): Draco's sequential integer coder converts values to int32 and its
      // difference prediction needs max - min < 2^31 (PredictionSchemeWrapTransformBase::
      // InitCorrectionBounds), so a uint32 attribute fails to encode ids above 2^31 - 1; halves always fit.
      id_halves.resize(2 * static_cast<size_t>(n));
      for (size_t i = 0; i < static_cast<size_t>(n); ++i) {
        id_halves[2 * i] = static_cast<uint16_t>(ids[i] & 0xffffu);
        id_halves[2 * i + 1] = static_cast<uint16_t>(ids[i] >> 16);
      }
      const int att = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 2, draco::DT_UINT16);
      builder.SetAttributeValuesForAllPoints(att, id_halves.data(), 2 * sizeof(uint16_t));
      unique_ids.emplace_back(att, kUidPointId);
    }
    if (normals_xyz != nullptr) {
      const int att = builder.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
      builder.SetAttributeValuesForAllPoints(att, normals_xyz, 3 * sizeof(float));
      unique_ids.emplace_back(att, kUidNormal);
    }
  }
  std::unique_ptr<draco::PointCloud> cloud = builder.Finalize(/*deduplicate_points=*/false);
  if (cloud)
    for (const auto& [att, uid] : unique_ids) cloud->attribute(att)->set_unique_id(uid);
  return cloud;
}

// Encodes `cloud` and appends the bitstream to `out`.
core::Status encode_cloud(const draco::PointCloud& cloud, bool kd_tree, int position_bits,
                          const ChunkCodecConfig& config, std::vector<uint8_t>* out) {
  draco::ExpertEncoder encoder(cloud);
  encoder.SetSpeedOptions(config.speed, config.speed);
  encoder.SetEncodingMethod(kd_tree ? draco::POINT_CLOUD_KD_TREE_ENCODING
                                    : draco::POINT_CLOUD_SEQUENTIAL_ENCODING);
  for (int i = 0; i < cloud.num_attributes(); ++i) {
    // Not SetAttributeExplicitQuantization for positions: Draco keeps an explicit origin and range as
    // option strings (std::to_string, 6 decimals), which moves the origin by up to 5e-7 m. Draco derives
    // from the values the same min and range encode_chunk computed.
    const uint32_t uid = cloud.attribute(i)->unique_id();
    if (uid == kUidPosition) encoder.SetAttributeQuantization(i, position_bits);
    if (uid == kUidNormal) encoder.SetAttributeQuantization(i, config.normal_quantization_bits);
  }
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeToBuffer(&buffer);
  if (!status.ok()) return core::Internal("encode_chunk: Draco failed to encode: " + draco_message(status));
  const auto* bytes = reinterpret_cast<const uint8_t*>(buffer.data());
  out->insert(out->end(), bytes, bytes + buffer.size());
  return core::Status::Ok();
}

// Quantized coordinates of one point, the key that ties a decoded point to its original.
struct GridKey {
  uint32_t c[3];
  uint32_t index;
  bool operator<(const GridKey& o) const {
    return c[0] != o.c[0]   ? c[0] < o.c[0]
           : c[1] != o.c[1] ? c[1] < o.c[1]
           : c[2] != o.c[2] ? c[2] < o.c[2]
                            : index < o.index;
  }
  bool same_cell(const GridKey& o) const { return c[0] == o.c[0] && c[1] == o.c[1] && c[2] == o.c[2]; }
};

// The order in which the kd-tree positions bitstream `positions` decodes: order[j] is the index in
// `cloud` of decoded point j. Each original's quantized coordinates come from Draco's own
// AttributeQuantizationTransform (what its kd-tree encoder applies), each decoded point's from
// inverting the dequantization, which is exact while float32's spacing at the chunk's coordinates is
// well below half a quantization step. Points sharing quantized coordinates are interchangeable.
// Far from the origin (kilometres, at 1 mm) neighbouring steps collapse onto one float and the
// matching fails: an empty result, and the caller falls back to the single layout.
std::vector<uint32_t> kd_tree_order(const draco::PointCloud& cloud, int q,
                                    const std::vector<uint8_t>& positions) {
  const int n = static_cast<int>(cloud.num_points());
  const draco::PointAttribute& att = *cloud.attribute(0);
  draco::AttributeQuantizationTransform quantization;
  if (!quantization.ComputeParameters(att, q)) return {};
  std::unique_ptr<draco::PointAttribute> codes = quantization.InitTransformedAttribute(att, n);
  if (!codes || !quantization.TransformAttribute(att, {}, codes.get())) return {};

  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(positions.data()), positions.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodePointCloudFromBuffer(&buffer);
  if (!decoded.ok() || decoded.value()->num_points() != cloud.num_points()) return {};
  const draco::PointAttribute* decoded_att =
      decoded.value()->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (decoded_att == nullptr) return {};

  const uint32_t max_code = (uint32_t{1} << q) - 1;
  const double step =
      static_cast<double>(quantization.range() / static_cast<float>(max_code));  // Dequantizer
  std::vector<GridKey> original(static_cast<size_t>(n)), from_stream(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    GridKey& k = original[static_cast<size_t>(i)];
    codes->GetValue(codes->mapped_index(draco::PointIndex(static_cast<uint32_t>(i))), k.c);
    k.index = static_cast<uint32_t>(i);
    float v[3];
    decoded_att->GetValue(decoded_att->mapped_index(draco::PointIndex(static_cast<uint32_t>(i))), v);
    GridKey& d = from_stream[static_cast<size_t>(i)];
    for (int a = 0; a < 3; ++a) {
      const double code = std::round((double{v[a]} - double{quantization.min_value(a)}) / step);
      if (!(code >= 0.0 && code <= max_code)) return {};
      d.c[a] = static_cast<uint32_t>(code);
    }
    d.index = static_cast<uint32_t>(i);
  }
  std::sort(original.begin(), original.end());
  std::sort(from_stream.begin(), from_stream.end());
  std::vector<uint32_t> order(static_cast<size_t>(n));
  for (size_t i = 0; i < original.size(); ++i) {
    if (!original[i].same_cell(from_stream[i])) return {};
    order[from_stream[i].index] = original[i].index;
  }
  return order;
}

// The attributes of a decoded chunk, found by unique id in one or two Draco clouds.
struct Attributes {
  const draco::PointAttribute* position = nullptr;
  const draco::PointAttribute* color = nullptr;
  const draco::PointAttribute* flags = nullptr;
  const draco::PointAttribute* point_id = nullptr;
  const draco::PointAttribute* normal = nullptr;
  int color_level_bits = 8;  // < 8: the colour attribute holds levels (kUidColorLevelsBase)
};

core::Status find_attributes(const draco::PointCloud& cloud, Attributes* found) {
  for (int i = 0; i < cloud.num_attributes(); ++i) {
    const draco::PointAttribute* att = cloud.attribute(i);
    if (att == nullptr) continue;
    const draco::PointAttribute** slot = nullptr;
    bool type_ok = false;
    switch (att->unique_id()) {
      case kUidPosition:
        slot = &found->position;
        type_ok = is_type(*att, draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, 3);
        break;
      case kUidColor:
        slot = &found->color;
        type_ok = is_type(*att, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3);
        break;
      case kUidFlags:
        slot = &found->flags;
        type_ok = is_type(*att, draco::GeometryAttribute::GENERIC, draco::DT_UINT8, 1);
        break;
      case kUidPointId:
        slot = &found->point_id;
        type_ok = is_type(*att, draco::GeometryAttribute::GENERIC, draco::DT_UINT16, 2);
        break;
      case kUidNormal:
        slot = &found->normal;
        type_ok = is_type(*att, draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, 3);
        break;
      default:
        if (!is_color_levels(att->unique_id())) {
          return core::CorruptData("decode_chunk: unexpected attribute with unique id " +
                                   std::to_string(att->unique_id()) + " (chunks carry ids 0..11)");
        }
        slot = &found->color;
        type_ok = is_type(*att, draco::GeometryAttribute::COLOR, draco::DT_UINT8, 3);
        found->color_level_bits = static_cast<int>(att->unique_id() - kUidColorLevelsBase);
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
  return core::Status::Ok();
}

// Decodes one Draco point cloud from `buffer` (its prefix already checked) and checks its point count.
core::Status decode_cloud(draco::DecoderBuffer* buffer, int n, const char* what,
                          std::unique_ptr<draco::PointCloud>* cloud) {
  draco::Decoder decoder;
  auto decoded = decoder.DecodePointCloudFromBuffer(buffer);
  if (!decoded.ok()) {
    return core::CorruptData(std::string("decode_chunk: ") + what +
                             "Draco could not decode the chunk: " + draco_message(decoded.status()));
  }
  *cloud = std::move(decoded).value();
  if (!*cloud || static_cast<int64_t>((*cloud)->num_points()) != n) {
    return core::CorruptData(std::string("decode_chunk: ") + what + "Draco decoded " +
                             std::to_string(*cloud ? (*cloud)->num_points() : 0) +
                             " points, the header claims " + std::to_string(n));
  }
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

  EncodedChunkInfo info;
  if (!config.preserve_order && config.color_bits < 8) {
    // Layout (b): positions kd-tree coded, then the other attributes sequentially in decoded order.
    std::unique_ptr<draco::PointCloud> positions =
        build_cloud(points, n, nullptr, nullptr, 8, true, false, false);
    if (!positions) return core::Internal("encode_chunk: Draco's PointCloudBuilder returned no cloud");
    HWR_RETURN_IF_ERROR(encode_cloud(*positions, /*kd_tree=*/true, q, config, out));
    const std::vector<uint32_t> order = kd_tree_order(*positions, q, *out);
    if (!order.empty()) {
      std::vector<ChunkPoint> sorted(static_cast<size_t>(n));
      std::vector<uint32_t> sorted_ids(ids != nullptr ? static_cast<size_t>(n) : 0);
      std::vector<float> sorted_normals(normals_xyz != nullptr ? 3 * static_cast<size_t>(n) : 0);
      for (size_t j = 0; j < order.size(); ++j) {
        sorted[j] = points[order[j]];
        if (ids != nullptr) sorted_ids[j] = ids[order[j]];
        if (normals_xyz != nullptr)
          std::copy_n(normals_xyz + 3 * size_t{order[j]}, 3, &sorted_normals[3 * j]);
      }
      std::unique_ptr<draco::PointCloud> attributes = build_cloud(
          sorted.data(), n, ids != nullptr ? sorted_ids.data() : nullptr,
          normals_xyz != nullptr ? sorted_normals.data() : nullptr, config.color_bits, false, true,
          /*color_as_levels=*/true);
      if (!attributes) return core::Internal("encode_chunk: Draco's PointCloudBuilder returned no cloud");
      HWR_RETURN_IF_ERROR(encode_cloud(*attributes, /*kd_tree=*/false, q, config, out));
      info.split = true;
    } else {
      out->clear();  // the single layout below
    }
  }
  if (!info.split) {
    std::unique_ptr<draco::PointCloud> cloud =
        build_cloud(points, n, ids, normals_xyz, config.color_bits, true, true, false);
    if (!cloud) return core::Internal("encode_chunk: Draco's PointCloudBuilder returned no cloud");
    HWR_RETURN_IF_ERROR(encode_cloud(*cloud, !config.preserve_order, q, config, out));
  }
  if (out->size() > config.max_payload_bytes) {
    const size_t bytes = out->size();
    out->clear();
    return core::OutOfRange("encode_chunk: " + std::to_string(n) + " points encode to " +
                            std::to_string(bytes) + " bytes, over the " +
                            std::to_string(config.max_payload_bytes) + "-byte chunk limit; split the chunk");
  }

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
  // Layout (b) when the first cloud holds the positions alone (chunk_codec.hpp).
  const bool split = prefix->num_attributes == 1 && prefix->attributes[0].unique_id == kUidPosition;
  if (split && prefix->header.method != DracoPointCloudMethod::kKdTree)
    return core::CorruptData("decode_chunk: the split chunk's position cloud is not kd-tree coded");
  HWR_RETURN_IF_ERROR(
      check_attribute_layout(*prefix, split ? CloudRole::kSplitPositions : CloudRole::kSingle));

  Attributes found;
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(data), size);
  std::unique_ptr<draco::PointCloud> cloud;
  HWR_RETURN_IF_ERROR(decode_cloud(&buffer, n, "", &cloud));
  HWR_RETURN_IF_ERROR(find_attributes(*cloud, &found));
  size_t used = static_cast<size_t>(buffer.decoded_size());
  std::unique_ptr<draco::PointCloud> attribute_cloud;
  if (split) {
    if (used >= size)
      return core::CorruptData("decode_chunk: the split chunk ends after its positions (no attribute cloud)");
    const uint8_t* rest = data + used;
    const size_t rest_size = size - used;
    auto second = parse_draco_point_cloud_prefix(rest, rest_size);
    if (!second.ok()) return core::CorruptData("decode_chunk: attribute cloud: " + second.status().message());
    if (second->header.num_points != n) {
      return core::CorruptData("decode_chunk: the attribute cloud claims " +
                               std::to_string(second->header.num_points) + " points, the position cloud " +
                               std::to_string(n));
    }
    if (second->header.method != DracoPointCloudMethod::kSequential)
      return core::CorruptData("decode_chunk: the split chunk's attribute cloud is not sequentially coded");
    HWR_RETURN_IF_ERROR(check_attribute_layout(*second, CloudRole::kSplitAttributes));
    draco::DecoderBuffer second_buffer;
    second_buffer.Init(reinterpret_cast<const char*>(rest), rest_size);
    HWR_RETURN_IF_ERROR(decode_cloud(&second_buffer, n, "attribute cloud: ", &attribute_cloud));
    HWR_RETURN_IF_ERROR(find_attributes(*attribute_cloud, &found));
    used += static_cast<size_t>(second_buffer.decoded_size());
  }
  if (used != size) {
    return core::CorruptData("decode_chunk: " + std::to_string(size - used) +
                             " bytes follow the chunk's Draco data (" + std::to_string(size) +
                             " bytes in all)");
  }
  const draco::PointAttribute* position = found.position;
  const draco::PointAttribute* color = found.color;
  const draco::PointAttribute* flags = found.flags;
  const draco::PointAttribute* point_id = found.point_id;
  const draco::PointAttribute* normal = found.normal;
  if (position == nullptr) return core::CorruptData("decode_chunk: the chunk has no position attribute");
  if (color == nullptr) return core::CorruptData("decode_chunk: the chunk has no colour attribute");

  const size_t count = static_cast<size_t>(n);
  out->points.resize(count);
  auto* point_bytes = reinterpret_cast<uint8_t*>(out->points.data());
  HWR_RETURN_IF_ERROR(copy_attribute(*position, n, 3 * sizeof(float), point_bytes + offsetof(ChunkPoint, x_m),
                                     sizeof(ChunkPoint), "position"));
  HWR_RETURN_IF_ERROR(
      copy_attribute(*color, n, 3, point_bytes + offsetof(ChunkPoint, r), sizeof(ChunkPoint), "colour"));
  if (found.color_level_bits < 8) {
    const int bits = found.color_level_bits;
    const uint8_t max_level = static_cast<uint8_t>((1 << bits) - 1);
    for (size_t i = 0; i < count; ++i) {
      ChunkPoint& p = out->points[i];
      if (p.r > max_level || p.g > max_level || p.b > max_level) {
        return core::CorruptData("decode_chunk: decoded colour of point " + std::to_string(i) +
                                 " is over level " + std::to_string(max_level) + " of its " +
                                 std::to_string(bits) + "-bit levels");
      }
      p.r = level_color(p.r, bits);
      p.g = level_color(p.g, bits);
      p.b = level_color(p.b, bits);
    }
  }
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
