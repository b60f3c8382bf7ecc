#include "ndt_clouds.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace hwr::bench {
namespace {

core::Expected<std::string> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return core::NotFound("cannot open '" + path + "' (is ../shared/data present? see its README.md)");
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// Reads header lines (terminated by '\n', '\r' stripped) from `data` at *pos.
bool next_line(const std::string& data, size_t* pos, std::string* line) {
  if (*pos >= data.size()) return false;
  const size_t end = data.find('\n', *pos);
  const size_t stop = end == std::string::npos ? data.size() : end;
  *line = data.substr(*pos, stop - *pos);
  if (!line->empty() && line->back() == '\r') line->pop_back();
  *pos = end == std::string::npos ? data.size() : end + 1;
  return true;
}

std::vector<std::string> split_ws(const std::string& s) {
  std::istringstream is(s);
  std::vector<std::string> out;
  for (std::string w; is >> w;) out.push_back(w);
  return out;
}

// LZF decompression (Marc Lehmann's liblzf format, which PCL's binary_compressed PCD uses): a
// control byte c < 32 starts a run of c + 1 literal bytes; otherwise a back reference of length
// (c >> 5) + 2 (length 7 continues in the next byte) at distance ((c & 31) << 8) + next byte + 1.
core::Status lzf_decompress(const uint8_t* in, size_t in_size, uint8_t* out, size_t out_size) {
  const uint8_t* ip = in;
  const uint8_t* const in_end = in + in_size;
  uint8_t* op = out;
  uint8_t* const out_end = out + out_size;
  while (ip < in_end) {
    const unsigned ctrl = *ip++;
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (ip + len > in_end || op + len > out_end)
        return core::CorruptData("LZF literal run past the buffer end");
      std::memcpy(op, ip, len);
      op += len;
      ip += len;
      continue;
    }
    size_t len = ctrl >> 5;
    if (ip >= in_end) return core::CorruptData("LZF back reference truncated");
    if (len == 7) {
      len += *ip++;
      if (ip >= in_end) return core::CorruptData("LZF back reference truncated");
    }
    const size_t dist = ((ctrl & 0x1fu) << 8) + *ip++ + 1;
    len += 2;
    if (dist > static_cast<size_t>(op - out) || op + len > out_end) {
      return core::CorruptData("LZF back reference outside the output");
    }
    const uint8_t* ref = op - dist;
    for (size_t k = 0; k < len; ++k) *op++ = *ref++;  // may overlap: byte by byte
  }
  if (op != out_end) return core::CorruptData("LZF stream decompressed to fewer bytes than the header says");
  return core::Status::Ok();
}

int64_t voxel_key(const Eigen::Vector3f& p, double inv_leaf) {
  // 21 bits per axis, offset so negative indices pack; 2^20 voxels each side of the origin.
  const auto idx = [&](float v) {
    return static_cast<int64_t>(std::floor(static_cast<double>(v) * inv_leaf)) + (int64_t{1} << 20);
  };
  return (idx(p.x()) << 42) | (idx(p.y()) << 21) | idx(p.z());
}

}  // namespace

