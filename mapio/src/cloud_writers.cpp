#include "hwr/mapio/cloud_writers.hpp"

#include <cstring>
#include <sstream>
#include <string_view>

#include "durable_file.hpp"
#include "hwr/core/file_io.hpp"

namespace hwr::mapio {
namespace {

// Both formats store little-endian values; the records are copied from memory as they are.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the cloud writers assume a little-endian host");

constexpr size_t kStagingBytes = size_t{1} << 20;
// A header longer than this is not one of ours (guards the line scan of a garbage file).
constexpr size_t kMaxHeaderBytes = 64 * 1024;

enum class Format { kPly, kPcd };

size_t record_bytes(Format format, bool normals) {
  // PLY: xyz float + (normals float) + rgb uchar; PCD: xyz float + rgb float + (normals float).
  if (format == Format::kPly) return 12 + (normals ? 12 : 0) + 3;
  return 16 + (normals ? 12 : 0);
}

std::string ply_header(size_t n, bool normals) {
  std::string h = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) + "\n";
  h += "property float x\nproperty float y\nproperty float z\n";
  if (normals) h += "property float nx\nproperty float ny\nproperty float nz\n";
  h += "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  return h;
}

std::string pcd_header(size_t n, bool normals) {
  const std::string count = std::to_string(n);
  std::string h = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n";
  h += normals ? "FIELDS x y z rgb normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4 4\nTYPE F F F F F F F\n"
                 "COUNT 1 1 1 1 1 1 1\n"
               : "FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n";
  h += "WIDTH " + count + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + count + "\nDATA binary\n";
  return h;
}

// One point's record in `format`'s field order.
void put_record(Format format, const float* xyz, const uint8_t* rgb, const float* normals, char* out) {
  std::memcpy(out, xyz, 12);
  if (format == Format::kPly) {
    if (normals != nullptr) {
      std::memcpy(out + 12, normals, 12);
      std::memcpy(out + 24, rgb, 3);
    } else {
      std::memcpy(out + 12, rgb, 3);
    }
    return;
  }
  const float packed = pack_pcl_rgb(rgb[0], rgb[1], rgb[2]);
  std::memcpy(out + 12, &packed, 4);
  if (normals != nullptr) std::memcpy(out + 16, normals, 12);
}

core::Status write_cloud(Format format, const std::string& path, const float* xyz, const uint8_t* rgb,
                         const float* normals, size_t n) {
  if (n > 0 && (xyz == nullptr || rgb == nullptr)) {
    return core::InvalidArgument(path + ": " + std::to_string(n) + " points but no xyz or rgb array");
  }
  const bool has_normals = normals != nullptr;
  const std::string header = format == Format::kPly ? ply_header(n, has_normals) : pcd_header(n, has_normals);
  detail::AtomicFileWriter file;
  HWR_RETURN_IF_ERROR(file.open(path));
  HWR_RETURN_IF_ERROR(file.write(header.data(), header.size()));

  const size_t stride = record_bytes(format, has_normals);
  const size_t per_flush = kStagingBytes / stride;
  std::vector<char> staging(per_flush * stride);
  for (size_t first = 0; first < n; first += per_flush) {
    const size_t count = std::min(per_flush, n - first);
    for (size_t k = 0; k < count; ++k) {
      const size_t i = first + k;
      put_record(format, xyz + 3 * i, rgb + 3 * i, has_normals ? normals + 3 * i : nullptr,
                 staging.data() + k * stride);
    }
    HWR_RETURN_IF_ERROR(file.write(staging.data(), count * stride));
  }
  return file.commit();
}

// --- readers -------------------------------------------------------------------------------------

// Splits the header off `bytes`: the lines up to and including the one equal to `last` (a prefix
// match for PCD's "DATA binary"). Returns false when there is no such line in the first
// kMaxHeaderBytes.
bool split_header(const std::string& bytes, std::string_view last, std::vector<std::string>* lines,
                  size_t* data_offset) {
  size_t pos = 0;
  const size_t limit = std::min(bytes.size(), kMaxHeaderBytes);
  while (pos < limit) {
    const size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos || eol >= limit) return false;
    std::string line = bytes.substr(pos, eol - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = eol + 1;
    lines->push_back(line);
    if (line == last) {
      *data_offset = pos;
      return true;
    }
  }
  return false;
}

std::vector<std::string> tokens(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string t; in >> t;) out.push_back(t);
  return out;
}

