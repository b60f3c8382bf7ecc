#include "map_store_binary.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <type_traits>

#include "hwr/core/se3.hpp"
#include "map_store_files.hpp"

namespace hwr::recon::store_detail {
namespace {

static_assert(
    __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
    "the map store's files are little-endian and written with memcpy; add byte swaps for this host");
static_assert(sizeof(CloudPoint) == kCloudPointBytes && std::is_trivially_copyable<CloudPoint>::value,
              "cloud.bin stores CloudPoint's bytes as they are");
static_assert(offsetof(CloudPoint, r) == 12 && offsetof(CloudPoint, flags) == 15, "CloudPoint layout");
static_assert(kFinePointBytes == kCloudPointBytes + sizeof(uint32_t), "fine.bin: a CloudPoint and its count");
static_assert(kWeldRegionLabelBytes == 32, "fine.bin's region record holds a 32-byte label");
static_assert(sizeof(WeldRegionSource) == 1, "fine.bin stores the source as one byte");

constexpr char kKeyframesMagic[8] = {'H', 'W', 'R', 'K', 'F', '0', '0', '1'};
constexpr char kCloudMagic[8] = {'H', 'W', 'R', 'P', 'C', '0', '0', '1'};
constexpr char kFineMagic[8] = {'H', 'W', 'R', 'F', 'N', '0', '0', '1'};
constexpr size_t kHeaderCrcOffset = 44;

template <class T>
void put(uint8_t* dst, size_t offset, T v) {
  static_assert(std::is_trivially_copyable<T>::value, "plain value");
  std::memcpy(dst + offset, &v, sizeof(T));
}

template <class T>
T get(const uint8_t* src, size_t offset) {
  T v;
  std::memcpy(&v, src + offset, sizeof(T));
  return v;
}

void put_pose(uint8_t* dst, size_t offset, const Eigen::Isometry3d& T) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      put<double>(dst, offset + 8 * static_cast<size_t>(4 * r + c), T.matrix()(r, c));
  }
}

Eigen::Isometry3d get_pose(const uint8_t* src, size_t offset) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      T.matrix()(r, c) = get<double>(src, offset + 8 * static_cast<size_t>(4 * r + c));
  }
  return T;
}

std::string hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%08x", v);
  return buf;
}

BinHeader make_header(const char (&magic)[8], uint32_t field16, uint32_t field20, uint64_t count24,
                      uint64_t payload_bytes, uint32_t payload_crc32) {
  BinHeader h{};
  std::memcpy(h.data(), magic, 8);
  put<uint32_t>(h.data(), 8, kBinVersion);
  put<uint32_t>(h.data(), 12, static_cast<uint32_t>(kBinHeaderBytes));
  put<uint32_t>(h.data(), 16, field16);
  put<uint32_t>(h.data(), 20, field20);
  put<uint64_t>(h.data(), 24, count24);
  put<uint64_t>(h.data(), 32, payload_bytes);
  put<uint32_t>(h.data(), 40, payload_crc32);
  put<uint32_t>(h.data(), kHeaderCrcOffset, crc32_bytes(h.data(), kHeaderCrcOffset));
  return h;
}

