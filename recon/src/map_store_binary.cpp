#include "map_store_binary.hpp"

#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <limits>
#include <type_traits>

#include "map_store_files.hpp"

namespace hwr::recon::store_detail {
namespace {

static_assert(
    __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
    "the map store's files are little-endian and written with memcpy; add byte swaps for this host");
static_assert(sizeof(CloudPoint) == kCloudPointBytes && std::is_trivially_copyable<CloudPoint>::value,
              "cloud.bin stores CloudPoint's bytes as they are");
static_assert(offsetof(CloudPoint, r) == 12 && offsetof(CloudPoint, flags) == 15, "CloudPoint layout");

constexpr char kKeyframesMagic[8] = {'H', 'W', 'R', 'K', 'F', '0', '0', '1'};
constexpr char kCloudMagic[8] = {'H', 'W', 'R', 'P', 'C', '0', '0', '1'};
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

core::Status check_payload_crc(const std::string& path, const uint8_t* payload, size_t n, uint32_t stored) {
  const uint32_t crc = crc32_bytes(payload, n);
  if (crc != stored) {
    return core::CorruptData(path + ": payload CRC32 mismatch (stored " + hex32(stored) + ", computed " +
                             hex32(crc) + "); the file is corrupt");
  }
  return core::Status::Ok();
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

}  // namespace hwr::recon::store_detail
