#include "hwr/recon/map_store.hpp"

#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>

#include "hwr/core/config.hpp"
#include "hwr/core/file_io.hpp"
#include "hwr/core/se3.hpp"
#include "map_store_binary.hpp"
#include "map_store_files.hpp"

namespace hwr::recon {
namespace {

namespace fs = std::filesystem;
using store_detail::BinExpectation;
using store_detail::BinHeader;
using store_detail::ByteSpan;
using store_detail::FineExpectation;

// store.yaml and segment.yaml. Version 2 added the welding regions: segment.yaml's fine_voxel_m,
// weld_regions, fine_points, fine_bin_bytes and fine_bin_crc32, and the segment's fine.bin.
//   - A segment.yaml of version 1 has none of those keys (they are unknown keys there) and no
//     fine.bin; it reads with empty fine data. Version 2 requires the keys and the file.
//   - store.yaml is written once, when the store is created, with the version of the build that
//     created it; it does not change when segments are added. This build creates stores at version
//     2, opens stores of version 1 and 2, and writes every new segment at version 2, also into a
//     version-1 store (store.yaml's own content is the same in both versions). Each segment.yaml
//     carries its own version, and a reader checks that one: a build older than the segment refuses
//     it (kInvalidArgument, "newer than this build reads"), never misreads it.
//   - Anything newer than this build's version, store.yaml or segment.yaml, is refused.
constexpr uint32_t kStoreFormatVersion = 2;
constexpr uint32_t kFirstFineFormatVersion = 2;  // segments from this version on have fine.bin
constexpr char kStoreYaml[] = "store.yaml";
constexpr char kSegmentsDir[] = "segments";
constexpr char kSegmentYaml[] = "segment.yaml";
constexpr char kKeyframesBin[] = "keyframes.bin";
constexpr char kCloudBin[] = "cloud.bin";
constexpr char kFineBin[] = "fine.bin";
constexpr char kTmpPrefix[] = ".tmp-";
// segment.yaml ends with this key; its value is the CRC32 of every byte before the line, so a
// flipped digit in a pose is caught like one in the binary files.
constexpr char kSelfCrcKey[] = "self_crc32";

// ---- text writing (printf-style; doubles with %.17g round-trip exactly through strtod) ----

__attribute__((format(printf, 2, 3))) void appendf(std::string* s, const char* fmt, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, fmt);
  const int n = std::vsnprintf(buf, sizeof(buf), fmt, ap);
  va_end(ap);
  if (n > 0) s->append(buf, std::min(static_cast<size_t>(n), sizeof(buf) - 1));
}

std::string yaml_double(double v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// The 12 doubles of the 3x4 matrix [R | t], row by row: bit-exact, unlike a quaternion.
std::string yaml_pose(const Eigen::Isometry3d& T) {
  std::string s = "[";
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (r + c > 0) s += ", ";
      s += yaml_double(T.matrix()(r, c));
    }
  }
  return s + "]";
}

std::string yaml_quoted(const std::string& v) {
  std::string s = "\"";
  for (char ch : v) {
    if (ch == '"' || ch == '\\') s += '\\';
    s += ch;
  }
  return s + "\"";
}

// ---- text reading (strict ConfigDocument) ----

// A uint32 through the int64 reader; absence and type errors are recorded by require().
void read_u32(core::ConfigMap& m, const char* key, uint32_t* out) {
  int64_t v = -1;
  m.require(key, &v);
  if (!m.has(key)) return;
  if (v < 0 || v > int64_t{std::numeric_limits<uint32_t>::max()}) {
    m.record_error(key, "expected an integer in [0, 4294967295]");
    return;
  }
  *out = static_cast<uint32_t>(v);
}

void read_pose(core::ConfigMap& m, const char* key, Eigen::Isometry3d* T) {
  std::vector<double> v;
  m.require(key, &v);
  if (!m.has(key)) return;
  if (v.size() != 12) {
    m.record_error(
        key, "expected the 12 numbers of a 3x4 pose [R | t] row by row, got " + std::to_string(v.size()));
    return;
  }
  *T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) T->matrix()(r, c) = v[static_cast<size_t>(4 * r + c)];
  }
}