// The checks every header shares: length, magic, header CRC, version, header size, and the
// payload size against the file length. Nothing here allocates beyond the error message.
core::Status check_header(const std::string& path, const ReadFile& file, const char (&magic)[8], BinHeader* h,
                          uint64_t* payload_bytes) {
  if (file.size_bytes() < kBinHeaderBytes) {
    return core::CorruptData(path + ": truncated: " + std::to_string(file.size_bytes()) +
                             " bytes, shorter than the " + std::to_string(kBinHeaderBytes) + "-byte header");
  }
  HWR_RETURN_IF_ERROR(file.read_at(0, h->data(), kBinHeaderBytes));
  if (std::memcmp(h->data(), magic, 8) != 0) {
    return core::CorruptData(path + ": bad magic (expected '" + std::string(magic, 8) +
                             "'); not a map store file");
  }
  const uint32_t stored_header_crc = get<uint32_t>(h->data(), kHeaderCrcOffset);
  const uint32_t header_crc = crc32_bytes(h->data(), kHeaderCrcOffset);
  if (stored_header_crc != header_crc) {
    return core::CorruptData(path + ": header CRC32 mismatch (stored " + hex32(stored_header_crc) +
                             ", computed " + hex32(header_crc) + ")");
  }
  const uint32_t version = get<uint32_t>(h->data(), 8);
  if (version != kBinVersion) {
    return core::CorruptData(path + ": unsupported file version " + std::to_string(version) +
                             " (this build reads " + std::to_string(kBinVersion) + ")");
  }
  if (get<uint32_t>(h->data(), 12) != kBinHeaderBytes) {
    return core::CorruptData(path + ": header size field is " + std::to_string(get<uint32_t>(h->data(), 12)) +
                             ", expected " + std::to_string(kBinHeaderBytes));
  }
  *payload_bytes = get<uint64_t>(h->data(), 32);
  const uint64_t actual = file.size_bytes() - kBinHeaderBytes;
  if (*payload_bytes != actual) {
    return core::CorruptData(path + ": header says " + std::to_string(*payload_bytes) +
                             " payload bytes, the file has " + std::to_string(actual) +
                             (actual < *payload_bytes ? " (truncated)" : ""));
  }
  return core::Status::Ok();
}

core::Status compare_payload_crc(const std::string& path, uint32_t computed, uint32_t stored) {
  if (computed != stored) {
    return core::CorruptData(path + ": payload CRC32 mismatch (stored " + hex32(stored) + ", computed " +
                             hex32(computed) + "); the file is corrupt");
  }
  return core::Status::Ok();
}

core::Status check_payload_crc(const std::string& path, const uint8_t* payload, size_t n, uint32_t stored) {
  return compare_payload_crc(path, crc32_bytes(payload, n), stored);
}

core::Status check_expectation(const std::string& path, const char* what, uint64_t count,
                               uint32_t payload_crc32, const BinExpectation& expect) {
  if (count != expect.count) {
    return core::CorruptData(path + ": header holds " + std::to_string(count) + " " + what +
                             ", segment.yaml says " + std::to_string(expect.count));
  }
  if (payload_crc32 != expect.payload_crc32) {
    return core::CorruptData(path + ": payload CRC32 " + hex32(payload_crc32) +
                             " disagrees with segment.yaml's " + hex32(expect.payload_crc32));
  }
  return core::Status::Ok();
}

// ---- fine.bin's records: the checks the writer and the reader share ----

bool known_source(WeldRegionSource source) {
  switch (source) {  // no default: -Wswitch flags a new source that fine.bin would not accept
    case WeldRegionSource::kModel:
    case WeldRegionSource::kGeometry:
    case WeldRegionSource::kOperator:
    case WeldRegionSource::kSimTruth:
      return true;
  }
  return false;
}

std::string g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// Empty when fine.bin can hold the region; else what is wrong with it, as a phrase.
std::string weld_region_problem(const StoredWeldRegion& s) {
  const WeldRegion& r = s.region;
  if (!known_source(r.source)) {
    return "source " + std::to_string(static_cast<unsigned>(r.source)) +
           " is not a WeldRegionSource (0 model, 1 geometry, 2 operator, 3 sim-truth)";
  }
  if (std::find(r.label.begin(), r.label.end(), '\0') == r.label.end()) {
    return "label is not NUL-terminated within its " + std::to_string(kWeldRegionLabelBytes) + " bytes";
  }
  std::string problem = core::rigid_transform_problem(r.T_cam_region);
  if (!problem.empty()) return "T_cam_region " + problem;
  problem = core::rigid_transform_problem(s.T_segment_region);
  if (!problem.empty()) return "T_segment_region " + problem;
  for (int i = 0; i < 3; ++i) {
    if (!(std::isfinite(r.half_size_m[i]) && r.half_size_m[i] > 0)) {
      return "half_size_m (" + g17(r.half_size_m[0]) + ", " + g17(r.half_size_m[1]) + ", " +
             g17(r.half_size_m[2]) + ") must be positive and finite";
    }
  }
  if (s.fine_points < 0) return "fine_points is negative (" + std::to_string(s.fine_points) + ")";
  if (!s.viewpoint_segment.allFinite()) return "viewpoint_segment is not finite";
  return "";
}

