// The on-disk map store (issue #4 item 4). Oracles: a segment read back equals the one written,
// field by field and bit for bit (poses, -0.0, subnormals, INT64_MAX, weld region labels with bytes
// after their NUL); the files' CRCs equal a second, bitwise CRC32 written here; every corruption (a
// flipped byte, a truncation, a header claiming huge counts, a record with valid CRCs but invalid
// content) is kCorruptData naming the file, and the huge claim allocates nothing of its size; what
// the reader would refuse the writer refuses (kInvalidArgument, nothing written); a format-1
// segment (before fine.bin) and a format-1 store still read; a writer killed with SIGKILL at random
// moments leaves a store whose segments are exactly the prefix 0..k-1 of what it wrote.

#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "sigkill_writer.hpp"
#include "temp_dir.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/recon/map_store.hpp"

namespace hwr::recon {
namespace {

namespace fs = std::filesystem;

constexpr int kDescriptorBytes = 32;

struct TempDir : hwr::testing::TempDir {
  TempDir() : hwr::testing::TempDir("hwr_map_store") {}
  std::string store() const { return file("store"); }
};

// Bitwise CRC32 (ISO-HDLC, reflected 0xEDB88320): a second implementation of the files' checksum.
uint32_t reference_crc32(const uint8_t* p, size_t n) {
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

template <class T>
void put(std::vector<uint8_t>* b, size_t offset, T v) {
  std::memcpy(b->data() + offset, &v, sizeof(T));
}
template <class T>
T get(const std::vector<uint8_t>& b, size_t offset) {
  T v;
  std::memcpy(&v, b.data() + offset, sizeof(T));
  return v;
}

// Header CRC (bytes 0..43, stored at 44) after a test edits a header field (map_store_binary.hpp).
void reseal_header(std::vector<uint8_t>* b) { put<uint32_t>(b, 44, reference_crc32(b->data(), 44)); }

std::string segment_dir(const std::string& store, uint32_t id) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "seg_%06u", id);
  return store + "/segments/" + buf;
}

std::string read_text(const std::string& path) {
  const std::vector<uint8_t> b = read_bytes(path);
  return std::string(b.begin(), b.end());
}

void write_text(const std::string& path, const std::string& text) {
  write_bytes(path, std::vector<uint8_t>(text.begin(), text.end()));
}

// segment.yaml edited as a writer would have written it: `edit` changes the text above the
// self_crc32 line, which is then written again with the CRC32 of that text (map_store.cpp).
template <class Edit>
void rewrite_segment_yaml(const std::string& path, Edit edit) {
  const std::string text = read_text(path);
  const size_t at = text.rfind("\nself_crc32:");
  ASSERT_NE(at, std::string::npos) << text;
  std::string body = text.substr(0, at + 1);
  edit(&body);
  body += "self_crc32: " +
          std::to_string(reference_crc32(reinterpret_cast<const uint8_t*>(body.data()), body.size())) +
          "  # CRC32 of every byte above this line\n";
  write_text(path, body);
}

// The line "KEY: ..." of a segment.yaml body (top level: at the start of a line).
size_t yaml_line(const std::string& body, const std::string& key) {
  if (body.compare(0, key.size() + 1, key + ":") == 0) return 0;
  const size_t at = body.find("\n" + key + ":");
  return at == std::string::npos ? at : at + 1;
}

void set_yaml_value(std::string* body, const std::string& key, const std::string& value) {
  const size_t line = yaml_line(*body, key);
  ASSERT_NE(line, std::string::npos) << key << " not in\n" << *body;
  const size_t end = body->find('\n', line);
  body->replace(line, end - line, key + ": " + value);
}

void remove_yaml_line(std::string* body, const std::string& key) {
  const size_t line = yaml_line(*body, key);
  ASSERT_NE(line, std::string::npos) << key << " not in\n" << *body;
  body->erase(line, body->find('\n', line) + 1 - line);
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }
bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

bool same_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!same_bits(a.matrix()(r, c), b.matrix()(r, c))) return false;
    }
  }
  return true;
}

StoreMetadata test_metadata() {
  StoreMetadata m;
  m.robot_id = "hwr-7 \"lab\" \\ bench";
  m.run_id = "20261124T195600Z";
  m.intrinsics.width = 640;
  m.intrinsics.height = 480;
  m.intrinsics.fx = 535.4;
  m.intrinsics.fy = 539.2;
  m.intrinsics.cx = 320.1;
  m.intrinsics.cy = 247.6;
  m.intrinsics.distortion = {0.1, -0.25, 1e-3, -2e-4, 1.0 / 3.0};
  // A camera 10 cm ahead of and 30 cm above the IMU, pitched down 18 deg (the sim's mount):
  // irrational entries, so a round trip that is not bit-exact shows.
  m.T_imu_cam.linear() = Eigen::AngleAxisd(0.1 * M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                         (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
  m.T_imu_cam.translation() = Eigen::Vector3d(0.1, 0.0, 0.3);
  return m;
}

Eigen::Isometry3d random_pose(std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Vector3d axis(u(*rng), u(*rng), u(*rng));
  axis.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(3.0 * u(*rng), axis).toRotationMatrix();
  T.translation() = Eigen::Vector3d(20 * u(*rng), 20 * u(*rng), 2 * u(*rng));
  return T;
}

// The content a writer produces for segment `id`, derived from the id alone (the SIGKILL test's
// parent rebuilds it to check what the killed child left).
SegmentRecord make_segment(uint32_t id, int n_keyframes, int n_points) {
  std::mt19937_64 rng(0x9E3779B97F4A7C15ull ^ id);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255);
  SegmentRecord s;
  s.segment_id = id;
  s.T_world_segment = random_pose(&rng);
  s.travelled_m = 17.0 + u(rng);
  s.t_first_ns = 1'700'000'000'000'000'000 + static_cast<int64_t>(id) * 1'000'000'000;
  s.t_last_ns = s.t_first_ns + 999'999'937;
  JunctionRecord& j = s.junction;
  j.valid = id > 0;
  j.keyframe_before = static_cast<int32_t>(10 * id) - 1;
  j.keyframe_after = static_cast<int32_t>(10 * id);
  j.orb_matches = 300 + static_cast<int>(id % 97);
  j.orb_inliers = 120 + static_cast<int>(id % 31);
  j.ndt_converged = id % 3 != 0;
  j.ndt_iterations = 5 + static_cast<int>(id % 11);
  j.ndt_fitness = 0.01 + 0.001 * u(rng);
  j.T_prev_segment_segment = random_pose(&rng);
  j.T_prev_segment_segment_odometry = random_pose(&rng);
  j.T_prev_segment_segment_measured = random_pose(&rng);
  j.fused = id % 2 == 0;
  j.ndt_used = id % 4 == 0;
  j.odometry_kept = id % 4 == 1;
  for (int k = 0; k < n_keyframes; ++k) {
    StoredKeyframe kf;
    kf.id = static_cast<int32_t>(10 * id) + k;
    kf.t_ns = s.t_first_ns + 100'000'000LL * k;
    kf.T_world_cam = random_pose(&rng);
    const int n_features = (k * 37 + static_cast<int>(id)) % 60;  // 0 features happens too
    for (int f = 0; f < n_features; ++f) {
      StoredFeature sf;
      sf.u_px = static_cast<float>(320 + 320 * u(rng));
      sf.v_px = static_cast<float>(240 + 240 * u(rng));
      sf.depth_m = f % 4 == 0 ? 0.0f : static_cast<float>(4 + 3 * u(rng));
      sf.octave = static_cast<uint8_t>(f % 8);
      kf.features.push_back(sf);
    }
    for (int b = 0; b < n_features * kDescriptorBytes; ++b)
      kf.descriptors.push_back(static_cast<uint8_t>(byte(rng)));
    kf.gnss_valid = k % 2 == 0;
    if (kf.gnss_valid) {
      kf.lat_deg = 48.137154 + 1e-5 * u(rng);
      kf.lon_deg = 11.576124 + 1e-5 * u(rng);
      kf.alt_m = 519.0 + u(rng);
    }
    kf.mag_valid = k % 3 != 1;
    if (kf.mag_valid) kf.mag_imu_uT = Eigen::Vector3d(20 * u(rng), -5 * u(rng), 43 * u(rng));
    s.keyframes.push_back(std::move(kf));
  }
  s.points_segment.resize(static_cast<size_t>(n_points));
  for (CloudPoint& p : s.points_segment) {
    p.x_m = static_cast<float>(10 * u(rng));
    p.y_m = static_cast<float>(10 * u(rng));
    p.z_m = static_cast<float>(3 * u(rng));
    p.r = static_cast<uint8_t>(byte(rng));
    p.g = static_cast<uint8_t>(byte(rng));
    p.b = static_cast<uint8_t>(byte(rng));
    p.flags = static_cast<uint8_t>(byte(rng) & 1);
  }
  return s;
}

// Weld regions and a fine cloud for a segment (fine.bin), derived from its id alone: the sources
// cycle through all four values, one label fills the 31 bytes, one keeps bytes after its NUL.
void add_fine_data(SegmentRecord* s, int n_regions, int n_points) {
  std::mt19937_64 rng(0xF1E7D0A7ull ^ s->segment_id);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255);
  s->fine_voxel_m = 0.002 + 1e-19;  // not a short decimal
  const WeldRegionSource sources[] = {WeldRegionSource::kModel, WeldRegionSource::kGeometry,
                                      WeldRegionSource::kOperator, WeldRegionSource::kSimTruth};
  for (int r = 0; r < n_regions; ++r) {
    StoredWeldRegion sr;
    WeldRegion& w = sr.region;
    w.id = 1000 * s->segment_id + static_cast<uint32_t>(r);
    w.source = sources[(static_cast<uint32_t>(r) + s->segment_id) % 4];
    w.confidence = static_cast<float>(0.5 + 0.5 * u(rng));
    if (r % 3 == 0) {
      set_weld_region_label(&w, "plate_" + std::to_string(s->segment_id) + "_joint_" + std::to_string(r));
    } else if (r % 3 == 1) {
      set_weld_region_label(&w, std::string(40, 'L'));  // cut to 31 bytes and a NUL
    } else {
      set_weld_region_label(&w, "fillet");
      w.label[20] = 'z';  // after the NUL: kept as it is
    }
    w.keyframe_id = static_cast<int32_t>(10 * s->segment_id) + r - 1;
    w.t_ns = s->t_first_ns + 33'333'333LL * r;
    w.T_cam_region = random_pose(&rng);
    w.half_size_m = Eigen::Vector3d(0.05 + 0.01 * u(rng), 0.3 + 0.1 * u(rng), 0.02 + 0.001 * u(rng));
    sr.T_segment_region = random_pose(&rng);
    sr.fine_points = n_points / (r + 1);
    sr.viewpoint_segment = Eigen::Vector3d(0.5 * u(rng) - 1.0, -0.25, 1.0 + u(rng));
    s->weld_regions.push_back(sr);
  }
  s->fine_points_segment.resize(static_cast<size_t>(n_points));
  s->fine_counts.resize(static_cast<size_t>(n_points));
  for (int i = 0; i < n_points; ++i) {
    CloudPoint& p = s->fine_points_segment[static_cast<size_t>(i)];
    p.x_m = static_cast<float>(2 + 0.2 * u(rng));
    p.y_m = static_cast<float>(-1 + 0.3 * u(rng));
    p.z_m = static_cast<float>(0.01 * u(rng));
    p.r = static_cast<uint8_t>(byte(rng));
    p.g = static_cast<uint8_t>(byte(rng));
    p.b = static_cast<uint8_t>(byte(rng));
    p.flags = static_cast<uint8_t>(byte(rng) & 1);
    s->fine_counts[static_cast<size_t>(i)] =
        i == 0 ? std::numeric_limits<uint32_t>::max() : 1 + static_cast<uint32_t>(byte(rng) % 40);
  }
}