core::Expected<XyzCloud> read_ply_xyz(const std::string& path) {
  auto data = slurp(path);
  if (!data.ok()) return data.status();
  const std::string& d = *data;
  size_t pos = 0;
  std::string line;
  if (!next_line(d, &pos, &line) || line != "ply")
    return core::ParseError(path + ": not a PLY file (no 'ply' magic)");
  bool binary = false, in_vertex = false, vertex_seen = false;
  long n = -1;
  int stride = 0, off[3] = {-1, -1, -1}, type_size[3] = {0, 0, 0};
  std::vector<std::string> ascii_props;
  const auto size_of = [](const std::string& t) -> int {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32")
      return 4;
    if (t == "double" || t == "float64") return 8;
    return 0;
  };
  while (true) {
    if (!next_line(d, &pos, &line)) return core::ParseError(path + ": PLY header has no end_header");
    const auto w = split_ws(line);
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (w.size() < 2 || (w[1] != "binary_little_endian" && w[1] != "ascii")) {
        return core::ParseError(path + ": PLY format '" + line +
                                "' not supported (binary_little_endian or ascii)");
      }
      binary = w[1] == "binary_little_endian";
    } else if (w[0] == "element") {
      if (w.size() < 3) return core::ParseError(path + ": bad PLY element line '" + line + "'");
      in_vertex = w[1] == "vertex";
      if (in_vertex) {
        n = std::atol(w[2].c_str());
        vertex_seen = true;
      } else if (!vertex_seen) {
        return core::ParseError(path + ": PLY element '" + w[1] + "' before 'vertex' is not supported");
      }
    } else if (w[0] == "property" && in_vertex) {
      if (w.size() < 3 || w[1] == "list")
        return core::ParseError(path + ": list property in the vertex element");
      const int s = size_of(w[1]);
      if (s == 0) return core::ParseError(path + ": unknown PLY type '" + w[1] + "'");
      for (int a = 0; a < 3; ++a) {
        if (w[2] == std::string(1, "xyz"[a])) {
          if (w[1] != "float" && w[1] != "float32" && w[1] != "double" && w[1] != "float64") {
            return core::ParseError(path + ": PLY coordinate '" + w[2] + "' is not float/double");
          }
          off[a] = stride;
          type_size[a] = s;
        }
      }
      ascii_props.push_back(w[2]);
      stride += s;
    }
  }
  if (n < 0 || off[0] < 0 || off[1] < 0 || off[2] < 0)
    return core::ParseError(path + ": PLY has no vertex x, y, z");
  XyzCloud c;
  c.xyz.resize(static_cast<size_t>(n) * 3);
  if (binary) {
    if (pos + static_cast<size_t>(n) * stride > d.size())
      return core::CorruptData(path + ": PLY vertex data truncated");
    for (long i = 0; i < n; ++i) {
      const char* row = d.data() + pos + static_cast<size_t>(i) * stride;
      for (int a = 0; a < 3; ++a) {
        if (type_size[a] == 4) {
          float v;
          std::memcpy(&v, row + off[a], 4);
          c.xyz[3 * i + a] = v;
        } else {
          double v;
          std::memcpy(&v, row + off[a], 8);
          c.xyz[3 * i + a] = static_cast<float>(v);
        }
      }
    }
  } else {
    std::istringstream is(d.substr(pos));
    for (long i = 0; i < n; ++i) {
      for (size_t k = 0; k < ascii_props.size(); ++k) {
        double v;
        if (!(is >> v)) return core::CorruptData(path + ": PLY ascii vertex data truncated");
        for (int a = 0; a < 3; ++a) {
          if (ascii_props[k] == std::string(1, "xyz"[a])) c.xyz[3 * i + a] = static_cast<float>(v);
        }
      }
    }
  }
  return c;
}