// nullptr when fine.bin can hold the fine point; else what is wrong with it (no allocation: the
// reader asks for every point).
const char* fine_point_problem(const CloudPoint& p, uint32_t count) {
  if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) {
    return "has a non-finite coordinate";
  }
  if (count == 0) return "has count 0 (a fine voxel merges at least one point)";
  return nullptr;
}

std::string region_name(size_t index, uint32_t id) {
  return "weld region " + std::to_string(index) + " (id " + std::to_string(id) + ")";
}

void put_region(uint8_t* p, const StoredWeldRegion& s) {
  const WeldRegion& r = s.region;
  put<uint32_t>(p, 0, r.id);
  p[4] = static_cast<uint8_t>(r.source);
  p[5] = p[6] = p[7] = 0;
  put<float>(p, 8, r.confidence);
  std::memcpy(p + 12, r.label.data(), kWeldRegionLabelBytes);
  put<int32_t>(p, 44, r.keyframe_id);
  put<int64_t>(p, 48, r.t_ns);
  put_pose(p, 56, r.T_cam_region);
  for (int i = 0; i < 3; ++i) put<double>(p, 152 + 8 * static_cast<size_t>(i), r.half_size_m[i]);
  put_pose(p, 176, s.T_segment_region);
  put<int64_t>(p, 272, s.fine_points);
  for (int i = 0; i < 3; ++i) put<double>(p, 280 + 8 * static_cast<size_t>(i), s.viewpoint_segment[i]);
}

// Fine points read (and CRC'ed) per chunk: the payload is never held twice in memory.
constexpr uint64_t kFineChunkPoints = 4096;

}  // namespace

uint32_t crc32_bytes(const void* data, size_t n, uint32_t crc) {
  const Bytef* p = static_cast<const Bytef*>(data);
  uLong c = crc;
  while (n > 0) {
    const uInt chunk = n > (1u << 30) ? (1u << 30) : static_cast<uInt>(n);
    c = ::crc32(c, p, chunk);
    p += chunk;
    n -= chunk;
  }
  return static_cast<uint32_t>(c);
}

core::Status encode_keyframes(const std::vector<StoredKeyframe>& keyframes, int descriptor_bytes,
                              BinHeader* header, std::vector<uint8_t>* payload, uint32_t* payload_crc32) {
  if (descriptor_bytes < 1 || static_cast<uint32_t>(descriptor_bytes) > kMaxDescriptorBytes) {
    return core::InvalidArgument("map store: descriptor_bytes must be in [1, " +
                                 std::to_string(kMaxDescriptorBytes) + "], got " +
                                 std::to_string(descriptor_bytes));
  }
  if (keyframes.size() > std::numeric_limits<uint32_t>::max()) {
    return core::InvalidArgument("map store: too many keyframes in one segment");
  }
  const size_t db = static_cast<size_t>(descriptor_bytes);
  uint64_t n_features = 0;
  for (const StoredKeyframe& kf : keyframes) {
    if (kf.features.size() > std::numeric_limits<uint32_t>::max()) {
      return core::InvalidArgument("map store: keyframe " + std::to_string(kf.id) + " has too many features");
    }
    if (kf.descriptors.size() != kf.features.size() * db) {
      return core::InvalidArgument(
          "map store: keyframe " + std::to_string(kf.id) + " has " + std::to_string(kf.descriptors.size()) +
          " descriptor bytes for " + std::to_string(kf.features.size()) + " features; expected features x " +
          std::to_string(descriptor_bytes) + " = " + std::to_string(kf.features.size() * db));
    }
    n_features += kf.features.size();
  }
  const uint64_t payload_bytes = keyframes.size() * kKeyframeRecordBytes + n_features * (kFeatureBytes + db);
  payload->assign(payload_bytes, 0);
  uint8_t* p = payload->data();
  for (const StoredKeyframe& kf : keyframes) {
    put<int32_t>(p, 0, kf.id);
    put<uint32_t>(p, 4, static_cast<uint32_t>(kf.features.size()));
    put<int64_t>(p, 8, kf.t_ns);
    put_pose(p, 16, kf.T_world_cam);
    p[112] = kf.gnss_valid ? 1 : 0;
    p[113] = kf.mag_valid ? 1 : 0;
    put<double>(p, 120, kf.lat_deg);
    put<double>(p, 128, kf.lon_deg);
    put<double>(p, 136, kf.alt_m);
    for (int i = 0; i < 3; ++i) put<double>(p, 144 + 8 * static_cast<size_t>(i), kf.mag_imu_uT[i]);
    p += kKeyframeRecordBytes;
    for (const StoredFeature& f : kf.features) {
      put<float>(p, 0, f.u_px);
      put<float>(p, 4, f.v_px);
      put<float>(p, 8, f.depth_m);
      p[12] = f.octave;
      p += kFeatureBytes;
    }
    if (!kf.descriptors.empty()) std::memcpy(p, kf.descriptors.data(), kf.descriptors.size());
    p += kf.descriptors.size();
  }
  *payload_crc32 = crc32_bytes(payload->data(), payload->size());
  *header = make_header(kKeyframesMagic, static_cast<uint32_t>(keyframes.size()), static_cast<uint32_t>(db),
                        n_features, payload_bytes, *payload_crc32);
  return core::Status::Ok();
}