bool same_point(const CloudPoint& p, const CloudPoint& q) {
  return same_bits(p.x_m, q.x_m) && same_bits(p.y_m, q.y_m) && same_bits(p.z_m, q.z_m) && p.r == q.r &&
         p.g == q.g && p.b == q.b && p.flags == q.flags;
}

// Field-by-field, bit-exact; returns the first difference (empty when equal).
std::string first_difference(const SegmentRecord& a, const SegmentRecord& b) {
  if (a.segment_id != b.segment_id) return "segment_id";
  if (!same_pose(a.T_world_segment, b.T_world_segment)) return "T_world_segment";
  if (!same_bits(a.travelled_m, b.travelled_m)) return "travelled_m";
  if (a.t_first_ns != b.t_first_ns || a.t_last_ns != b.t_last_ns) return "t_first_ns/t_last_ns";
  const JunctionRecord& ja = a.junction;
  const JunctionRecord& jb = b.junction;
  if (ja.valid != jb.valid || ja.keyframe_before != jb.keyframe_before ||
      ja.keyframe_after != jb.keyframe_after || ja.orb_matches != jb.orb_matches ||
      ja.orb_inliers != jb.orb_inliers || ja.ndt_converged != jb.ndt_converged ||
      ja.ndt_iterations != jb.ndt_iterations || !same_bits(ja.ndt_fitness, jb.ndt_fitness) ||
      ja.fused != jb.fused || ja.ndt_used != jb.ndt_used || ja.odometry_kept != jb.odometry_kept) {
    return "junction scalars";
  }
  if (!same_pose(ja.T_prev_segment_segment, jb.T_prev_segment_segment))
    return "junction.T_prev_segment_segment";
  if (!same_pose(ja.T_prev_segment_segment_odometry, jb.T_prev_segment_segment_odometry)) {
    return "junction.T_prev_segment_segment_odometry";
  }
  if (!same_pose(ja.T_prev_segment_segment_measured, jb.T_prev_segment_segment_measured)) {
    return "junction.T_prev_segment_segment_measured";
  }
  if (a.keyframes.size() != b.keyframes.size()) return "keyframes.size()";
  for (size_t k = 0; k < a.keyframes.size(); ++k) {
    const StoredKeyframe& x = a.keyframes[k];
    const StoredKeyframe& y = b.keyframes[k];
    const std::string at = "keyframes[" + std::to_string(k) + "].";
    if (x.id != y.id) return at + "id";
    if (x.t_ns != y.t_ns) return at + "t_ns";
    if (!same_pose(x.T_world_cam, y.T_world_cam)) return at + "T_world_cam";
    if (x.features.size() != y.features.size()) return at + "features.size()";
    for (size_t f = 0; f < x.features.size(); ++f) {
      const StoredFeature& p = x.features[f];
      const StoredFeature& q = y.features[f];
      if (!same_bits(p.u_px, q.u_px) || !same_bits(p.v_px, q.v_px) || !same_bits(p.depth_m, q.depth_m) ||
          p.octave != q.octave) {
        return at + "features[" + std::to_string(f) + "]";
      }
    }
    if (x.descriptors != y.descriptors) return at + "descriptors";
    if (x.gnss_valid != y.gnss_valid || !same_bits(x.lat_deg, y.lat_deg) ||
        !same_bits(x.lon_deg, y.lon_deg) || !same_bits(x.alt_m, y.alt_m)) {
      return at + "gnss";
    }
    if (x.mag_valid != y.mag_valid) return at + "mag_valid";
    for (int i = 0; i < 3; ++i) {
      if (!same_bits(x.mag_imu_uT[i], y.mag_imu_uT[i])) return at + "mag_imu_uT";
    }
  }
  if (a.points_segment.size() != b.points_segment.size()) return "points_segment.size()";
  for (size_t i = 0; i < a.points_segment.size(); ++i) {
    if (!same_point(a.points_segment[i], b.points_segment[i]))
      return "points_segment[" + std::to_string(i) + "]";
  }
  if (!same_bits(a.fine_voxel_m, b.fine_voxel_m)) return "fine_voxel_m";
  if (a.weld_regions.size() != b.weld_regions.size()) return "weld_regions.size()";
  for (size_t i = 0; i < a.weld_regions.size(); ++i) {
    const StoredWeldRegion& x = a.weld_regions[i];
    const StoredWeldRegion& y = b.weld_regions[i];
    const std::string at = "weld_regions[" + std::to_string(i) + "].";
    if (x.region.id != y.region.id) return at + "id";
    if (x.region.source != y.region.source) return at + "source";
    if (!same_bits(x.region.confidence, y.region.confidence)) return at + "confidence";
    if (x.region.label != y.region.label) return at + "label";
    if (x.region.keyframe_id != y.region.keyframe_id) return at + "keyframe_id";
    if (x.region.t_ns != y.region.t_ns) return at + "t_ns";
    if (!same_pose(x.region.T_cam_region, y.region.T_cam_region)) return at + "T_cam_region";
    for (int k = 0; k < 3; ++k) {
      if (!same_bits(x.region.half_size_m[k], y.region.half_size_m[k])) return at + "half_size_m";
    }
    if (!same_pose(x.T_segment_region, y.T_segment_region)) return at + "T_segment_region";
    if (x.fine_points != y.fine_points) return at + "fine_points";
    for (int k = 0; k < 3; ++k) {
      if (!same_bits(x.viewpoint_segment[k], y.viewpoint_segment[k])) return at + "viewpoint_segment";
    }
  }
  if (a.fine_points_segment.size() != b.fine_points_segment.size()) return "fine_points_segment.size()";
  for (size_t i = 0; i < a.fine_points_segment.size(); ++i) {
    if (!same_point(a.fine_points_segment[i], b.fine_points_segment[i])) {
      return "fine_points_segment[" + std::to_string(i) + "]";
    }
  }
  if (a.fine_counts != b.fine_counts) return "fine_counts";
  return "";
}

