#include "hwr/mapio/draco_header.hpp"

#include <cstdio>
#include <cstring>
#include <string>

namespace hwr::mapio {

namespace {

uint16_t read_le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

int32_t read_le32(const uint8_t* p) {
  const uint32_t u = static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
                     (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
  int32_t s;
  std::memcpy(&s, &u, sizeof s);
  return s;
}

// Bounds-checked little-endian reads over the chunk; every failed read names the field.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size, size_t pos) : data_(data), size_(size), pos_(pos) {}

  core::Status u8(uint8_t* v, const char* field) {
    if (size_ - pos_ < 1) return truncated(field);
    *v = data_[pos_++];
    return core::Status::Ok();
  }
  core::Status u32(uint32_t* v, const char* field) {
    if (size_ - pos_ < 4) return truncated(field);
    *v = static_cast<uint32_t>(read_le32(data_ + pos_));
    pos_ += 4;
    return core::Status::Ok();
  }
  // Draco's varint (core/varint_decoding.h): 7 bits per byte, lowest group first, high bit = more
  // follows, at most 5 bytes for a uint32.
  core::Status varint32(uint32_t* v, const char* field) {
    uint64_t value = 0;
    for (int i = 0; i < 5; ++i) {
      uint8_t b = 0;
      HWR_RETURN_IF_ERROR(u8(&b, field));
      value |= static_cast<uint64_t>(b & 0x7f) << (7 * i);
      if ((b & 0x80) == 0) {
        if (value > 0xffffffffu) break;
        *v = static_cast<uint32_t>(value);
        return core::Status::Ok();
      }
    }
    return core::CorruptData(std::string("Draco ") + field + " is not a valid 32-bit varint");
  }

 private:
  core::Status truncated(const char* field) const {
    return core::CorruptData(std::string("Draco chunk ends at byte ") + std::to_string(pos_) +
                             " before its " + field + " (truncated payload?)");
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_;
};

// Draco's enums as of 1.5.x: GeometryAttribute::Type has 5 named types (9 with the transcoder's
// TANGENT, MATERIAL, JOINTS, WEIGHTS; point-cloud chunks never use those), DataType runs 1..11.
constexpr uint8_t kDracoNamedAttributeTypes = 5;
constexpr uint8_t kDracoDataTypeFirst = 1;
constexpr uint8_t kDracoDataTypeLast = 11;
constexpr uint8_t kDracoSequentialDecoderTypeLast = 3;  // generic, integer, quantization, normals
constexpr uint8_t kDracoKdTreeMaxCompressionLevel = 6;

}  // namespace

core::Expected<DracoPointCloudHeader> parse_draco_point_cloud_header(const uint8_t* data, size_t size) {
  if (data == nullptr && size > 0)
    return core::InvalidArgument("Draco header: null data with a non-zero size");
  if (size < kDracoPointCloudHeaderBytes) {
    return core::CorruptData("Draco chunk is " + std::to_string(size) + " bytes, shorter than the " +
                             std::to_string(kDracoPointCloudHeaderBytes) +
                             "-byte point-cloud header (truncated payload?)");
  }
  if (std::memcmp(data, "DRACO", 5) != 0) {
    return core::CorruptData("chunk payload does not start with the \"DRACO\" magic: not a Draco bitstream");
  }
  DracoPointCloudHeader h;
  h.version_major = data[5];
  h.version_minor = data[6];
  if (h.version_major != kDracoBitstreamMajor || h.version_minor != kDracoBitstreamMinor) {
    return core::CorruptData("Draco bitstream version " + std::to_string(h.version_major) + "." +
                             std::to_string(h.version_minor) + " is not supported (expected " +
                             std::to_string(kDracoBitstreamMajor) + "." +
                             std::to_string(kDracoBitstreamMinor) + ")");
  }
  const uint8_t encoder_type = data[7];
  if (encoder_type != 0) {
    return core::CorruptData("Draco encoder type " + std::to_string(encoder_type) +
                             (encoder_type == 1 ? " (triangular mesh)" : "") + " is not a point cloud (0)");
  }
  const uint8_t method = data[8];
  if (method > 1) {
    return core::CorruptData("Draco point-cloud encoding method " + std::to_string(method) +
                             " is unknown (0 = sequential, 1 = kd-tree)");
  }
  h.method = static_cast<DracoPointCloudMethod>(method);
  h.flags = read_le16(data + 9);
  if (h.flags != 0) {
    char flags_hex[8];
    std::snprintf(flags_hex, sizeof flags_hex, "0x%04x", static_cast<unsigned>(h.flags));
    return core::CorruptData(std::string("Draco header flags ") + flags_hex +
                             " are set; chunks carry no metadata or other flagged sections");
  }
  h.num_points = read_le32(data + 11);
  if (h.num_points < 0) {
    return core::CorruptData("Draco header claims a negative point count (" + std::to_string(h.num_points) +
                             ")");
  }
  return h;
}

core::Expected<DracoPointCloudPrefix> parse_draco_point_cloud_prefix(const uint8_t* data, size_t size) {
  auto header = parse_draco_point_cloud_header(data, size);
  if (!header.ok()) return header.status();
  DracoPointCloudPrefix prefix;
  prefix.header = *header;
  Reader in(data, size, kDracoPointCloudHeaderBytes);

  uint8_t num_decoders = 0;
  HWR_RETURN_IF_ERROR(in.u8(&num_decoders, "number of attributes decoders"));
  if (num_decoders != 1) {
    return core::CorruptData("Draco chunk has " + std::to_string(num_decoders) +
                             " attributes decoders; point-cloud encoders write exactly 1");
  }
  uint32_t num_attributes = 0;
  HWR_RETURN_IF_ERROR(in.varint32(&num_attributes, "number of attributes"));
  if (num_attributes < 1 || num_attributes > static_cast<uint32_t>(kDracoMaxAttributes)) {
    return core::CorruptData("Draco chunk declares " + std::to_string(num_attributes) + " attributes (1.." +
                             std::to_string(kDracoMaxAttributes) + " accepted)");
  }
  prefix.num_attributes = static_cast<int>(num_attributes);
  for (uint32_t i = 0; i < num_attributes; ++i) {
    DracoAttributeDescriptor& a = prefix.attributes[i];
    uint8_t normalized = 0;
    HWR_RETURN_IF_ERROR(in.u8(&a.attribute_type, "attribute type"));
    HWR_RETURN_IF_ERROR(in.u8(&a.data_type, "attribute data type"));
    HWR_RETURN_IF_ERROR(in.u8(&a.num_components, "attribute component count"));
    HWR_RETURN_IF_ERROR(in.u8(&normalized, "attribute normalized flag"));
    HWR_RETURN_IF_ERROR(in.varint32(&a.unique_id, "attribute unique id"));
    a.normalized = normalized != 0;
    const std::string which = "Draco attribute " + std::to_string(i) + " ";
    if (a.attribute_type >= kDracoNamedAttributeTypes) {
      return core::CorruptData(which + "has unknown type " + std::to_string(a.attribute_type));
    }
    if (a.data_type < kDracoDataTypeFirst || a.data_type > kDracoDataTypeLast) {
      return core::CorruptData(which + "has unknown data type " + std::to_string(a.data_type));
    }
    if (a.num_components == 0) return core::CorruptData(which + "has 0 components");
  }

  if (prefix.header.method == DracoPointCloudMethod::kSequential) {
    for (uint32_t i = 0; i < num_attributes; ++i) {
      uint8_t decoder_type = 0;
      HWR_RETURN_IF_ERROR(in.u8(&decoder_type, "sequential attribute decoder type"));
      if (decoder_type > kDracoSequentialDecoderTypeLast) {
        return core::CorruptData("Draco attribute " + std::to_string(i) +
                                 " has unknown sequential decoder type " + std::to_string(decoder_type));
      }
    }
    return prefix;
  }

  HWR_RETURN_IF_ERROR(in.u8(&prefix.kd_tree_compression_level, "kd-tree compression level"));
  if (prefix.kd_tree_compression_level > kDracoKdTreeMaxCompressionLevel) {
    return core::CorruptData("Draco kd-tree compression level " +
                             std::to_string(prefix.kd_tree_compression_level) + " is over the maximum of 6");
  }
  HWR_RETURN_IF_ERROR(in.u32(&prefix.kd_tree_bit_length, "kd-tree bit length"));
  if (prefix.kd_tree_bit_length > 32) {
    return core::CorruptData("Draco kd-tree bit length " + std::to_string(prefix.kd_tree_bit_length) +
                             " is over 32");
  }
  uint32_t kd_points = 0;
  HWR_RETURN_IF_ERROR(in.u32(&kd_points, "kd-tree point count"));
  if (kd_points != static_cast<uint32_t>(prefix.header.num_points)) {
    return core::CorruptData("Draco kd-tree coder claims " + std::to_string(kd_points) +
                             " points, the header " + std::to_string(prefix.header.num_points));
  }
  return prefix;
}

}  // namespace hwr::mapio