// finish() reports type errors as kInvalidArgument; for a file we wrote they mean a malformed file.
core::Status finish_as_parse_error(const core::ConfigDocument& doc) {
  const core::Status st = doc.finish();
  if (st.ok()) return st;
  return core::ParseError(st.message());
}

// ---- paths ----

std::string join(const std::string& a, const char* b) { return a + "/" + b; }

std::string segment_dir_name(uint32_t id) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "seg_%06" PRIu32, id);
  return buf;
}

// "seg_NNNNNN" exactly as segment_dir_name writes it; anything else in segments/ is not ours.
bool parse_segment_dir_name(const char* name, uint32_t* id) {
  if (std::strncmp(name, "seg_", 4) != 0) return false;
  const char* digits = name + 4;
  const size_t n = std::strlen(digits);
  if (n < 6 || n > 10) return false;
  uint64_t v = 0;
  for (size_t i = 0; i < n; ++i) {
    if (digits[i] < '0' || digits[i] > '9') return false;
    v = v * 10 + static_cast<uint64_t>(digits[i] - '0');
  }
  if (v > std::numeric_limits<uint32_t>::max()) return false;
  *id = static_cast<uint32_t>(v);
  return segment_dir_name(*id) == name;
}

bool is_directory(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool path_exists(const std::string& path) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0;
}

// Entry names of a directory (without . and ..).
core::Status list_directory(const std::string& dir, std::vector<std::string>* names) {
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return core::IoError(dir + ": cannot list: " + std::strerror(errno));
  names->clear();
  errno = 0;
  while (const dirent* e = ::readdir(d)) {
    if (std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0) names->push_back(e->d_name);
  }
  const int err = errno;
  ::closedir(d);
  if (err != 0) return core::IoError(dir + ": listing failed: " + std::strerror(err));
  return core::Status::Ok();
}

core::Status segment_ids(const std::string& segments_dir, std::vector<uint32_t>* ids) {
  std::vector<std::string> names;
  HWR_RETURN_IF_ERROR(list_directory(segments_dir, &names));
  ids->clear();
  for (const std::string& n : names) {
    uint32_t id = 0;
    if (parse_segment_dir_name(n.c_str(), &id) && is_directory(segments_dir + "/" + n)) ids->push_back(id);
  }
  std::sort(ids->begin(), ids->end());
  return core::Status::Ok();
}

// Removes the .tmp- leftovers of writes a crash interrupted (the store has one writer).
core::Status remove_temporaries(const std::string& dir) {
  std::vector<std::string> names;
  HWR_RETURN_IF_ERROR(list_directory(dir, &names));
  for (const std::string& n : names) {
    if (n.compare(0, sizeof(kTmpPrefix) - 1, kTmpPrefix) != 0) continue;
    std::error_code ec;
    fs::remove_all(dir + "/" + n, ec);
    if (ec) return core::IoError(dir + "/" + n + ": cannot remove an interrupted write: " + ec.message());
  }
  return core::Status::Ok();
}

// ---- store.yaml ----

// A new store is created at kStoreFormatVersion whatever the argument's format_version (its
// default is kStoreFormatVersion), as long as that is not newer than this build.
core::Status validate_metadata(const StoreMetadata& m) {
  if (m.format_version < 1 || m.format_version > kStoreFormatVersion) {
    return core::InvalidArgument("map store: this build writes format_version " +
                                 std::to_string(kStoreFormatVersion) + ", metadata asks for " +
                                 std::to_string(m.format_version));
  }
  if (m.descriptor_bytes < 1 ||
      static_cast<uint32_t>(m.descriptor_bytes) > store_detail::kMaxDescriptorBytes) {
    return core::InvalidArgument("map store: descriptor_bytes must be in [1, " +
                                 std::to_string(store_detail::kMaxDescriptorBytes) + "], got " +
                                 std::to_string(m.descriptor_bytes));
  }
  for (const std::string* s : {&m.robot_id, &m.run_id}) {
    for (char ch : *s) {
      if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) {
        return core::InvalidArgument("map store: robot_id and run_id must not hold control characters");
      }
    }
  }
  const std::string problem = core::rigid_transform_problem(m.T_imu_cam);
  if (!problem.empty()) return core::InvalidArgument("map store: metadata T_imu_cam " + problem);
  return core::Status::Ok();
}