MapStore open_store(const std::string& dir) {
  auto store = MapStore::open(dir, test_metadata());
  EXPECT_TRUE(store.ok()) << store.status().to_string();
  return std::move(store).value();
}

// A store holding segment 0 (3 keyframes, 2000 points) for the corruption tests.
std::string store_with_one_segment(const TempDir& tmp) {
  MapStore store = open_store(tmp.store());
  EXPECT_TRUE(store.write_segment(make_segment(0, 3, 2000)).ok());
  return tmp.store();
}

// `saying`: a phrase the message must hold (what is wrong), when not empty.
void expect_corrupt_naming(const std::string& dir, uint32_t id, const std::string& file,
                           const std::string& saying = "") {
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok()) << store.status().to_string();
  auto seg = store->read_segment(id);
  ASSERT_FALSE(seg.ok()) << "a damaged " << file << " was read without error";
  EXPECT_EQ(seg.status().code(), core::ErrorCode::kCorruptData) << seg.status().to_string();
  EXPECT_NE(seg.status().message().find(segment_dir(dir, id) + "/" + file), std::string::npos)
      << "message does not name the file: " << seg.status().message();
  EXPECT_NE(seg.status().message().find(saying), std::string::npos)
      << "message does not say '" << saying << "': " << seg.status().message();
}

TEST(MapStore, ReferenceCrc32MatchesTheStandardCheckValue) {
  const char* check = "123456789";
  EXPECT_EQ(reference_crc32(reinterpret_cast<const uint8_t*>(check), 9), 0xCBF43926u);
}

TEST(MapStore, GivenASegmentWith100kPointsWhenReadBackThenEveryFieldIsBitExact) {
  TempDir tmp;
  SegmentRecord seg = make_segment(7, 4, 100000);
  // Values %.17g and strtod must carry exactly.
  seg.travelled_m = 1.0 / 3.0;
  seg.junction.ndt_fitness = std::numeric_limits<double>::denorm_min();
  seg.t_last_ns = std::numeric_limits<int64_t>::max();
  seg.t_first_ns = std::numeric_limits<int64_t>::min();
  seg.T_world_segment.translation().x() = -0.0;
  seg.keyframes[1].lat_deg = -33.868820000000001;
  {
    MapStore store = open_store(tmp.store());
    ASSERT_TRUE(store.write_segment(seg).ok());
  }
  auto store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(store.ok()) << store.status().to_string();
  auto back = store->read_segment(7);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(first_difference(seg, *back), "");
  EXPECT_EQ(back->points_segment.size(), 100000u);
  EXPECT_TRUE(std::signbit(back->T_world_segment.translation().x()));

  // The stored CRCs are the standard CRC32 of the payloads (second implementation).
  for (const char* file : {"keyframes.bin", "cloud.bin", "fine.bin"}) {
    const std::vector<uint8_t> b = read_bytes(segment_dir(tmp.store(), 7) + "/" + file);
    ASSERT_GE(b.size(), 48u);
    EXPECT_EQ(get<uint32_t>(b, 44), reference_crc32(b.data(), 44)) << file;
    EXPECT_EQ(get<uint32_t>(b, 40), reference_crc32(b.data() + 48, b.size() - 48)) << file;
    EXPECT_EQ(get<uint64_t>(b, 32), b.size() - 48) << file;
  }
  EXPECT_EQ(read_bytes(segment_dir(tmp.store(), 7) + "/cloud.bin").size(), 48u + 16u * 100000u);
  EXPECT_EQ(read_bytes(segment_dir(tmp.store(), 7) + "/fine.bin").size(), 48u) << "no fine data: a header";
}

TEST(MapStore, GivenSegmentsWrittenOutOfOrderThenListIsSortedWithTheirCounts) {
  TempDir tmp;
  MapStore store = open_store(tmp.store());
  const uint32_t ids[] = {12, 0, 3, 1000000};
  const int keyframes[] = {2, 5, 0, 1};
  const int points[] = {500, 0, 1234, 7};
  for (int i = 0; i < 4; ++i)
    ASSERT_TRUE(store.write_segment(make_segment(ids[i], keyframes[i], points[i])).ok());
  auto list = store.list_segments();
  ASSERT_TRUE(list.ok()) << list.status().to_string();
  ASSERT_EQ(list->size(), 4u);
  const uint32_t sorted[] = {0, 3, 12, 1000000};
  const int sorted_kf[] = {5, 0, 2, 1};
  const int sorted_pts[] = {0, 1234, 500, 7};
  for (int i = 0; i < 4; ++i) {
    const SegmentSummary& s = (*list)[static_cast<size_t>(i)];
    EXPECT_EQ(s.segment_id, sorted[i]);
    EXPECT_EQ(s.keyframes, sorted_kf[i]);
    EXPECT_EQ(s.points, sorted_pts[i]);
    const std::string d = segment_dir(tmp.store(), s.segment_id);
    EXPECT_EQ(s.bytes, fs::file_size(d + "/segment.yaml") + fs::file_size(d + "/keyframes.bin") +
                           fs::file_size(d + "/cloud.bin") + fs::file_size(d + "/fine.bin"));
    auto back = store.read_segment(s.segment_id);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(first_difference(make_segment(sorted[i], sorted_kf[i], sorted_pts[i]), *back), "");
  }
}

TEST(MapStore, GivenAFlippedByteThenReadIsCorruptDataNamingTheFile) {
  struct Case {
    const char* file;
    size_t offset_from_end;  // a payload byte (or a digit of a pose for segment.yaml)
  };
  for (const Case& c : {Case{"cloud.bin", 100}, Case{"keyframes.bin", 7}, Case{"cloud.bin", 1}}) {
    TempDir tmp;
    const std::string dir = store_with_one_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/" + c.file;
    std::vector<uint8_t> b = read_bytes(path);
    b[b.size() - c.offset_from_end] ^= 0x10;
    write_bytes(path, b);
    expect_corrupt_naming(dir, 0, c.file);
  }
  // segment.yaml: one digit of T_world_segment changes, the YAML stays valid.
  TempDir tmp;
  const std::string dir = store_with_one_segment(tmp);
  const std::string path = segment_dir(dir, 0) + "/segment.yaml";
  std::vector<uint8_t> b = read_bytes(path);
  const std::string text(b.begin(), b.end());
  const size_t at = text.find("T_world_segment: [");
  ASSERT_NE(at, std::string::npos);
  size_t digit = text.find_first_of("123456789", at + 20);
  b[digit] = b[digit] == '1' ? '2' : '1';
  write_bytes(path, b);
  expect_corrupt_naming(dir, 0, "segment.yaml");
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok());
  EXPECT_EQ(store->list_segments().status().code(), core::ErrorCode::kCorruptData);
}

TEST(MapStore, GivenATruncatedKeyframesFileThenReadIsCorruptData) {
  for (uint64_t keep : {0ull, 20ull, 48ull, 300ull, 1ull << 40}) {
    TempDir tmp;
    const std::string dir = store_with_one_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/keyframes.bin";
    const uint64_t size = fs::file_size(path);
    fs::resize_file(path, keep == (1ull << 40) ? size - 1 : keep);
    SCOPED_TRACE("kept " + std::to_string(fs::file_size(path)) + " of " + std::to_string(size) + " bytes");
    expect_corrupt_naming(dir, 0, "keyframes.bin");
  }
  // cloud.bin one point short: the size segment.yaml recorded catches it and says so.
  TempDir tmp;
  const std::string dir = store_with_one_segment(tmp);
  const std::string path = segment_dir(dir, 0) + "/cloud.bin";
  fs::resize_file(path, fs::file_size(path) - 16);
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok());
  auto seg = store->read_segment(0);
  EXPECT_EQ(seg.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(seg.status().message().find("truncated"), std::string::npos) << seg.status().message();
}