core::Expected<XyzCloud> read_pcd_xyz(const std::string& path) {
  auto data = slurp(path);
  if (!data.ok()) return data.status();
  const std::string& d = *data;
  size_t pos = 0;
  std::string line;
  std::vector<std::string> fields, types;
  std::vector<int> sizes, counts;
  long points = -1;
  std::string mode;
  while (next_line(d, &pos, &line)) {
    auto w = split_ws(line);
    if (w.empty() || w[0][0] == '#') continue;
    const std::string key = w[0];
    w.erase(w.begin());
    if (key == "FIELDS") fields = w;
    if (key == "TYPE") types = w;
    if (key == "SIZE") {
      for (const auto& s : w) sizes.push_back(std::atoi(s.c_str()));
    }
    if (key == "COUNT") {
      for (const auto& s : w) counts.push_back(std::atoi(s.c_str()));
    }
    if (key == "POINTS" && !w.empty()) points = std::atol(w[0].c_str());
    if (key == "DATA") {
      mode = w.empty() ? "" : w[0];
      break;
    }
  }
  if (mode.empty() || points < 0 || fields.empty()) return core::ParseError(path + ": incomplete PCD header");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (sizes.size() != fields.size() || types.size() != fields.size() || counts.size() != fields.size()) {
    return core::ParseError(path + ": PCD FIELDS/SIZE/TYPE/COUNT lengths differ");
  }
  int field_index[3] = {-1, -1, -1};
  std::vector<size_t> aos_offset(fields.size());
  size_t point_bytes = 0;
  for (size_t f = 0; f < fields.size(); ++f) {
    aos_offset[f] = point_bytes;
    point_bytes += static_cast<size_t>(sizes[f]) * counts[f];
    for (int a = 0; a < 3; ++a) {
      if (fields[f] == std::string(1, "xyz"[a])) {
        if (sizes[f] != 4 || types[f] != "F" || counts[f] != 1) {
          return core::ParseError(path + ": PCD field '" + fields[f] + "' is not a single 4-byte float");
        }
        field_index[a] = static_cast<int>(f);
      }
    }
  }
  if (field_index[0] < 0 || field_index[1] < 0 || field_index[2] < 0) {
    return core::ParseError(path + ": PCD has no x, y, z fields");
  }
  XyzCloud c;
  c.xyz.resize(static_cast<size_t>(points) * 3);
  const size_t n = static_cast<size_t>(points);
  if (mode == "ascii") {
    std::istringstream is(d.substr(pos));
    for (size_t i = 0; i < n; ++i) {
      for (size_t f = 0; f < fields.size(); ++f) {
        for (int k = 0; k < counts[f]; ++k) {
          std::string tok;
          if (!(is >> tok)) return core::CorruptData(path + ": PCD ascii data truncated");
          for (int a = 0; a < 3; ++a) {
            if (static_cast<int>(f) == field_index[a]) c.xyz[3 * i + a] = std::strtof(tok.c_str(), nullptr);
          }
        }
      }
    }
  } else if (mode == "binary") {
    if (pos + n * point_bytes > d.size()) return core::CorruptData(path + ": PCD binary data truncated");
    for (size_t i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a) {
        std::memcpy(&c.xyz[3 * i + a], d.data() + pos + i * point_bytes + aos_offset[field_index[a]], 4);
      }
    }
  } else if (mode == "binary_compressed") {
    uint32_t compressed = 0, uncompressed = 0;
    if (pos + 8 > d.size()) return core::CorruptData(path + ": PCD compressed header truncated");
    std::memcpy(&compressed, d.data() + pos, 4);
    std::memcpy(&uncompressed, d.data() + pos + 4, 4);
    if (pos + 8 + compressed > d.size() || uncompressed != n * point_bytes) {
      return core::CorruptData(path + ": PCD compressed sizes disagree with the header/file size");
    }
    std::vector<uint8_t> raw(uncompressed);
    const auto st = lzf_decompress(reinterpret_cast<const uint8_t*>(d.data() + pos + 8), compressed,
                                   raw.data(), raw.size());
    if (!st.ok()) return core::CorruptData(path + ": " + st.message());
    // Struct of arrays: every field's values for all points, field after field.
    size_t soa_offset = 0;
    for (size_t f = 0; f < fields.size(); ++f) {
      for (int a = 0; a < 3; ++a) {
        if (static_cast<int>(f) != field_index[a]) continue;
        for (size_t i = 0; i < n; ++i) std::memcpy(&c.xyz[3 * i + a], raw.data() + soa_offset + 4 * i, 4);
      }
      soa_offset += static_cast<size_t>(sizes[f]) * counts[f] * n;
    }
  } else {
    return core::ParseError(path + ": PCD DATA '" + mode + "' not supported");
  }
  return c;
}

core::Expected<XyzCloud> read_csv_xyz(const std::string& path) {
  auto data = slurp(path);
  if (!data.ok()) return data.status();
  std::istringstream is(*data);
  std::string line;
  std::getline(is, line);  // header
  XyzCloud c;
  int line_no = 1;
  while (std::getline(is, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    for (char& ch : line) {
      if (ch == ',') ch = ' ';
    }
    std::istringstream ls(line);
    float x, y, z;
    if (!(ls >> x >> y >> z))
      return core::ParseError(path + ":" + std::to_string(line_no) + ": expected x,y,z");
    c.push({x, y, z});
  }
  return c;
}

core::Expected<Eigen::Isometry3d> read_matrix4_txt(const std::string& path) {
  auto data = slurp(path);
  if (!data.ok()) return data.status();
  std::istringstream is(*data);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!(is >> m(r, c))) return core::ParseError(path + ": expected 16 numbers (a 4x4 matrix)");
    }
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(m.block<3, 3>(0, 0)).normalized().toRotationMatrix();
  T.translation() = m.block<3, 1>(0, 3);
  return T;
}