std::string store_yaml_text(const StoreMetadata& m) {
  std::string s = "# hwr-perception map store (recon/include/hwr/recon/map_store.hpp)\n";
  appendf(&s, "format_version: %" PRIu32 "\n", m.format_version);
  s += "robot_id: " + yaml_quoted(m.robot_id) + "\n";
  s += "run_id: " + yaml_quoted(m.run_id) + "\n";
  appendf(&s, "descriptor_bytes: %d\n", m.descriptor_bytes);
  s += "intrinsics:\n";
  appendf(&s, "  width: %d\n  height: %d\n", m.intrinsics.width, m.intrinsics.height);
  s += "  fx: " + yaml_double(m.intrinsics.fx) + "\n";
  s += "  fy: " + yaml_double(m.intrinsics.fy) + "\n";
  s += "  cx: " + yaml_double(m.intrinsics.cx) + "\n";
  s += "  cy: " + yaml_double(m.intrinsics.cy) + "\n";
  s += "  distortion: [";
  for (size_t i = 0; i < m.intrinsics.distortion.size(); ++i) {
    s += (i ? ", " : "") + yaml_double(m.intrinsics.distortion[i]);
  }
  s += "]  # k1 k2 p1 p2 k3\n";
  s += "T_imu_cam: " + yaml_pose(m.T_imu_cam) + "  # camera in the IMU frame, rows of [R | t]\n";
  return s;
}

core::Expected<StoreMetadata> read_store_yaml(const std::string& path) {
  auto doc = core::ConfigDocument::load_file(path);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  StoreMetadata m;
  read_u32(root, "format_version", &m.format_version);
  if (m.format_version > kStoreFormatVersion) {
    return core::InvalidArgument(path + ": format_version " + std::to_string(m.format_version) +
                                 " is newer than this build reads (" + std::to_string(kStoreFormatVersion) +
                                 "); use a newer hwr-perception");
  }
  if (m.format_version < 1) root.record_error("format_version", "must be at least 1");
  root.require("robot_id", &m.robot_id);
  root.require("run_id", &m.run_id);
  root.require("descriptor_bytes", &m.descriptor_bytes);
  if (m.descriptor_bytes < 1 ||
      static_cast<uint32_t>(m.descriptor_bytes) > store_detail::kMaxDescriptorBytes) {
    root.record_error("descriptor_bytes",
                      "must be in [1, " + std::to_string(store_detail::kMaxDescriptorBytes) + "]");
  }
  core::ConfigMap k = root.child("intrinsics");
  k.require("width", &m.intrinsics.width);
  k.require("height", &m.intrinsics.height);
  k.require("fx", &m.intrinsics.fx);
  k.require("fy", &m.intrinsics.fy);
  k.require("cx", &m.intrinsics.cx);
  k.require("cy", &m.intrinsics.cy);
  std::vector<double> dist;
  k.require("distortion", &dist);
  if (k.has("distortion") && dist.size() != m.intrinsics.distortion.size()) {
    k.record_error("distortion", "expected 5 numbers (k1 k2 p1 p2 k3), got " + std::to_string(dist.size()));
  } else if (k.has("distortion")) {
    std::copy(dist.begin(), dist.end(), m.intrinsics.distortion.begin());
  }
  // Optional: stores written before it existed keep the identity default.
  if (root.has("T_imu_cam")) {
    m.T_imu_cam_recorded = true;
    read_pose(root, "T_imu_cam", &m.T_imu_cam);
    const std::string problem = core::rigid_transform_problem(m.T_imu_cam);
    if (!problem.empty()) root.record_error("T_imu_cam", problem);
  }
  HWR_RETURN_IF_ERROR(finish_as_parse_error(*doc));
  return m;
}

// ---- segment.yaml ----