TEST(MapStore, GivenAHeaderClaimingHugeCountsThenCorruptDataWithoutAllocatingThem) {
  {
    // Control: the counter sees the real read's allocations (2000 points = 32000 bytes).
    TempDir tmp;
    auto store = MapStore::open_existing(store_with_one_segment(tmp));
    ASSERT_TRUE(store.ok());
    core::AllocationScope scope;
    auto seg = store->read_segment(0);
    const uint64_t bytes = scope.bytes();
    ASSERT_TRUE(seg.ok()) << seg.status().to_string();
    EXPECT_GE(bytes, 2000u * sizeof(CloudPoint));
  }
  // cloud.bin: 1e9 points (16 GB) in a 32 KB file, header CRC resealed so only the size checks
  // can catch it; then the same count with a payload size matching the file.
  for (bool consistent_payload : {true, false}) {
    TempDir tmp;
    const std::string dir = store_with_one_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/cloud.bin";
    std::vector<uint8_t> b = read_bytes(path);
    put<uint64_t>(&b, 24, 1'000'000'000ull);
    if (consistent_payload) put<uint64_t>(&b, 32, 16'000'000'000ull);
    reseal_header(&b);
    write_bytes(path, b);
    auto store = MapStore::open_existing(dir);
    ASSERT_TRUE(store.ok());
    core::AllocationScope scope;
    auto seg = store->read_segment(0);
    const uint64_t bytes = scope.bytes();
    ASSERT_FALSE(seg.ok());
    EXPECT_EQ(seg.status().code(), core::ErrorCode::kCorruptData) << seg.status().to_string();
    EXPECT_NE(seg.status().message().find("cloud.bin"), std::string::npos) << seg.status().message();
    EXPECT_LT(bytes, 1u << 20) << "allocated " << bytes << " bytes for a file that claims 16 GB";
  }
  // keyframes.bin: 2^32-1 keyframes and 2^60 features, payload size claimed to match.
  TempDir tmp;
  const std::string dir = store_with_one_segment(tmp);
  const std::string path = segment_dir(dir, 0) + "/keyframes.bin";
  std::vector<uint8_t> b = read_bytes(path);
  put<uint32_t>(&b, 16, 0xFFFFFFFFu);
  put<uint64_t>(&b, 24, 1ull << 60);
  put<uint64_t>(&b, 32, b.size() - 48);
  reseal_header(&b);
  write_bytes(path, b);
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok());
  core::AllocationScope scope;
  auto seg = store->read_segment(0);
  const uint64_t bytes = scope.bytes();
  EXPECT_EQ(seg.status().code(), core::ErrorCode::kCorruptData) << seg.status().to_string();
  EXPECT_NE(seg.status().message().find("keyframes.bin"), std::string::npos) << seg.status().message();
  EXPECT_LT(bytes, 1u << 20);
}

TEST(MapStore, GivenAMissingSegmentOrStoreThenNotFound) {
  TempDir tmp;
  const std::string dir = store_with_one_segment(tmp);
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok());
  EXPECT_EQ(store->read_segment(1).status().code(), core::ErrorCode::kNotFound);
  EXPECT_EQ(MapStore::open_existing(tmp.path() + "/absent").status().code(), core::ErrorCode::kNotFound);
  fs::create_directories(tmp.path() + "/empty");
  EXPECT_EQ(MapStore::open_existing(tmp.path() + "/empty").status().code(), core::ErrorCode::kNotFound);
  EXPECT_FALSE(fs::exists(tmp.path() + "/absent")) << "open_existing must create nothing";
}

TEST(MapStore, GivenAnExistingStoreWhenReopenedThenItKeepsItsMetadata) {
  TempDir tmp;
  const StoreMetadata first = test_metadata();
  ASSERT_TRUE(store_with_one_segment(tmp).size() > 0);
  StoreMetadata other;
  other.robot_id = "someone-else";
  other.run_id = "19700101T000000Z";
  other.descriptor_bytes = 64;
  auto reopened = MapStore::open(tmp.store(), other);
  ASSERT_TRUE(reopened.ok()) << reopened.status().to_string();
  auto existing = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(existing.ok()) << existing.status().to_string();
  for (const StoreMetadata* m : {&reopened->metadata(), &existing->metadata()}) {
    EXPECT_EQ(m->format_version, 2u) << "a new store is created at this build's version";
    EXPECT_EQ(m->robot_id, first.robot_id);
    EXPECT_EQ(m->run_id, first.run_id);
    EXPECT_EQ(m->descriptor_bytes, first.descriptor_bytes);
    EXPECT_EQ(m->intrinsics.width, 640);
    EXPECT_EQ(m->intrinsics.height, 480);
    EXPECT_TRUE(same_bits(m->intrinsics.fx, first.intrinsics.fx));
    EXPECT_TRUE(same_bits(m->intrinsics.fy, first.intrinsics.fy));
    EXPECT_TRUE(same_bits(m->intrinsics.cx, first.intrinsics.cx));
    EXPECT_TRUE(same_bits(m->intrinsics.cy, first.intrinsics.cy));
    for (size_t i = 0; i < 5; ++i)
      EXPECT_TRUE(same_bits(m->intrinsics.distortion[i], first.intrinsics.distortion[i]));
    EXPECT_TRUE(same_pose(m->T_imu_cam, first.T_imu_cam));
    EXPECT_FALSE(same_pose(m->T_imu_cam, Eigen::Isometry3d::Identity()));
    EXPECT_TRUE(m->T_imu_cam_recorded);
  }
  auto list = reopened->list_segments();
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->size(), 1u);
  EXPECT_TRUE(reopened->read_segment(0).ok());
}

// T_imu_cam (relocalization_priors.hpp needs the IMU attitude of each keyframe): a store written
// before the field existed reads back as identity; a non-rigid one is refused on write and on read.
TEST(MapStore, GivenAStoreWithoutOrWithABadTImuCamThenIdentityOrAnErrorNamingIt) {
  TempDir tmp;
  ASSERT_TRUE(store_with_one_segment(tmp).size() > 0);
  const std::string yaml = tmp.store() + "/store.yaml";
  const std::vector<uint8_t> good = read_bytes(yaml);
  const std::string text(good.begin(), good.end());
  const size_t line = text.find("T_imu_cam:");
  ASSERT_NE(line, std::string::npos) << text;
  const size_t end = text.find('\n', line);
  ASSERT_NE(end, std::string::npos);

  std::string older = text;
  older.erase(line, end + 1 - line);
  write_bytes(yaml, std::vector<uint8_t>(older.begin(), older.end()));
  auto old_store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(old_store.ok()) << old_store.status().to_string();
  EXPECT_TRUE(same_pose(old_store->metadata().T_imu_cam, Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(old_store->metadata().T_imu_cam_recorded) << "an older store: identity is not a calibration";
  EXPECT_EQ(old_store->metadata().run_id, test_metadata().run_id);

  // A scaled rotation (2 x identity) and a reflection (diag(1, 1, -1)).
  for (const char* bad : {"T_imu_cam: [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0]",
                          "T_imu_cam: [1, 0, 0, 0.1, 0, 1, 0, 0, 0, 0, -1, 0.3]"}) {
    std::string broken = text;
    broken.replace(line, end - line, bad);
    write_bytes(yaml, std::vector<uint8_t>(broken.begin(), broken.end()));
    const core::Status st = MapStore::open_existing(tmp.store()).status();
    EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << bad << ": " << st.to_string();
    EXPECT_NE(st.message().find("T_imu_cam"), std::string::npos) << st.message();
  }

  StoreMetadata reflected = test_metadata();
  reflected.T_imu_cam.linear().col(2) *= -1.0;
  const core::Status st = MapStore::open(tmp.path() + "/new_store", reflected).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument) << st.to_string();
  EXPECT_NE(st.message().find("T_imu_cam"), std::string::npos) << st.message();
  EXPECT_FALSE(fs::exists(tmp.path() + "/new_store/store.yaml"));
}

TEST(MapStore, GivenATempDirectoryLeftBehindThenOpenRemovesItAndItIsNeverListed) {
  TempDir tmp;
  const std::string dir = store_with_one_segment(tmp);
  // What a writer killed mid-segment leaves: a .tmp- directory with partial files.
  const std::string left = dir + "/segments/.tmp-seg_000001-4242";
  fs::create_directories(left);
  write_bytes(left + "/keyframes.bin", std::vector<uint8_t>(10, 0xAB));
  write_bytes(dir + "/.tmp-store.yaml-4242", std::vector<uint8_t>(3, 'x'));
  {
    auto ro = MapStore::open_existing(dir);  // read-only: leaves it, never lists it
    ASSERT_TRUE(ro.ok());
    auto list = ro->list_segments();
    ASSERT_TRUE(list.ok()) << list.status().to_string();
    ASSERT_EQ(list->size(), 1u);
    EXPECT_EQ((*list)[0].segment_id, 0u);
    EXPECT_TRUE(fs::exists(left));
  }
  auto store = MapStore::open(dir, test_metadata());
  ASSERT_TRUE(store.ok()) << store.status().to_string();
  EXPECT_FALSE(fs::exists(left));
  EXPECT_FALSE(fs::exists(dir + "/.tmp-store.yaml-4242"));
  // The id the interrupted write was for can be written now.
  EXPECT_TRUE(store->write_segment(make_segment(1, 1, 10)).ok());
  EXPECT_EQ(store->list_segments()->size(), 2u);
}

TEST(MapStore, GivenAnExistingIdOrBadDescriptorsThenWriteIsInvalidArgumentAndLeavesNothing) {
  TempDir tmp;
  MapStore store = open_store(tmp.store());
  const SegmentRecord seg = make_segment(4, 2, 100);
  ASSERT_TRUE(store.write_segment(seg).ok());
  const core::Status again = store.write_segment(make_segment(4, 1, 5));
  EXPECT_EQ(again.code(), core::ErrorCode::kInvalidArgument) << again.to_string();
  auto back = store.read_segment(4);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(first_difference(seg, *back), "") << "the first write must be untouched";

  SegmentRecord bad = make_segment(5, 3, 100);
  ASSERT_FALSE(bad.keyframes[2].features.empty());
  bad.keyframes[2].descriptors.pop_back();
  const core::Status st = store.write_segment(bad);
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument) << st.to_string();
  EXPECT_NE(st.message().find("keyframe " + std::to_string(bad.keyframes[2].id)), std::string::npos)
      << st.message();
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(tmp.store() + "/segments")) {
    (void)e;
    ++entries;
  }
  EXPECT_EQ(entries, 1u) << "a refused write must leave no directory behind";
}