BinHeader encode_cloud_header(const std::vector<CloudPoint>& points, uint32_t* payload_crc32) {
  const uint64_t payload_bytes = points.size() * kCloudPointBytes;
  *payload_crc32 = crc32_bytes(points.data(), payload_bytes);
  return make_header(kCloudMagic, static_cast<uint32_t>(kCloudPointBytes), 0, points.size(), payload_bytes,
                     *payload_crc32);
}

core::Status encode_fine(const SegmentRecord& segment, BinHeader* header, std::vector<uint8_t>* payload,
                         uint32_t* payload_crc32) {
  const std::string where = "map store: segment " + std::to_string(segment.segment_id) + ": ";
  const std::vector<StoredWeldRegion>& regions = segment.weld_regions;
  const std::vector<CloudPoint>& points = segment.fine_points_segment;
  const std::vector<uint32_t>& counts = segment.fine_counts;
  if (counts.size() != points.size()) {
    return core::InvalidArgument(where + "fine_counts has " + std::to_string(counts.size()) +
                                 " entries for " + std::to_string(points.size()) +
                                 " fine points (the two vectors are parallel)");
  }
  if (!std::isfinite(segment.fine_voxel_m) || segment.fine_voxel_m < 0) {
    return core::InvalidArgument(where + "fine_voxel_m must be finite and >= 0, got " +
                                 g17(segment.fine_voxel_m));
  }
  if (!points.empty() && !(segment.fine_voxel_m > 0)) {
    return core::InvalidArgument(where + std::to_string(points.size()) +
                                 " fine points need fine_voxel_m > 0, got " + g17(segment.fine_voxel_m));
  }
  if (regions.size() > std::numeric_limits<uint32_t>::max()) {
    return core::InvalidArgument(where + "too many weld regions in one segment");
  }
  for (size_t i = 0; i < regions.size(); ++i) {
    const std::string problem = weld_region_problem(regions[i]);
    if (!problem.empty()) {
      return core::InvalidArgument(where + region_name(i, regions[i].region.id) + ": " + problem);
    }
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (const char* problem = fine_point_problem(points[i], counts[i])) {
      return core::InvalidArgument(where + "fine point " + std::to_string(i) + " " + problem);
    }
  }
  const uint64_t region_bytes = regions.size() * kWeldRegionRecordBytes;
  const uint64_t payload_bytes = region_bytes + points.size() * kFinePointBytes;
  payload->assign(payload_bytes, 0);
  uint8_t* p = payload->data();
  for (const StoredWeldRegion& r : regions) {
    put_region(p, r);
    p += kWeldRegionRecordBytes;
  }
  for (size_t i = 0; i < points.size(); ++i) {
    std::memcpy(p, &points[i], kCloudPointBytes);
    put<uint32_t>(p, kCloudPointBytes, counts[i]);
    p += kFinePointBytes;
  }
  *payload_crc32 = crc32_bytes(payload->data(), payload->size());
  *header = make_header(kFineMagic, static_cast<uint32_t>(kFinePointBytes),
                        static_cast<uint32_t>(regions.size()), points.size(), payload_bytes, *payload_crc32);
  return core::Status::Ok();
}