struct SegmentYaml {
  SegmentRecord record;  // everything but keyframes, points and the fine data (fine_voxel_m included)
  uint32_t format_version = 0;
  uint32_t keyframes = 0;
  uint64_t points = 0;
  uint32_t weld_regions = 0;  // format 2 on; 0 before
  uint64_t fine_points = 0;
  uint64_t keyframes_bin_bytes = 0, cloud_bin_bytes = 0, fine_bin_bytes = 0;
  uint32_t keyframes_bin_crc32 = 0, cloud_bin_crc32 = 0, fine_bin_crc32 = 0;
};

std::string segment_yaml_text(const SegmentRecord& s, uint64_t keyframes_bin_bytes, uint32_t keyframes_crc32,
                              uint64_t cloud_bin_bytes, uint32_t cloud_crc32, uint64_t fine_bin_bytes,
                              uint32_t fine_crc32) {
  const JunctionRecord& j = s.junction;
  std::string t = "# hwr-perception map store segment: written once, never modified\n";
  appendf(&t, "format_version: %" PRIu32 "\n", kStoreFormatVersion);
  appendf(&t, "segment_id: %" PRIu32 "\n", s.segment_id);
  t += "T_world_segment: " + yaml_pose(s.T_world_segment) + "  # rows of [R | t]\n";
  t += "travelled_m: " + yaml_double(s.travelled_m) + "\n";
  appendf(&t, "t_first_ns: %" PRId64 "\nt_last_ns: %" PRId64 "\n", s.t_first_ns, s.t_last_ns);
  appendf(&t, "keyframes: %zu\npoints: %zu\n", s.keyframes.size(), s.points_segment.size());
  t += "fine_voxel_m: " + yaml_double(s.fine_voxel_m) + "\n";
  appendf(&t, "weld_regions: %zu\nfine_points: %zu\n", s.weld_regions.size(), s.fine_points_segment.size());
  t += "junction:\n";
  appendf(&t, "  valid: %s\n", j.valid ? "true" : "false");
  appendf(&t, "  keyframe_before: %" PRId32 "\n  keyframe_after: %" PRId32 "\n", j.keyframe_before,
          j.keyframe_after);
  appendf(&t, "  orb_matches: %d\n  orb_inliers: %d\n", j.orb_matches, j.orb_inliers);
  appendf(&t, "  ndt_converged: %s\n  ndt_iterations: %d\n", j.ndt_converged ? "true" : "false",
          j.ndt_iterations);
  t += "  ndt_fitness: " + yaml_double(j.ndt_fitness) + "\n";
  t += "  T_prev_segment_segment: " + yaml_pose(j.T_prev_segment_segment) + "\n";
  t += "  T_prev_segment_segment_odometry: " + yaml_pose(j.T_prev_segment_segment_odometry) + "\n";
  t += "  T_prev_segment_segment_measured: " + yaml_pose(j.T_prev_segment_segment_measured) + "\n";
  appendf(&t, "  fused: %s\n", j.fused ? "true" : "false");
  appendf(&t, "  ndt_used: %s\n  odometry_kept: %s\n", j.ndt_used ? "true" : "false",
          j.odometry_kept ? "true" : "false");
  appendf(&t, "keyframes_bin_bytes: %" PRIu64 "\nkeyframes_bin_crc32: %" PRIu32 "\n", keyframes_bin_bytes,
          keyframes_crc32);
  appendf(&t, "cloud_bin_bytes: %" PRIu64 "\ncloud_bin_crc32: %" PRIu32 "\n", cloud_bin_bytes, cloud_crc32);
  appendf(&t, "fine_bin_bytes: %" PRIu64 "\nfine_bin_crc32: %" PRIu32 "\n", fine_bin_bytes, fine_crc32);
  appendf(&t, "%s: %" PRIu32 "  # CRC32 of every byte above this line\n", kSelfCrcKey,
          store_detail::crc32_bytes(t.data(), t.size()));
  return t;
}