TEST(MapStore, GivenBadStoreFilesOrPathsThenOpenNamesTheProblem) {
  TempDir tmp;
  ASSERT_TRUE(store_with_one_segment(tmp).size() > 0);
  const std::string yaml = tmp.store() + "/store.yaml";
  const std::vector<uint8_t> good = read_bytes(yaml);
  std::string text(good.begin(), good.end());

  std::string newer = text;
  ASSERT_NE(newer.find("format_version: 2\n"), std::string::npos) << text;
  newer.replace(newer.find("format_version: 2\n"), 17, "format_version: 3");
  write_bytes(yaml, std::vector<uint8_t>(newer.begin(), newer.end()));
  EXPECT_EQ(MapStore::open(tmp.store(), test_metadata()).status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(MapStore::open_existing(tmp.store()).status().code(), core::ErrorCode::kInvalidArgument);

  std::string malformed = text;
  malformed.replace(malformed.find("descriptor_bytes: 32"), 20, "descriptor_bytes: x2");
  write_bytes(yaml, std::vector<uint8_t>(malformed.begin(), malformed.end()));
  const core::Status st = MapStore::open(tmp.store(), test_metadata()).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << st.to_string();
  EXPECT_NE(st.message().find("descriptor_bytes"), std::string::npos) << st.message();

  // A path through a regular file cannot be created.
  write_bytes(tmp.path() + "/plain_file", {1, 2, 3});
  EXPECT_EQ(MapStore::open(tmp.path() + "/plain_file/store", test_metadata()).status().code(),
            core::ErrorCode::kIoError);
  // store.yaml lost under existing segments: refuse to start a new store over them.
  fs::remove(yaml);
  EXPECT_EQ(MapStore::open(tmp.store(), test_metadata()).status().code(), core::ErrorCode::kCorruptData);
}

// ---- fine.bin: the welding regions and the fine cloud (format 2) ----

// Segment 0 with 3 keyframes, 2000 points, 3 weld regions and `fine_points` fine points.
std::string store_with_fine_segment(const TempDir& tmp, int fine_points = 1000) {
  MapStore store = open_store(tmp.store());
  SegmentRecord seg = make_segment(0, 3, 2000);
  add_fine_data(&seg, 3, fine_points);
  EXPECT_TRUE(store.write_segment(seg).ok());
  return tmp.store();
}

// fine.bin after a test edited its payload: payload CRC (header and segment.yaml) and header CRC
// written again, so only the record checks can catch the edit.
void reseal_fine(const std::string& dir, uint32_t id, std::vector<uint8_t>* b) {
  const uint32_t crc = reference_crc32(b->data() + 48, b->size() - 48);
  put<uint32_t>(b, 40, crc);
  reseal_header(b);
  write_bytes(segment_dir(dir, id) + "/fine.bin", *b);
  rewrite_segment_yaml(segment_dir(dir, id) + "/segment.yaml", [&](std::string* body) {
    set_yaml_value(body, "fine_bin_crc32", std::to_string(crc));
  });
}

size_t segment_entries(const std::string& store) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(store + "/segments")) {
    (void)e;
    ++n;
  }
  return n;
}

TEST(MapStore, GivenASegmentWithThreeWeldRegionsAndAThousandFinePointsWhenReadBackThenEveryFieldIsBitExact) {
  TempDir tmp;
  SegmentRecord seg = make_segment(5, 3, 500);
  add_fine_data(&seg, 3, 1000);
  seg.weld_regions[1].region.confidence = -0.0f;
  seg.weld_regions[2].region.t_ns = std::numeric_limits<int64_t>::min();
  seg.weld_regions[2].fine_points = std::numeric_limits<int64_t>::max();
  seg.weld_regions[0].region.half_size_m.x() = std::numeric_limits<double>::denorm_min();
  seg.fine_points_segment[3].z_m = -0.0f;
  ASSERT_EQ(seg.weld_regions[0].region.source, WeldRegionSource::kGeometry);  // 5 % 4 = 1, then 2, 3
  ASSERT_EQ(seg.weld_regions[2].region.source, WeldRegionSource::kSimTruth);
  ASSERT_EQ(weld_region_label(seg.weld_regions[1].region).size(), 31u);
  ASSERT_EQ(seg.weld_regions[2].region.label[20], 'z');
  {
    MapStore store = open_store(tmp.store());
    ASSERT_TRUE(store.write_segment(seg).ok());
  }
  auto store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(store.ok()) << store.status().to_string();
  auto back = store->read_segment(5);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(first_difference(seg, *back), "");
  ASSERT_EQ(back->weld_regions.size(), 3u);
  EXPECT_EQ(back->fine_points_segment.size(), 1000u);
  EXPECT_EQ(weld_region_label(back->weld_regions[0].region), "plate_5_joint_0");
  EXPECT_EQ(back->fine_counts[0], std::numeric_limits<uint32_t>::max());

  // The layout of map_store_binary.hpp: header fields, sizes and the standard CRC32s.
  const std::string d = segment_dir(tmp.store(), 5);
  const std::vector<uint8_t> b = read_bytes(d + "/fine.bin");
  ASSERT_EQ(b.size(), 48u + 3u * 304u + 1000u * 20u);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 8), "HWRFN001");
  EXPECT_EQ(get<uint32_t>(b, 8), 1u);
  EXPECT_EQ(get<uint32_t>(b, 12), 48u);
  EXPECT_EQ(get<uint32_t>(b, 16), 20u);
  EXPECT_EQ(get<uint32_t>(b, 20), 3u);
  EXPECT_EQ(get<uint64_t>(b, 24), 1000u);
  EXPECT_EQ(get<uint64_t>(b, 32), b.size() - 48);
  EXPECT_EQ(get<uint32_t>(b, 40), reference_crc32(b.data() + 48, b.size() - 48));
  EXPECT_EQ(get<uint32_t>(b, 44), reference_crc32(b.data(), 44));
  const size_t r1 = 48 + 304;  // region 1's record
  EXPECT_EQ(get<uint32_t>(b, r1), seg.weld_regions[1].region.id);
  EXPECT_EQ(b[r1 + 4], static_cast<uint8_t>(WeldRegionSource::kOperator));
  EXPECT_EQ(b[r1 + 5] | b[r1 + 6] | b[r1 + 7], 0) << "explicit zero padding";
  EXPECT_EQ(get<int32_t>(b, r1 + 44), seg.weld_regions[1].region.keyframe_id);
  EXPECT_TRUE(same_bits(get<double>(b, r1 + 56 + 8 * 3), seg.weld_regions[1].region.T_cam_region(0, 3)));
  EXPECT_TRUE(same_bits(get<double>(b, r1 + 176 + 8 * 11), seg.weld_regions[1].T_segment_region(2, 3)));
  EXPECT_EQ(get<int64_t>(b, r1 + 272), seg.weld_regions[1].fine_points);
  const size_t p7 = 48 + 3 * 304 + 7 * 20;  // fine point 7
  EXPECT_TRUE(same_bits(get<float>(b, p7 + 4), seg.fine_points_segment[7].y_m));
  EXPECT_EQ(get<uint32_t>(b, p7 + 16), seg.fine_counts[7]);
  const std::string yaml = read_text(d + "/segment.yaml");
  const std::vector<std::string> lines = {
      "weld_regions: 3\n", "fine_points: 1000\n", "fine_bin_bytes: " + std::to_string(b.size()) + "\n",
      "fine_bin_crc32: " + std::to_string(get<uint32_t>(b, 40)) + "\n", "format_version: 2\n"};
  for (const std::string& line : lines) {
    EXPECT_NE(yaml.find(line), std::string::npos) << line << " not in\n" << yaml;
  }

  // The index: fine_voxel_m from segment.yaml, fine.bin never opened (it reads without it).
  auto index = store->read_keyframes(5);
  ASSERT_TRUE(index.ok()) << index.status().to_string();
  EXPECT_TRUE(same_bits(index->fine_voxel_m, seg.fine_voxel_m));
  EXPECT_TRUE(index->weld_regions.empty());
  EXPECT_TRUE(index->fine_points_segment.empty());
  EXPECT_TRUE(index->fine_counts.empty());
  auto list = store->list_segments();
  ASSERT_TRUE(list.ok()) << list.status().to_string();
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ((*list)[0].bytes, fs::file_size(d + "/segment.yaml") + fs::file_size(d + "/keyframes.bin") +
                                  fs::file_size(d + "/cloud.bin") + b.size());
  fs::remove(d + "/fine.bin");
  EXPECT_TRUE(store->read_keyframes(5).ok()) << "read_keyframes must not open fine.bin";

  // The prior map's cloud read: cloud.bin alone, neither fine.bin nor keyframes.bin opened.
  fs::remove(d + "/keyframes.bin");
  auto cloud = store->read_cloud(5);
  ASSERT_TRUE(cloud.ok()) << cloud.status().to_string();
  EXPECT_EQ(cloud->points_segment.size(), seg.points_segment.size());
  EXPECT_TRUE(cloud->keyframes.empty());
  EXPECT_TRUE(cloud->fine_points_segment.empty());
  EXPECT_TRUE(cloud->weld_regions.empty());
  EXPECT_FALSE(store->read_segment(5).ok());  // the whole segment needs both
}