core::Status read_keyframes_file(const std::string& path, int descriptor_bytes, const BinExpectation& expect,
                                 std::vector<StoredKeyframe>* out) {
  ReadFile file;
  HWR_RETURN_IF_ERROR(ReadFile::open(path, &file));
  BinHeader h{};
  uint64_t payload_bytes = 0;
  HWR_RETURN_IF_ERROR(check_header(path, file, kKeyframesMagic, &h, &payload_bytes));
  const uint64_t n_keyframes = get<uint32_t>(h.data(), 16);
  const uint32_t db = get<uint32_t>(h.data(), 20);
  const uint64_t n_features = get<uint64_t>(h.data(), 24);
  const uint32_t stored_crc = get<uint32_t>(h.data(), 40);
  if (db != static_cast<uint32_t>(descriptor_bytes)) {
    return core::CorruptData(path + ": " + std::to_string(db) +
                             " descriptor bytes per feature, the store uses " +
                             std::to_string(descriptor_bytes));
  }
  // Counts against the payload size, overflow-free (n_keyframes < 2^32; n_features is bounded
  // by the payload, which is bounded by the real file length).
  const uint64_t record_bytes = n_keyframes * kKeyframeRecordBytes;
  const uint64_t per_feature = kFeatureBytes + db;
  if (record_bytes > payload_bytes || n_features > (payload_bytes - record_bytes) / per_feature ||
      record_bytes + n_features * per_feature != payload_bytes) {
    return core::CorruptData(path + ": header counts (" + std::to_string(n_keyframes) + " keyframes, " +
                             std::to_string(n_features) + " features) do not match its " +
                             std::to_string(payload_bytes) + " payload bytes");
  }
  HWR_RETURN_IF_ERROR(check_expectation(path, "keyframes", n_keyframes, stored_crc, expect));

  std::vector<uint8_t> payload(payload_bytes);
  HWR_RETURN_IF_ERROR(file.read_at(kBinHeaderBytes, payload.data(), payload.size()));
  HWR_RETURN_IF_ERROR(check_payload_crc(path, payload.data(), payload.size(), stored_crc));

  std::vector<StoredKeyframe> keyframes(n_keyframes);
  const uint8_t* p = payload.data();
  const uint8_t* const end = payload.data() + payload.size();
  uint64_t features_seen = 0;
  for (uint64_t k = 0; k < n_keyframes; ++k) {
    StoredKeyframe& kf = keyframes[k];
    if (static_cast<size_t>(end - p) < kKeyframeRecordBytes) {
      return core::CorruptData(path + ": keyframe " + std::to_string(k) + " runs past the payload");
    }
    kf.id = get<int32_t>(p, 0);
    const uint64_t n = get<uint32_t>(p, 4);
    kf.t_ns = get<int64_t>(p, 8);
    kf.T_world_cam = get_pose(p, 16);
    if (p[112] > 1 || p[113] > 1) {
      return core::CorruptData(path + ": keyframe " + std::to_string(k) + ": validity flags must be 0 or 1");
    }
    kf.gnss_valid = p[112] == 1;
    kf.mag_valid = p[113] == 1;
    kf.lat_deg = get<double>(p, 120);
    kf.lon_deg = get<double>(p, 128);
    kf.alt_m = get<double>(p, 136);
    for (int i = 0; i < 3; ++i) kf.mag_imu_uT[i] = get<double>(p, 144 + 8 * static_cast<size_t>(i));
    p += kKeyframeRecordBytes;
    features_seen += n;
    if (features_seen > n_features || n * per_feature > static_cast<uint64_t>(end - p)) {
      return core::CorruptData(path + ": keyframe " + std::to_string(k) + " claims " + std::to_string(n) +
                               " features, more than the payload holds");
    }
    kf.features.resize(n);
    for (StoredFeature& f : kf.features) {
      f.u_px = get<float>(p, 0);
      f.v_px = get<float>(p, 4);
      f.depth_m = get<float>(p, 8);
      f.octave = p[12];
      p += kFeatureBytes;
    }
    kf.descriptors.assign(p, p + n * db);
    p += n * db;
  }
  if (p != end || features_seen != n_features) {
    return core::CorruptData(path + ": keyframe records cover " + std::to_string(p - payload.data()) +
                             " of " + std::to_string(payload.size()) + " payload bytes");
  }
  *out = std::move(keyframes);
  return core::Status::Ok();
}