core::Expected<SegmentYaml> read_segment_yaml(const std::string& path) {
  std::string text;
  const core::Status rd = core::read_file(path, &text);
  if (!rd.ok()) {
    if (rd.code() == core::ErrorCode::kNotFound) {
      return core::CorruptData(path + ": missing; a complete segment directory always has one");
    }
    return rd;
  }
  // The self CRC covers everything up to its own line; checked before the YAML is parsed, so a
  // damaged file is kCorruptData whatever the damage did to its syntax.
  const std::string marker = std::string("\n") + kSelfCrcKey + ":";
  const size_t at = text.rfind(marker);
  if (at == std::string::npos) {
    return core::CorruptData(path + ": no '" + kSelfCrcKey + "' line (the file is truncated or not ours)");
  }
  const uint32_t computed = store_detail::crc32_bytes(text.data(), at + 1);
  char* end = nullptr;
  const unsigned long long stored = std::strtoull(text.c_str() + at + marker.size(), &end, 10);
  if (end == text.c_str() + at + marker.size() || stored != computed) {
    return core::CorruptData(path + ": content CRC32 mismatch (stored " + std::to_string(stored) +
                             ", computed " + std::to_string(computed) + "); the file was altered or damaged");
  }

  auto doc = core::ConfigDocument::parse(text, path);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  uint32_t self_crc = 0;
  read_u32(root, kSelfCrcKey, &self_crc);
  SegmentYaml y;
  SegmentRecord& s = y.record;
  uint32_t& version = y.format_version;
  read_u32(root, "format_version", &version);
  if (version > kStoreFormatVersion) {
    return core::InvalidArgument(path + ": format_version " + std::to_string(version) +
                                 " is newer than this build reads (" + std::to_string(kStoreFormatVersion) +
                                 ")");
  }
  if (root.has("format_version") && version < 1) root.record_error("format_version", "must be at least 1");
  read_u32(root, "segment_id", &s.segment_id);
  read_pose(root, "T_world_segment", &s.T_world_segment);
  root.require("travelled_m", &s.travelled_m);
  root.require("t_first_ns", &s.t_first_ns);
  root.require("t_last_ns", &s.t_last_ns);
  read_u32(root, "keyframes", &y.keyframes);
  root.require("points", &y.points);
  core::ConfigMap j = root.child("junction");
  JunctionRecord& jr = s.junction;
  j.require("valid", &jr.valid);
  j.require("keyframe_before", &jr.keyframe_before);
  j.require("keyframe_after", &jr.keyframe_after);
  j.require("orb_matches", &jr.orb_matches);
  j.require("orb_inliers", &jr.orb_inliers);
  j.require("ndt_converged", &jr.ndt_converged);
  j.require("ndt_iterations", &jr.ndt_iterations);
  j.require("ndt_fitness", &jr.ndt_fitness);
  read_pose(j, "T_prev_segment_segment", &jr.T_prev_segment_segment);
  read_pose(j, "T_prev_segment_segment_odometry", &jr.T_prev_segment_segment_odometry);
  read_pose(j, "T_prev_segment_segment_measured", &jr.T_prev_segment_segment_measured);
  j.require("fused", &jr.fused);
  j.get("ndt_used", &jr.ndt_used)
      .get("odometry_kept", &jr.odometry_kept);  // optional: early format-2 files lack them
  root.require("keyframes_bin_bytes", &y.keyframes_bin_bytes);
  read_u32(root, "keyframes_bin_crc32", &y.keyframes_bin_crc32);
  root.require("cloud_bin_bytes", &y.cloud_bin_bytes);
  read_u32(root, "cloud_bin_crc32", &y.cloud_bin_crc32);
  // Format 2: the welding regions. Absent from a version-1 file (there they are unknown keys, which
  // finish() reports).
  if (version >= kFirstFineFormatVersion) {
    root.require("fine_voxel_m", &s.fine_voxel_m);
    if (root.has("fine_voxel_m") && !(std::isfinite(s.fine_voxel_m) && s.fine_voxel_m >= 0)) {
      root.record_error("fine_voxel_m", "must be finite and >= 0");
    }
    read_u32(root, "weld_regions", &y.weld_regions);
    root.require("fine_points", &y.fine_points);
    root.require("fine_bin_bytes", &y.fine_bin_bytes);
    read_u32(root, "fine_bin_crc32", &y.fine_bin_crc32);
  }
  HWR_RETURN_IF_ERROR(finish_as_parse_error(*doc));
  return y;
}