TEST(MapStore, GivenASegmentWithoutFineDataWhenReadBackThenTheFineVectorsAreEmpty) {
  TempDir tmp;
  const SegmentRecord seg = make_segment(2, 2, 300);
  ASSERT_TRUE(seg.weld_regions.empty() && seg.fine_points_segment.empty());
  {
    MapStore store = open_store(tmp.store());
    ASSERT_TRUE(store.write_segment(seg).ok());
  }
  // Regions without fine points are kept too (and fine_voxel_m without points).
  SegmentRecord regions_only = make_segment(3, 1, 10);
  add_fine_data(&regions_only, 2, 0);
  {
    MapStore store = open_store(tmp.store());
    ASSERT_TRUE(store.write_segment(regions_only).ok());
  }
  auto store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(store.ok());
  auto back = store->read_segment(2);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(first_difference(seg, *back), "");
  EXPECT_TRUE(back->weld_regions.empty());
  EXPECT_TRUE(back->fine_points_segment.empty());
  EXPECT_TRUE(back->fine_counts.empty());
  EXPECT_TRUE(same_bits(back->fine_voxel_m, 0.0));
  EXPECT_EQ(fs::file_size(segment_dir(tmp.store(), 2) + "/fine.bin"), 48u) << "always written";
  auto back3 = store->read_segment(3);
  ASSERT_TRUE(back3.ok()) << back3.status().to_string();
  EXPECT_EQ(first_difference(regions_only, *back3), "");
  EXPECT_EQ(back3->weld_regions.size(), 2u);
}

TEST(MapStore, GivenAFormat1SegmentWithoutFineBinThenItReadsWithEmptyFineData) {
  TempDir tmp;
  SegmentRecord seg = make_segment(3, 2, 400);
  {
    MapStore store = open_store(tmp.store());
    SegmentRecord with_fine = seg;
    add_fine_data(&with_fine, 2, 100);
    ASSERT_TRUE(store.write_segment(with_fine).ok());
  }
  // What the format-1 writer wrote: no fine keys, format_version 1, no fine.bin.
  const std::string d = segment_dir(tmp.store(), 3);
  const std::string yaml = d + "/segment.yaml";
  const std::string v2_text = read_text(yaml);
  fs::remove(d + "/fine.bin");
  rewrite_segment_yaml(yaml, [](std::string* body) {
    set_yaml_value(body, "format_version", "1");
    for (const char* key :
         {"fine_voxel_m", "weld_regions", "fine_points", "fine_bin_bytes", "fine_bin_crc32"})
      remove_yaml_line(body, key);
  });
  const std::string v1_text = read_text(yaml);
  ASSERT_EQ(v1_text.find("fine"), std::string::npos) << v1_text;
  auto store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(store.ok());
  auto back = store->read_segment(3);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(first_difference(seg, *back), "") << "a format-1 segment: everything but the fine data";
  EXPECT_TRUE(back->weld_regions.empty() && back->fine_points_segment.empty() && back->fine_counts.empty());
  EXPECT_TRUE(same_bits(back->fine_voxel_m, 0.0));
  auto index = store->read_keyframes(3);
  ASSERT_TRUE(index.ok()) << index.status().to_string();
  EXPECT_TRUE(same_bits(index->fine_voxel_m, 0.0));
  auto list = store->list_segments();
  ASSERT_TRUE(list.ok()) << list.status().to_string();
  EXPECT_EQ((*list)[0].bytes,
            fs::file_size(yaml) + fs::file_size(d + "/keyframes.bin") + fs::file_size(d + "/cloud.bin"));

  // Format 1 with a fine key, format 2 without one: malformed (kParseError naming the key).
  rewrite_segment_yaml(yaml, [](std::string* body) { body->append("fine_points: 0\n"); });
  core::Status st = store->read_segment(3).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << st.to_string();
  EXPECT_NE(st.message().find("fine_points"), std::string::npos) << st.message();
  write_text(yaml, v2_text);
  rewrite_segment_yaml(yaml, [](std::string* body) { remove_yaml_line(body, "fine_bin_crc32"); });
  st = store->read_keyframes(3).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << st.to_string();
  EXPECT_NE(st.message().find("fine_bin_crc32"), std::string::npos) << st.message();
  // Newer than this build: refused as before.
  write_text(yaml, v2_text);
  rewrite_segment_yaml(yaml, [](std::string* body) { set_yaml_value(body, "format_version", "3"); });
  st = store->read_segment(3).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument) << st.to_string();
  EXPECT_NE(st.message().find("newer"), std::string::npos) << st.message();
}