// Strict non-negative decimal ("12", not "+12", "1e3" or "12x").
bool parse_count(const std::string& text, uint64_t* out) {
  if (text.empty() || text.size() > 19) return false;
  uint64_t v = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<uint64_t>(c - '0');
  }
  *out = v;
  return true;
}

// Checks that the data after the header holds exactly n records, before anything is allocated.
core::Status check_data_size(const std::string& path, uint64_t n, size_t stride, size_t data_bytes) {
  if (n > data_bytes / stride || n * stride != data_bytes) {
    return core::CorruptData(path + ": header declares " + std::to_string(n) + " points (" +
                             std::to_string(stride) + " bytes each) but " + std::to_string(data_bytes) +
                             " data bytes follow");
  }
  return core::Status::Ok();
}

void allocate(CloudArrays* out, size_t n, bool normals) {
  out->xyz.resize(3 * n);
  out->rgb.resize(3 * n);
  out->normals.assign(normals ? 3 * n : 0, 0.0f);
  out->has_normals = normals;
}

bool is_float_type(const std::string& t) { return t == "float" || t == "float32"; }
bool is_uchar_type(const std::string& t) { return t == "uchar" || t == "uint8"; }

}  // namespace

float pack_pcl_rgb(uint8_t r, uint8_t g, uint8_t b) {
  const uint32_t bits = (uint32_t{r} << 16) | (uint32_t{g} << 8) | uint32_t{b};
  float packed;
  std::memcpy(&packed, &bits, sizeof(packed));
  return packed;
}

void unpack_pcl_rgb(float rgb, uint8_t* r, uint8_t* g, uint8_t* b) {
  uint32_t bits;
  std::memcpy(&bits, &rgb, sizeof(bits));
  *r = static_cast<uint8_t>((bits >> 16) & 0xffu);
  *g = static_cast<uint8_t>((bits >> 8) & 0xffu);
  *b = static_cast<uint8_t>(bits & 0xffu);
}

core::Status write_ply(const std::string& path, const float* xyz, const uint8_t* rgb,
                       const float* normals_or_null, size_t n) {
  return write_cloud(Format::kPly, path, xyz, rgb, normals_or_null, n);
}

core::Status write_pcd(const std::string& path, const float* xyz, const uint8_t* rgb,
                       const float* normals_or_null, size_t n) {
  return write_cloud(Format::kPcd, path, xyz, rgb, normals_or_null, n);
}

core::Status read_ply(const std::string& path, CloudArrays* out) {
  std::string bytes;
  HWR_RETURN_IF_ERROR(core::read_file(path, &bytes));
  std::vector<std::string> lines;
  size_t data_offset = 0;
  if (!split_header(bytes, "end_header", &lines, &data_offset) || lines.front() != "ply") {
    return core::ParseError(path + ": not a PLY file (no 'ply' ... 'end_header' header)");
  }
  bool format_ok = false, vertex_seen = false;
  uint64_t n = 0;
  std::vector<std::string> properties;  // "float x", ...
  for (size_t i = 1; i + 1 < lines.size(); ++i) {
    const std::vector<std::string> t = tokens(lines[i]);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "format") {
      if (t.size() != 3 || t[1] != "binary_little_endian" || t[2] != "1.0") {
        return core::ParseError(path + ": '" + lines[i] + "': only binary_little_endian 1.0 is read");
      }
      format_ok = true;
    } else if (t[0] == "element") {
      if (vertex_seen || t.size() != 3 || t[1] != "vertex" || !parse_count(t[2], &n)) {
        return core::ParseError(path + ": '" + lines[i] + "': expected one 'element vertex N'");
      }
      vertex_seen = true;
    } else if (t[0] == "property" && vertex_seen && t.size() == 3) {
      const char* type = is_float_type(t[1]) ? "float " : is_uchar_type(t[1]) ? "uchar " : "? ";
      properties.push_back(type + t[2]);
    } else {
      return core::ParseError(path + ": unexpected header line '" + lines[i] + "'");
    }
  }
  if (!format_ok || !vertex_seen)
    return core::ParseError(path + ": PLY header lacks 'format' or 'element vertex'");
  const std::vector<std::string> plain = {"float x",   "float y",     "float z",
                                          "uchar red", "uchar green", "uchar blue"};
  const std::vector<std::string> with_normals = {"float x",   "float y",     "float z",
                                                 "float nx",  "float ny",    "float nz",
                                                 "uchar red", "uchar green", "uchar blue"};
  const bool normals = properties == with_normals;
  if (!normals && properties != plain) {
    return core::ParseError(path +
                            ": vertex properties are not x y z [nx ny nz] red green blue (float/uchar)");
  }
  const size_t stride = record_bytes(Format::kPly, normals);
  HWR_RETURN_IF_ERROR(check_data_size(path, n, stride, bytes.size() - data_offset));
  allocate(out, n, normals);
  const char* p = bytes.data() + data_offset;
  for (size_t i = 0; i < n; ++i, p += stride) {
    std::memcpy(&out->xyz[3 * i], p, 12);
    if (normals) {
      std::memcpy(&out->normals[3 * i], p + 12, 12);
      std::memcpy(&out->rgb[3 * i], p + 24, 3);
    } else {
      std::memcpy(&out->rgb[3 * i], p + 12, 3);
    }
  }
  return core::Status::Ok();
}