// The segment's files on disk must have the sizes segment.yaml recorded.
core::Status check_file_size(const std::string& path, uint64_t expected_bytes) {
  uint64_t actual = 0;
  if (!store_detail::file_size_bytes(path, &actual)) {
    return core::CorruptData(path + ": missing; a complete segment directory always has it");
  }
  if (actual != expected_bytes) {
    return core::CorruptData(path + ": " + std::to_string(actual) + " bytes, segment.yaml says " +
                             std::to_string(expected_bytes) +
                             (actual < expected_bytes ? " (truncated)" : ""));
  }
  return core::Status::Ok();
}

}  // namespace

core::Expected<MapStore> MapStore::open(const std::string& dir, const StoreMetadata& metadata) {
  if (dir.empty()) return core::InvalidArgument("map store: empty directory path");
  std::error_code ec;
  const bool existed = fs::exists(dir, ec);
  fs::create_directories(dir, ec);
  if (ec || !is_directory(dir)) {
    return core::IoError(dir + ": cannot create the map store directory: " +
                         (ec ? ec.message() : std::string("exists and is not a directory")));
  }
  const std::string segments = join(dir, kSegmentsDir);
  if (!is_directory(segments) && ::mkdir(segments.c_str(), 0755) != 0) {
    return core::IoError(segments + ": cannot create: " + std::strerror(errno));
  }
  HWR_RETURN_IF_ERROR(remove_temporaries(segments));
  HWR_RETURN_IF_ERROR(remove_temporaries(dir));

  const std::string store_yaml = join(dir, kStoreYaml);
  if (path_exists(store_yaml)) {
    auto existing = read_store_yaml(store_yaml);
    if (!existing.ok()) return existing.status();
    return MapStore(dir, std::move(existing).value());
  }
  // A new store. segments/ exists before store.yaml, and store.yaml before any segment, so
  // segments without store.yaml mean the file was lost, not a crash during creation.
  std::vector<uint32_t> ids;
  HWR_RETURN_IF_ERROR(segment_ids(segments, &ids));
  if (!ids.empty()) {
    return core::CorruptData(store_yaml + ": missing, but the store holds " + std::to_string(ids.size()) +
                             " segments; restore store.yaml rather than starting a new store over them");
  }
  HWR_RETURN_IF_ERROR(validate_metadata(metadata));
  StoreMetadata created = metadata;
  created.format_version = kStoreFormatVersion;  // see kStoreFormatVersion
  const std::string text = store_yaml_text(created);
  const std::string tmp = join(dir, kTmpPrefix) + "store.yaml-" + std::to_string(::getpid());
  const ByteSpan span{text.data(), text.size()};
  core::Status st = store_detail::write_file_synced(tmp, &span, 1);
  if (st.ok() && std::rename(tmp.c_str(), store_yaml.c_str()) != 0) {
    st = core::IoError(store_yaml + ": rename failed: " + std::strerror(errno));
  }
  if (!st.ok()) {
    std::remove(tmp.c_str());
    return st;
  }
  HWR_RETURN_IF_ERROR(core::fsync_directory(dir));
  if (!existed) {
    // Make the new directory's own entry durable too (best effort: the parent may be unreadable).
    const fs::path parent = fs::absolute(fs::path(dir), ec).parent_path();
    if (!ec) (void)core::fsync_directory(parent.string());
  }
  return MapStore(dir, std::move(created));
}

core::Expected<MapStore> MapStore::open_existing(const std::string& dir) {
  const std::string store_yaml = join(dir, kStoreYaml);
  if (!is_directory(dir)) return core::NotFound(dir + ": no map store here (directory not found)");
  if (!path_exists(store_yaml))
    return core::NotFound(store_yaml + ": not found; " + dir + " is not a map store");
  if (!is_directory(join(dir, kSegmentsDir))) {
    return core::CorruptData(join(dir, kSegmentsDir) + ": missing; a map store always has it");
  }
  auto m = read_store_yaml(store_yaml);
  if (!m.ok()) return m.status();
  return MapStore(dir, std::move(m).value());
}