TEST(MapStore, GivenAStoreCreatedAtFormat1ThenItOpensKeepsItsStoreYamlAndTakesFormat2Segments) {
  TempDir tmp;
  ASSERT_TRUE(store_with_one_segment(tmp).size() > 0);
  const std::string store_yaml = tmp.store() + "/store.yaml";
  std::string text = read_text(store_yaml);
  ASSERT_NE(text.find("format_version: 2\n"), std::string::npos) << text;
  text.replace(text.find("format_version: 2\n"), 17, "format_version: 1");
  write_text(store_yaml, text);

  SegmentRecord seg = make_segment(1, 2, 100);
  add_fine_data(&seg, 3, 200);
  {
    auto store = MapStore::open(tmp.store(), test_metadata());
    ASSERT_TRUE(store.ok()) << store.status().to_string();
    EXPECT_EQ(store->metadata().format_version, 1u);
    ASSERT_TRUE(store->write_segment(seg).ok());
  }
  EXPECT_EQ(read_text(store_yaml), text) << "store.yaml is written once";
  auto store = MapStore::open_existing(tmp.store());
  ASSERT_TRUE(store.ok()) << store.status().to_string();
  EXPECT_EQ(store->metadata().format_version, 1u);
  auto back = store->read_segment(1);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(first_difference(seg, *back), "");
  EXPECT_NE(read_text(segment_dir(tmp.store(), 1) + "/segment.yaml").find("format_version: 2\n"),
            std::string::npos);
  EXPECT_TRUE(store->read_segment(0).ok());

  // New stores: created at format 2 whatever older format the argument asks, unless it asks for newer.
  StoreMetadata old_default = test_metadata();
  old_default.format_version = 1;
  auto created = MapStore::open(tmp.path() + "/new_store", old_default);
  ASSERT_TRUE(created.ok()) << created.status().to_string();
  EXPECT_EQ(created->metadata().format_version, 2u);
  EXPECT_NE(read_text(tmp.path() + "/new_store/store.yaml").find("format_version: 2\n"), std::string::npos);
  StoreMetadata newer = test_metadata();
  newer.format_version = 3;
  EXPECT_EQ(MapStore::open(tmp.path() + "/newer_store", newer).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(tmp.path() + "/newer_store/store.yaml"));
}

TEST(MapStore, GivenADamagedOrMissingFineBinThenReadIsCorruptDataNamingIt) {
  // Truncated: segment.yaml's fine_bin_bytes catches it before the header is read.
  for (uint64_t keep : {0ull, 20ull, 48ull, 48ull + 304ull, 1ull << 40}) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/fine.bin";
    const uint64_t size = fs::file_size(path);
    fs::resize_file(path, keep == (1ull << 40) ? size - 1 : keep);
    SCOPED_TRACE("kept " + std::to_string(fs::file_size(path)) + " of " + std::to_string(size) + " bytes");
    expect_corrupt_naming(dir, 0, "fine.bin", "truncated");
  }
  // One flipped byte: in a region record, in a fine point, in a count, in the header.
  struct Flip {
    size_t offset;
    const char* saying;
  };
  for (const Flip& f :
       {Flip{48 + 304 + 100, "payload CRC32"}, Flip{48 + 3 * 304 + 555, "payload CRC32"},
        Flip{48 + 3 * 304 + 20 * 999 + 17, "payload CRC32"}, Flip{20, "header CRC32"}, Flip{2, "magic"}}) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/fine.bin";
    std::vector<uint8_t> b = read_bytes(path);
    b[f.offset] ^= 0x04;
    write_bytes(path, b);
    SCOPED_TRACE("byte " + std::to_string(f.offset));
    expect_corrupt_naming(dir, 0, "fine.bin", f.saying);
  }
  // Counts that disagree with segment.yaml (which is resealed: only the comparison can tell).
  for (const char* key : {"fine_points", "weld_regions"}) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    rewrite_segment_yaml(segment_dir(dir, 0) + "/segment.yaml",
                         [&](std::string* body) { set_yaml_value(body, key, key[0] == 'f' ? "999" : "4"); });
    SCOPED_TRACE(key);
    expect_corrupt_naming(dir, 0, "fine.bin", "segment.yaml says");
  }
  // A header whose counts or point size do not fit its payload (header CRC resealed).
  struct HeaderEdit {
    size_t offset;
    uint64_t value;
    int bytes;
    const char* saying;
  };
  for (const HeaderEdit& e :
       {HeaderEdit{16, 16, 4, "bytes per fine point"}, HeaderEdit{20, 4, 4, "header counts"},
        HeaderEdit{24, 1001, 8, "header counts"}, HeaderEdit{8, 2, 4, "version"}}) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/fine.bin";
    std::vector<uint8_t> b = read_bytes(path);
    if (e.bytes == 4)
      put<uint32_t>(&b, e.offset, static_cast<uint32_t>(e.value));
    else
      put<uint64_t>(&b, e.offset, e.value);
    reseal_header(&b);
    write_bytes(path, b);
    SCOPED_TRACE("header offset " + std::to_string(e.offset));
    expect_corrupt_naming(dir, 0, "fine.bin", e.saying);
  }
  // A format-2 segment without its fine.bin.
  TempDir tmp;
  const std::string dir = store_with_fine_segment(tmp);
  fs::remove(segment_dir(dir, 0) + "/fine.bin");
  expect_corrupt_naming(dir, 0, "fine.bin", "missing");
}

TEST(MapStore, GivenAFineBinHeaderClaimingHugeCountsThenCorruptDataWithoutAllocatingThem) {
  // 1e9 fine points (20 GB), with the payload size claimed to match or not; 2^32-1 regions
  // (1.2 TB) with the payload size of the real file.
  struct Claim {
    uint32_t regions;
    uint64_t points;
    bool matching_payload;
  };
  for (const Claim& c : {Claim{3, 1'000'000'000ull, true}, Claim{3, 1'000'000'000ull, false},
                         Claim{0xFFFFFFFFu, 1000, false}}) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    const std::string path = segment_dir(dir, 0) + "/fine.bin";
    std::vector<uint8_t> b = read_bytes(path);
    put<uint32_t>(&b, 20, c.regions);
    put<uint64_t>(&b, 24, c.points);
    if (c.matching_payload) put<uint64_t>(&b, 32, uint64_t{c.regions} * 304 + c.points * 20);
    reseal_header(&b);
    write_bytes(path, b);
    auto store = MapStore::open_existing(dir);
    ASSERT_TRUE(store.ok());
    core::AllocationScope scope;
    auto seg = store->read_segment(0);
    const uint64_t bytes = scope.bytes();
    ASSERT_FALSE(seg.ok());
    EXPECT_EQ(seg.status().code(), core::ErrorCode::kCorruptData) << seg.status().to_string();
    EXPECT_NE(seg.status().message().find("fine.bin"), std::string::npos) << seg.status().message();
    EXPECT_LT(bytes, 1u << 20) << "allocated " << bytes << " bytes for a file that claims " << c.points
                               << " fine points and " << c.regions << " regions";
  }
}

TEST(MapStore, GivenAFineBinRecordWithValidCrcsButInvalidContentThenReadIsCorruptDataNamingIt) {
  constexpr size_t kRegion1 = 48 + 304;              // region 1's record
  constexpr size_t kPoint5 = 48 + 3 * 304 + 5 * 20;  // fine point 5
  struct Edit {
    const char* saying;
    void (*apply)(std::vector<uint8_t>*);
  };
  const Edit edits[] = {
      {"source 4", [](std::vector<uint8_t>* b) { (*b)[kRegion1 + 4] = 4; }},
      {"source 255", [](std::vector<uint8_t>* b) { (*b)[kRegion1 + 4] = 255; }},
      {"padding", [](std::vector<uint8_t>* b) { (*b)[kRegion1 + 6] = 1; }},
      {"label", [](std::vector<uint8_t>* b) { std::memset(b->data() + kRegion1 + 12, 'x', 32); }},
      {"T_cam_region is not rigid", [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 56, 1.5); }},
      {"T_cam_region has a non-finite",
       [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 56 + 8 * 7, NAN); }},
      {"T_segment_region is not rigid",
       [](std::vector<uint8_t>* b) {
         for (int i : {0, 1, 2})
           put<double>(b, kRegion1 + 176 + 8 * (4 * i + 2),
                       -get<double>(*b, kRegion1 + 176 + 8 * (4 * i + 2)));
       }},
      {"half_size_m", [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 152 + 8, 0.0); }},
      {"half_size_m", [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 152 + 16, -0.1); }},
      {"half_size_m", [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 152, INFINITY); }},
      {"fine_points is negative", [](std::vector<uint8_t>* b) { put<int64_t>(b, kRegion1 + 272, -1); }},
      {"viewpoint_segment is not finite",
       [](std::vector<uint8_t>* b) { put<double>(b, kRegion1 + 288, NAN); }},
      {"fine point 5 has a non-finite coordinate",
       [](std::vector<uint8_t>* b) { put<float>(b, kPoint5 + 8, NAN); }},
      {"fine point 5 has count 0", [](std::vector<uint8_t>* b) { put<uint32_t>(b, kPoint5 + 16, 0); }},
  };
  for (const Edit& e : edits) {
    TempDir tmp;
    const std::string dir = store_with_fine_segment(tmp);
    std::vector<uint8_t> b = read_bytes(segment_dir(dir, 0) + "/fine.bin");
    e.apply(&b);
    reseal_fine(dir, 0, &b);
    SCOPED_TRACE(e.saying);
    expect_corrupt_naming(dir, 0, "fine.bin", e.saying);
    if (std::string(e.saying).rfind("fine point", 0) != 0) {
      expect_corrupt_naming(dir, 0, "fine.bin", "weld region 1 (id 1)");
    }
  }
  // Fine points with segment.yaml's fine_voxel_m 0 (resealed): refused naming fine.bin; a negative
  // one is a malformed segment.yaml.
  TempDir tmp;
  const std::string dir = store_with_fine_segment(tmp);
  const std::string yaml = segment_dir(dir, 0) + "/segment.yaml";
  const std::string good = read_text(yaml);
  rewrite_segment_yaml(yaml, [](std::string* body) { set_yaml_value(body, "fine_voxel_m", "0"); });
  expect_corrupt_naming(dir, 0, "fine.bin", "fine_voxel_m");
  write_text(yaml, good);
  rewrite_segment_yaml(yaml, [](std::string* body) { set_yaml_value(body, "fine_voxel_m", "-0.002"); });
  auto store = MapStore::open_existing(dir);
  ASSERT_TRUE(store.ok());
  const core::Status st = store->read_segment(0).status();
  EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << st.to_string();
  EXPECT_NE(st.message().find("fine_voxel_m"), std::string::npos) << st.message();
  // With no fine points, fine_voxel_m 0 is what "no fine cloud" writes.
  TempDir tmp0;
  const std::string dir0 = store_with_fine_segment(tmp0, 0);
  rewrite_segment_yaml(segment_dir(dir0, 0) + "/segment.yaml",
                       [](std::string* body) { set_yaml_value(body, "fine_voxel_m", "0"); });
  auto store0 = MapStore::open_existing(dir0);
  ASSERT_TRUE(store0.ok());
  EXPECT_TRUE(store0->read_segment(0).ok());
}