core::Expected<Eigen::Isometry3d> read_pointmatcher_pose(const std::string& list_csv,
                                                         const std::string& reading) {
  auto data = slurp(list_csv);
  if (!data.ok()) return data.status();
  std::istringstream is(*data);
  std::string line;
  while (std::getline(is, line)) {
    for (char& ch : line) {
      if (ch == ',') ch = ' ';
    }
    std::istringstream ls(line);
    std::string name;
    ls >> name;
    if (name != reading) continue;
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (!(ls >> m(r, c)))
          return core::ParseError(list_csv + ": row '" + reading + "' has fewer than 16 numbers");
      }
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(m.block<3, 3>(0, 0)).normalized().toRotationMatrix();
    T.translation() = m.block<3, 1>(0, 3);
    return T;
  }
  return core::NotFound(list_csv + ": no row for '" + reading + "'");
}

XyzCloud voxel_downsample(const XyzCloud& in, double leaf_m) {
  const double inv = 1.0 / leaf_m;
  std::vector<std::pair<int64_t, int>> keyed;
  keyed.reserve(static_cast<size_t>(in.size()));
  for (int i = 0; i < in.size(); ++i) {
    const Eigen::Vector3f p = in.at(i);
    if (!p.allFinite()) continue;
    keyed.emplace_back(voxel_key(p, inv), i);
  }
  std::sort(keyed.begin(), keyed.end());
  XyzCloud out;
  for (size_t a = 0; a < keyed.size();) {
    size_t b = a;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    while (b < keyed.size() && keyed[b].first == keyed[a].first)
      sum += in.at(keyed[b++].second).cast<double>();
    out.push((sum / static_cast<double>(b - a)).cast<float>());
    a = b;
  }
  return out;
}

XyzCloud transformed(const XyzCloud& in, const Eigen::Isometry3d& T) {
  XyzCloud out;
  out.xyz.reserve(in.xyz.size());
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (int i = 0; i < in.size(); ++i) out.push(Tf * in.at(i));
  return out;
}

XyzCloud range_filtered(const XyzCloud& in, double min_m, double max_m) {
  XyzCloud out;
  for (int i = 0; i < in.size(); ++i) {
    const double r = in.at(i).cast<double>().norm();
    if (r >= min_m && r <= max_m) out.push(in.at(i));
  }
  return out;
}

double rms_nearest_distance(const XyzCloud& target, const XyzCloud& source, const Eigen::Isometry3d& T,
                            double cell_m) {
  const double inv = 1.0 / cell_m;
  std::unordered_map<int64_t, std::vector<int>> grid;
  for (int i = 0; i < target.size(); ++i) {
    if (target.at(i).allFinite()) grid[voxel_key(target.at(i), inv)].push_back(i);
  }
  const Eigen::Isometry3f Tf = T.cast<float>();
  double sum_sq = 0;
  long used = 0;
  for (int i = 0; i < source.size(); ++i) {
    const Eigen::Vector3f p = Tf * source.at(i);
    if (!p.allFinite()) continue;
    float best = std::numeric_limits<float>::infinity();
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const Eigen::Vector3f q = p + Eigen::Vector3f(dx, dy, dz) * static_cast<float>(cell_m);
          const auto it = grid.find(voxel_key(q, inv));
          if (it == grid.end()) continue;
          for (const int j : it->second) best = std::min(best, (target.at(j) - p).squaredNorm());
        }
      }
    }
    if (best <= cell_m * cell_m) {
      sum_sq += best;
      ++used;
    }
  }
  return used == 0 ? std::nan("") : std::sqrt(sum_sq / static_cast<double>(used));
}

}  // namespace hwr::bench