core::Status MapStore::write_segment(const SegmentRecord& segment) {
  const std::string segments = join(dir_, kSegmentsDir);
  const std::string name = segment_dir_name(segment.segment_id);
  const std::string final_dir = segments + "/" + name;
  if (path_exists(final_dir)) {
    return core::InvalidArgument("map store: segment " + std::to_string(segment.segment_id) +
                                 " already exists (" + final_dir + "); segments are written once");
  }
  BinHeader kf_header{};
  std::vector<uint8_t> kf_payload;
  uint32_t kf_crc = 0;
  HWR_RETURN_IF_ERROR(store_detail::encode_keyframes(segment.keyframes, metadata_.descriptor_bytes,
                                                     &kf_header, &kf_payload, &kf_crc));
  BinHeader fine_header{};
  std::vector<uint8_t> fine_payload;
  uint32_t fine_crc = 0;
  HWR_RETURN_IF_ERROR(store_detail::encode_fine(segment, &fine_header, &fine_payload, &fine_crc));
  uint32_t cloud_crc = 0;
  const BinHeader cloud_header = store_detail::encode_cloud_header(segment.points_segment, &cloud_crc);
  const uint64_t kf_bytes = kf_header.size() + kf_payload.size();
  const uint64_t cloud_bytes = cloud_header.size() + segment.points_segment.size() * sizeof(CloudPoint);
  const uint64_t fine_bytes = fine_header.size() + fine_payload.size();
  const std::string yaml =
      segment_yaml_text(segment, kf_bytes, kf_crc, cloud_bytes, cloud_crc, fine_bytes, fine_crc);

  const std::string tmp = segments + "/" + kTmpPrefix + name + "-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);  // our own earlier failure
  if (::mkdir(tmp.c_str(), 0755) != 0) return core::IoError(tmp + ": cannot create: " + std::strerror(errno));

  auto write_all = [&]() -> core::Status {
    const ByteSpan kf_spans[] = {{kf_header.data(), kf_header.size()},
                                 {kf_payload.data(), kf_payload.size()}};
    HWR_RETURN_IF_ERROR(store_detail::write_file_synced(join(tmp, kKeyframesBin), kf_spans, 2));
    const ByteSpan cloud_spans[] = {
        {cloud_header.data(), cloud_header.size()},
        {segment.points_segment.data(), segment.points_segment.size() * sizeof(CloudPoint)}};
    HWR_RETURN_IF_ERROR(store_detail::write_file_synced(join(tmp, kCloudBin), cloud_spans, 2));
    const ByteSpan fine_spans[] = {{fine_header.data(), fine_header.size()},
                                   {fine_payload.data(), fine_payload.size()}};
    HWR_RETURN_IF_ERROR(store_detail::write_file_synced(join(tmp, kFineBin), fine_spans, 2));
    const ByteSpan yaml_span{yaml.data(), yaml.size()};
    HWR_RETURN_IF_ERROR(store_detail::write_file_synced(join(tmp, kSegmentYaml), &yaml_span, 1));
    HWR_RETURN_IF_ERROR(core::fsync_directory(tmp));
    // The commit point: before it the segment is absent, after it complete.
    if (std::rename(tmp.c_str(), final_dir.c_str()) != 0) {
      const int err = errno;
      if (err == EEXIST || err == ENOTEMPTY) {
        return core::InvalidArgument("map store: segment " + std::to_string(segment.segment_id) +
                                     " already exists (" + final_dir + "); segments are written once");
      }
      return core::IoError(final_dir + ": rename from " + tmp + " failed: " + std::strerror(err));
    }
    return core::Status::Ok();
  };
  const core::Status st = write_all();
  if (!st.ok()) {
    fs::remove_all(tmp, ec);
    return st;
  }
  return core::fsync_directory(segments);
}