TEST(MapStore, GivenABadFineRecordThenWriteIsInvalidArgumentAndWritesNothing) {
  struct Case {
    const char* saying;
    void (*apply)(SegmentRecord*);
  };
  const Case cases[] = {
      {"fine_counts has 99 entries for 100 fine points", [](SegmentRecord* s) { s->fine_counts.pop_back(); }},
      {"fine_counts has 101 entries", [](SegmentRecord* s) { s->fine_counts.push_back(1); }},
      {"weld region 1 (id 9001): T_cam_region is not rigid",
       [](SegmentRecord* s) { s->weld_regions[1].region.T_cam_region.linear() *= 1.001; }},
      {"weld region 2 (id 9002): T_segment_region is not rigid: det R = -1",
       [](SegmentRecord* s) { s->weld_regions[2].T_segment_region.linear().col(2) *= -1.0; }},
      {"T_cam_region has a non-finite entry",
       [](SegmentRecord* s) { s->weld_regions[0].region.T_cam_region.translation().y() = NAN; }},
      {"weld region 0 (id 9000): label is not NUL-terminated",
       [](SegmentRecord* s) { s->weld_regions[0].region.label.fill('x'); }},
      {"source 4 is not a WeldRegionSource",
       [](SegmentRecord* s) { s->weld_regions[1].region.source = static_cast<WeldRegionSource>(4); }},
      {"half_size_m", [](SegmentRecord* s) { s->weld_regions[1].region.half_size_m.y() = 0; }},
      {"half_size_m", [](SegmentRecord* s) { s->weld_regions[1].region.half_size_m.z() = NAN; }},
      {"fine_points is negative", [](SegmentRecord* s) { s->weld_regions[2].fine_points = -3; }},
      {"viewpoint_segment is not finite",
       [](SegmentRecord* s) { s->weld_regions[0].viewpoint_segment.x() = INFINITY; }},
      {"fine point 7 has a non-finite coordinate",
       [](SegmentRecord* s) { s->fine_points_segment[7].x_m = INFINITY; }},
      {"fine point 8 has count 0", [](SegmentRecord* s) { s->fine_counts[8] = 0; }},
      {"fine points need fine_voxel_m > 0", [](SegmentRecord* s) { s->fine_voxel_m = 0; }},
      {"fine_voxel_m must be finite and >= 0",
       [](SegmentRecord* s) {
         s->fine_points_segment.clear();
         s->fine_counts.clear();
         s->fine_voxel_m = -1;
       }},
      {"fine_voxel_m must be finite and >= 0", [](SegmentRecord* s) { s->fine_voxel_m = NAN; }},
  };
  TempDir tmp;
  MapStore store = open_store(tmp.store());
  for (const Case& c : cases) {
    SCOPED_TRACE(c.saying);
    SegmentRecord seg = make_segment(9, 2, 50);
    add_fine_data(&seg, 3, 100);
    c.apply(&seg);
    const core::Status st = store.write_segment(seg);
    EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument) << st.to_string();
    EXPECT_NE(st.message().find("segment 9"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find(c.saying), std::string::npos) << st.message();
    EXPECT_EQ(segment_entries(tmp.store()), 0u) << "a refused write must leave nothing behind";
  }
  // The same record, valid, is written.
  SegmentRecord seg = make_segment(9, 2, 50);
  add_fine_data(&seg, 3, 100);
  ASSERT_TRUE(store.write_segment(seg).ok());
  EXPECT_EQ(segment_entries(tmp.store()), 1u);
}

// The crash test's writer: segment sizes vary with the id (0-3 keyframes, 0-30k points; two of
// three segments with 0-3 weld regions and 0-5k fine points).
SegmentRecord crash_segment(uint32_t id) {
  const uint32_t h = id * 2654435761u;
  SegmentRecord s = make_segment(id, static_cast<int>(h % 4), static_cast<int>((h >> 8) % 30000));
  if (h % 3 != 0) add_fine_data(&s, static_cast<int>((h >> 4) % 4), static_cast<int>((h >> 12) % 5000));
  return s;
}

[[noreturn]] void crash_child(const std::string& dir) {
  auto store = MapStore::open(dir, test_metadata());
  if (!store.ok()) _exit(2);
  auto list = store->list_segments();
  if (!list.ok()) _exit(3);
  for (uint32_t id = static_cast<uint32_t>(list->size()); id < 100000; ++id) {
    if (!store->write_segment(crash_segment(id)).ok()) _exit(4);
  }
  _exit(0);
}

TEST(MapStore, GivenAWriterKilledAtRandomMomentsThenTheStoreLoadsWithAPrefixOfItsSegments) {
  TempDir tmp;
  const std::string dir = tmp.store();
  std::mt19937 rng(20261124);
  std::uniform_int_distribution<int> delay_ms(5, 150);
  constexpr int kRounds = 20;  // about half the kills land inside a segment write
  size_t previous = 0;
  int interrupted_writes = 0;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const int delay = delay_ms(rng);
    hwr::test::kill_writer_after(delay, [&] { crash_child(dir); });
    if (::testing::Test::HasFatalFailure()) return;

    if (fs::exists(dir + "/segments")) {
      for (const auto& e : fs::directory_iterator(dir + "/segments")) {
        if (e.path().filename().string().rfind(".tmp-", 0) == 0) ++interrupted_writes;
      }
    }
    auto store = MapStore::open(dir, test_metadata());
    ASSERT_TRUE(store.ok()) << store.status().to_string();
    for (const auto& e : fs::directory_iterator(dir + "/segments")) {
      EXPECT_NE(e.path().filename().string().rfind(".tmp-", 0), 0u) << "left after open(): " << e.path();
    }
    auto list = store->list_segments();
    ASSERT_TRUE(list.ok()) << list.status().to_string();
    ASSERT_GE(list->size(), previous) << "segments disappeared";
    for (size_t i = 0; i < list->size(); ++i) {
      const SegmentSummary& s = (*list)[i];
      ASSERT_EQ(s.segment_id, i) << "ids are not a prefix 0..k-1";
      if (i < previous && round != kRounds - 1)
        continue;  // checked in an earlier round; all again at the end
      auto seg = store->read_segment(s.segment_id);
      ASSERT_TRUE(seg.ok()) << seg.status().to_string();
      ASSERT_EQ(first_difference(crash_segment(s.segment_id), *seg), "") << "segment " << s.segment_id;
    }
    previous = list->size();
  }
  std::printf("[ crash    ] %d kills: %zu complete segments, %d writes interrupted mid-segment\n", kRounds,
              previous, interrupted_writes);
  EXPECT_GT(previous, 0u) << "the writer never completed a segment: the test checked nothing";
  EXPECT_GT(interrupted_writes, 0) << "no kill landed inside a segment write: the test checked nothing";
}

}  // namespace
}  // namespace hwr::recon