core::Status read_cloud_file(const std::string& path, const BinExpectation& expect,
                             std::vector<CloudPoint>* out) {
  ReadFile file;
  HWR_RETURN_IF_ERROR(ReadFile::open(path, &file));
  BinHeader h{};
  uint64_t payload_bytes = 0;
  HWR_RETURN_IF_ERROR(check_header(path, file, kCloudMagic, &h, &payload_bytes));
  const uint32_t point_bytes = get<uint32_t>(h.data(), 16);
  const uint64_t n_points = get<uint64_t>(h.data(), 24);
  const uint32_t stored_crc = get<uint32_t>(h.data(), 40);
  if (point_bytes != kCloudPointBytes || get<uint32_t>(h.data(), 20) != 0) {
    return core::CorruptData(path + ": " + std::to_string(point_bytes) + " bytes per point, expected " +
                             std::to_string(kCloudPointBytes));
  }
  if (n_points > payload_bytes / kCloudPointBytes || n_points * kCloudPointBytes != payload_bytes) {
    return core::CorruptData(path + ": header claims " + std::to_string(n_points) +
                             " points, the payload holds " +
                             std::to_string(payload_bytes / kCloudPointBytes));
  }
  HWR_RETURN_IF_ERROR(check_expectation(path, "points", n_points, stored_crc, expect));
  // Straight into the caller's array: one allocation, bounded by the real file length.
  std::vector<CloudPoint> points(n_points);
  HWR_RETURN_IF_ERROR(file.read_at(kBinHeaderBytes, points.data(), payload_bytes));
  HWR_RETURN_IF_ERROR(
      check_payload_crc(path, reinterpret_cast<const uint8_t*>(points.data()), payload_bytes, stored_crc));
  *out = std::move(points);
  return core::Status::Ok();
}