core::Expected<std::vector<SegmentSummary>> MapStore::list_segments() const {
  const std::string segments = join(dir_, kSegmentsDir);
  std::vector<uint32_t> ids;
  HWR_RETURN_IF_ERROR(segment_ids(segments, &ids));
  std::vector<SegmentSummary> out;
  out.reserve(ids.size());
  for (uint32_t id : ids) {
    const std::string seg_dir = segments + "/" + segment_dir_name(id);
    auto y = read_segment_yaml(join(seg_dir, kSegmentYaml));
    if (!y.ok()) return y.status();
    if (y->record.segment_id != id) {
      return core::CorruptData(join(seg_dir, kSegmentYaml) + ": segment_id " +
                               std::to_string(y->record.segment_id) + " does not match its directory");
    }
    SegmentSummary s;
    s.segment_id = id;
    s.keyframes = static_cast<int>(std::min<uint32_t>(y->keyframes, std::numeric_limits<int>::max()));
    s.points = static_cast<int64_t>(std::min<uint64_t>(y->points, std::numeric_limits<int64_t>::max()));
    for (const char* f : {kSegmentYaml, kKeyframesBin, kCloudBin, kFineBin}) {  // no fine.bin before format 2
      uint64_t bytes = 0;
      if (store_detail::file_size_bytes(join(seg_dir, f), &bytes)) s.bytes += bytes;
    }
    out.push_back(s);
  }
  return out;
}

core::Expected<SegmentRecord> MapStore::read_segment(uint32_t segment_id) const {
  return read_segment_files(segment_id, Parts{});
}

core::Expected<SegmentRecord> MapStore::read_keyframes(uint32_t segment_id) const {
  return read_segment_files(segment_id, Parts{true, false, false});
}

core::Expected<SegmentRecord> MapStore::read_cloud(uint32_t segment_id) const {
  return read_segment_files(segment_id, Parts{false, true, false});
}

core::Expected<SegmentRecord> MapStore::read_segment_files(uint32_t segment_id, Parts parts) const {
  const std::string seg_dir = join(dir_, kSegmentsDir) + "/" + segment_dir_name(segment_id);
  if (!is_directory(seg_dir)) {
    return core::NotFound("map store " + dir_ + ": no segment " + std::to_string(segment_id) + " (" +
                          seg_dir + " not found; list_segments() gives the ids present)");
  }
  const std::string yaml_path = join(seg_dir, kSegmentYaml);
  auto y = read_segment_yaml(yaml_path);
  if (!y.ok()) return y.status();
  if (y->record.segment_id != segment_id) {
    return core::CorruptData(yaml_path + ": segment_id " + std::to_string(y->record.segment_id) +
                             " does not match its directory");
  }
  SegmentRecord out = std::move(y->record);
  if (parts.keyframes) {
    const std::string kf_path = join(seg_dir, kKeyframesBin);
    HWR_RETURN_IF_ERROR(check_file_size(kf_path, y->keyframes_bin_bytes));
    HWR_RETURN_IF_ERROR(store_detail::read_keyframes_file(
        kf_path, metadata_.descriptor_bytes, BinExpectation{y->keyframes, y->keyframes_bin_crc32},
        &out.keyframes));
  }
  if (parts.cloud) {
    const std::string cloud_path = join(seg_dir, kCloudBin);
    HWR_RETURN_IF_ERROR(check_file_size(cloud_path, y->cloud_bin_bytes));
    HWR_RETURN_IF_ERROR(store_detail::read_cloud_file(
        cloud_path, BinExpectation{y->points, y->cloud_bin_crc32}, &out.points_segment));
  }
  // fine_voxel_m comes from segment.yaml whichever files are read.
  if (!parts.fine || y->format_version < kFirstFineFormatVersion) return out;  // no fine data: empty
  const std::string fine_path = join(seg_dir, kFineBin);
  HWR_RETURN_IF_ERROR(check_file_size(fine_path, y->fine_bin_bytes));
  HWR_RETURN_IF_ERROR(store_detail::read_fine_file(
      fine_path, FineExpectation{y->weld_regions, y->fine_points, y->fine_bin_crc32, out.fine_voxel_m},
      &out.weld_regions, &out.fine_points_segment, &out.fine_counts));
  return out;
}

}  // namespace hwr::recon