core::Status read_pcd(const std::string& path, CloudArrays* out) {
  std::string bytes;
  HWR_RETURN_IF_ERROR(core::read_file(path, &bytes));
  std::vector<std::string> lines;
  size_t data_offset = 0;
  if (!split_header(bytes, "DATA binary", &lines, &data_offset)) {
    return core::ParseError(path + ": not a binary PCD file (no 'DATA binary' line in its header)");
  }
  std::vector<std::string> fields, sizes, types, counts;
  uint64_t width = 0, height = 0, points = 0;
  bool version_ok = false, have_width = false, have_height = false, have_points = false;
  for (size_t i = 0; i + 1 < lines.size(); ++i) {
    const std::vector<std::string> t = tokens(lines[i]);
    if (t.empty() || t[0][0] == '#') continue;
    const std::vector<std::string> rest(t.begin() + 1, t.end());
    if (t[0] == "VERSION") {
      version_ok = rest.size() == 1 && (rest[0] == "0.7" || rest[0] == ".7");
    } else if (t[0] == "FIELDS") {
      fields = rest;
    } else if (t[0] == "SIZE") {
      sizes = rest;
    } else if (t[0] == "TYPE") {
      types = rest;
    } else if (t[0] == "COUNT") {
      counts = rest;
    } else if (t[0] == "WIDTH") {
      have_width = rest.size() == 1 && parse_count(rest[0], &width);
    } else if (t[0] == "HEIGHT") {
      have_height = rest.size() == 1 && parse_count(rest[0], &height);
    } else if (t[0] == "POINTS") {
      have_points = rest.size() == 1 && parse_count(rest[0], &points);
    } else if (t[0] != "VIEWPOINT") {
      return core::ParseError(path + ": unexpected PCD header line '" + lines[i] + "'");
    }
  }
  if (!version_ok) return core::ParseError(path + ": PCD header lacks 'VERSION 0.7'");
  const std::vector<std::string> plain = {"x", "y", "z", "rgb"};
  const std::vector<std::string> with_normals = {"x", "y", "z", "rgb", "normal_x", "normal_y", "normal_z"};
  const bool normals = fields == with_normals;
  if (!normals && fields != plain) {
    return core::ParseError(path + ": FIELDS are not 'x y z rgb [normal_x normal_y normal_z]'");
  }
  if (sizes != std::vector<std::string>(fields.size(), "4") ||
      types != std::vector<std::string>(fields.size(), "F") ||
      counts != std::vector<std::string>(fields.size(), "1")) {
    return core::ParseError(path + ": expected SIZE 4, TYPE F and COUNT 1 for every field");
  }
  if (!have_width || !have_height || !have_points || height == 0 || width > points ||
      points / height != width || points % height != 0) {
    return core::ParseError(path +
                            ": WIDTH, HEIGHT and POINTS missing or inconsistent (WIDTH x HEIGHT != POINTS)");
  }
  const size_t stride = record_bytes(Format::kPcd, normals);
  HWR_RETURN_IF_ERROR(check_data_size(path, points, stride, bytes.size() - data_offset));
  allocate(out, points, normals);
  const char* p = bytes.data() + data_offset;
  for (size_t i = 0; i < points; ++i, p += stride) {
    std::memcpy(&out->xyz[3 * i], p, 12);
    float packed;
    std::memcpy(&packed, p + 12, 4);
    unpack_pcl_rgb(packed, &out->rgb[3 * i], &out->rgb[3 * i + 1], &out->rgb[3 * i + 2]);
    if (normals) std::memcpy(&out->normals[3 * i], p + 16, 12);
  }
  return core::Status::Ok();
}

}  // namespace hwr::mapio