core::Status read_fine_file(const std::string& path, const FineExpectation& expect,
                            std::vector<StoredWeldRegion>* regions_out, std::vector<CloudPoint>* points_out,
                            std::vector<uint32_t>* counts_out) {
  ReadFile file;
  HWR_RETURN_IF_ERROR(ReadFile::open(path, &file));
  BinHeader h{};
  uint64_t payload_bytes = 0;
  HWR_RETURN_IF_ERROR(check_header(path, file, kFineMagic, &h, &payload_bytes));
  const uint32_t point_bytes = get<uint32_t>(h.data(), 16);
  const uint64_t n_regions = get<uint32_t>(h.data(), 20);
  const uint64_t n_points = get<uint64_t>(h.data(), 24);
  const uint32_t stored_crc = get<uint32_t>(h.data(), 40);
  if (point_bytes != kFinePointBytes) {
    return core::CorruptData(path + ": " + std::to_string(point_bytes) + " bytes per fine point, expected " +
                             std::to_string(kFinePointBytes));
  }
  // Counts against the payload size, overflow-free (n_regions < 2^32, so region_bytes < 2^41).
  const uint64_t region_bytes = n_regions * kWeldRegionRecordBytes;
  if (region_bytes > payload_bytes || n_points > (payload_bytes - region_bytes) / kFinePointBytes ||
      region_bytes + n_points * kFinePointBytes != payload_bytes) {
    return core::CorruptData(path + ": header counts (" + std::to_string(n_regions) + " weld regions, " +
                             std::to_string(n_points) + " fine points) do not match its " +
                             std::to_string(payload_bytes) + " payload bytes");
  }
  if (n_regions != expect.regions) {
    return core::CorruptData(path + ": header holds " + std::to_string(n_regions) +
                             " weld regions, segment.yaml says " + std::to_string(expect.regions));
  }
  HWR_RETURN_IF_ERROR(check_expectation(path, "fine points", n_points, stored_crc,
                                        BinExpectation{expect.points, expect.payload_crc32}));
  if (n_points > 0 && !(expect.fine_voxel_m > 0)) {
    return core::CorruptData(path + ": " + std::to_string(n_points) + " fine points, but segment.yaml's " +
                             "fine_voxel_m is " + g17(expect.fine_voxel_m) +
                             " (must be > 0 with fine points)");
  }

  // Everything below is bounded by the real file length.
  std::vector<uint8_t> region_bytes_read(region_bytes);
  HWR_RETURN_IF_ERROR(file.read_at(kBinHeaderBytes, region_bytes_read.data(), region_bytes_read.size()));
  uint32_t crc = crc32_bytes(region_bytes_read.data(), region_bytes_read.size());
  std::vector<CloudPoint> points(n_points);
  std::vector<uint32_t> counts(n_points);
  std::vector<uint8_t> chunk(std::min(n_points, kFineChunkPoints) * kFinePointBytes);
  // The first bad point, reported only once the CRC has shown the bytes are the ones written.
  uint64_t bad_point = 0;
  const char* point_problem = nullptr;
  uint64_t offset = kBinHeaderBytes + region_bytes;
  for (uint64_t i = 0; i < n_points;) {
    const uint64_t n = std::min(kFineChunkPoints, n_points - i);
    HWR_RETURN_IF_ERROR(file.read_at(offset, chunk.data(), n * kFinePointBytes));
    crc = crc32_bytes(chunk.data(), n * kFinePointBytes, crc);
    for (uint64_t k = 0; k < n; ++k) {
      const uint8_t* p = chunk.data() + k * kFinePointBytes;
      std::memcpy(&points[i + k], p, kCloudPointBytes);
      counts[i + k] = get<uint32_t>(p, kCloudPointBytes);
      if (point_problem == nullptr) {
        point_problem = fine_point_problem(points[i + k], counts[i + k]);
        bad_point = i + k;
      }
    }
    offset += n * kFinePointBytes;
    i += n;
  }
  HWR_RETURN_IF_ERROR(compare_payload_crc(path, crc, stored_crc));

  std::vector<StoredWeldRegion> regions(n_regions);
  for (uint64_t i = 0; i < n_regions; ++i) {
    const uint8_t* p = region_bytes_read.data() + i * kWeldRegionRecordBytes;
    StoredWeldRegion& s = regions[i];
    WeldRegion& r = s.region;
    r.id = get<uint32_t>(p, 0);
    if (p[5] != 0 || p[6] != 0 || p[7] != 0) {
      return core::CorruptData(path + ": " + region_name(i, r.id) + ": padding bytes 5..7 are not zero");
    }
    r.source = static_cast<WeldRegionSource>(p[4]);
    r.confidence = get<float>(p, 8);
    std::memcpy(r.label.data(), p + 12, kWeldRegionLabelBytes);
    r.keyframe_id = get<int32_t>(p, 44);
    r.t_ns = get<int64_t>(p, 48);
    r.T_cam_region = get_pose(p, 56);
    for (int k = 0; k < 3; ++k) r.half_size_m[k] = get<double>(p, 152 + 8 * static_cast<size_t>(k));
    s.T_segment_region = get_pose(p, 176);
    s.fine_points = get<int64_t>(p, 272);
    for (int k = 0; k < 3; ++k) s.viewpoint_segment[k] = get<double>(p, 280 + 8 * static_cast<size_t>(k));
    const std::string problem = weld_region_problem(s);
    if (!problem.empty()) return core::CorruptData(path + ": " + region_name(i, r.id) + ": " + problem);
  }
  if (point_problem != nullptr) {
    return core::CorruptData(path + ": fine point " + std::to_string(bad_point) + " " + point_problem);
  }
  *regions_out = std::move(regions);
  *points_out = std::move(points);
  *counts_out = std::move(counts);
  return core::Status::Ok();
}

}  // namespace hwr::recon::store_detail
