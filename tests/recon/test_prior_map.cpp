// The lazily loaded prior map (issue #6 item 1). A small store of three segments, far apart, is
// written with MapStore and opened as a prior map. Oracles: the keyframes come back with their
// poses, descriptors and eq. 3 back-projections (recomputed here in double from the stored u, v,
// depth); no cloud is read at open; points_near returns exactly the points a brute-force search
// over every segment (moved to the prior frame with T_world_segment here) finds in the ball; a
// point budget evicts the least-recently-used cloud no query needs (a cloud read for its estimated
// box and found far is not needed) and skips what does not fit; thinned clouds hold, per occupied
// voxel of the segment frame, the mean of its stored points (computed here in double) moved to the
// prior frame; preload_clouds reads clouds in segment order until the budget is full; a damaged keyframes.bin
// fails open() with kCorruptData naming the file, a damaged cloud.bin is skipped (counted, never read again)
// while the other segments answer, a missing store is kNotFound naming the path, and a prior with more
// features than max_prior_features is refused (kOutOfRange).

#include <unistd.h>

#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "temp_dir.hpp"
#include "hwr/estimation/descriptor.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/prior_map.hpp"

namespace hwr::recon {
namespace {

namespace fs = std::filesystem;

struct TempDir : hwr::testing::TempDir {
  TempDir() : hwr::testing::TempDir("hwr_prior_map") {}
};

StoreMetadata metadata() {
  StoreMetadata m;
  m.run_id = "prior-test";
  m.intrinsics.width = 640;
  m.intrinsics.height = 480;
  m.intrinsics.fx = 525;
  m.intrinsics.fy = 520;
  m.intrinsics.cx = 319.5;
  m.intrinsics.cy = 239.5;
  return m;
}

constexpr int kSegments = 3;
constexpr int kPointsPerSegment = 2000;
constexpr int kKeyframesPerSegment = 2;
constexpr int kFeaturesPerKeyframe = 50;

Eigen::Isometry3d segment_pose(int k) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.3 + 0.7 * k, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
               Eigen::AngleAxisd(0.05 * k, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(30.0 * k, -5.0 + 2.0 * k, 0.5 * k);
  return T;
}

// Segments 30 m apart, each a cloud of points within 2 m of its origin and two keyframes near it.
std::vector<SegmentRecord> make_segments() {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(-1.f, 1.f);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<SegmentRecord> out;
  for (int k = 0; k < kSegments; ++k) {
    SegmentRecord s;
    s.segment_id = static_cast<uint32_t>(k);
    s.T_world_segment = segment_pose(k);
    for (int i = 0; i < kPointsPerSegment; ++i) {
      CloudPoint p;
      p.x_m = 2.f * unit(rng);
      p.y_m = 2.f * unit(rng);
      p.z_m = 2.f * unit(rng);
      p.r = static_cast<uint8_t>(k);
      p.g = static_cast<uint8_t>(i >> 8);
      p.b = static_cast<uint8_t>(i & 0xff);
      s.points_segment.push_back(p);
    }
    for (int j = 0; j < kKeyframesPerSegment; ++j) {
      StoredKeyframe kf;
      kf.id = k * kKeyframesPerSegment + j;
      kf.t_ns = 1000 + kf.id;
      kf.T_world_cam = s.T_world_segment;
      kf.T_world_cam.translation() += Eigen::Vector3d(0.5 * j, 0.1 * j, 0.0);
      kf.gnss_valid = j == 0;
      kf.lat_deg = 48.1 + k;
      kf.lon_deg = 11.5;
      kf.alt_m = 500;
      kf.mag_valid = true;
      kf.mag_imu_uT = Eigen::Vector3d(20, 1, -43);
      for (int f = 0; f < kFeaturesPerKeyframe; ++f) {
        StoredFeature sf;
        sf.u_px = 10.f + 12.3f * f;
        sf.v_px = 20.f + 8.1f * f;
        sf.depth_m = f % 5 == 0 ? 0.f : 0.5f + 0.07f * f;
        sf.octave = static_cast<uint8_t>(f % 4);
        kf.features.push_back(sf);
        for (int b = 0; b < estimation::kOrbDescriptorBytes; ++b) {
          kf.descriptors.push_back(static_cast<uint8_t>(byte(rng)));
        }
      }
      s.keyframes.push_back(kf);
    }
    out.push_back(std::move(s));
  }
  return out;
}

// Every stored point as it is (no thinning): the ball tests compare point identities.
PriorMapConfig exact_config() {
  PriorMapConfig c;
  c.cloud_voxel_m = 0;
  return c;
}

void write_store(const std::string& dir, const std::vector<SegmentRecord>& segments) {
  auto store = MapStore::open(dir, metadata());
  ASSERT_TRUE(store.ok()) << store.status().message();
  for (const SegmentRecord& s : segments) ASSERT_TRUE(store->write_segment(s).ok());
}

// A point's identity travels in its colour: r = segment, (g, b) = index in the segment.
int point_id(const CloudPoint& p) { return (p.r << 16) | (p.g << 8) | p.b; }

// Brute force over every segment, moved to the prior frame here in double: the ids of the points
// within radius_m of c, those within radius_m - 1e-4 (must be returned) and radius_m + 1e-4 (may be:
// float and double disagree on the sphere itself), and every point's prior-frame position.
struct BallOracle {
  std::vector<int> inner, outer;
  std::vector<Eigen::Vector3d> p_prior;  // by id
};
BallOracle expected_near(const std::vector<SegmentRecord>& segments, const Eigen::Vector3d& c,
                         double radius_m) {
  BallOracle e;
  e.p_prior.resize(static_cast<size_t>(kSegments) << 16);
  for (const SegmentRecord& s : segments) {
    for (const CloudPoint& p : s.points_segment) {
      const Eigen::Vector3d q = s.T_world_segment * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
      e.p_prior[static_cast<size_t>(point_id(p))] = q;
      const double d = (q - c).norm();
      if (d <= radius_m - 1e-4) e.inner.push_back(point_id(p));
      if (d <= radius_m + 1e-4) e.outer.push_back(point_id(p));
    }
  }
  std::sort(e.inner.begin(), e.inner.end());
  std::sort(e.outer.begin(), e.outer.end());
  return e;
}

void expect_same_points(const BallOracle& e, const std::vector<CloudPoint>& got) {
  std::vector<int> ids;
  double worst_m = 0;
  for (const CloudPoint& p : got) {
    ids.push_back(point_id(p));
    const Eigen::Vector3d& q = e.p_prior[static_cast<size_t>(point_id(p))];
    worst_m = std::max(worst_m, (Eigen::Vector3d(p.x_m, p.y_m, p.z_m) - q).norm());
  }
  std::sort(ids.begin(), ids.end());
  EXPECT_TRUE(std::adjacent_find(ids.begin(), ids.end()) == ids.end()) << "a point returned twice";
  EXPECT_TRUE(std::includes(ids.begin(), ids.end(), e.inner.begin(), e.inner.end()))
      << "a point inside the ball is missing";
  EXPECT_TRUE(std::includes(e.outer.begin(), e.outer.end(), ids.begin(), ids.end()))
      << "a point outside the ball was returned";
  EXPECT_LT(worst_m, 1e-4) << "prior-frame position vs T_world_segment * p in double";
}

void flip_byte(const std::string& path, size_t offset) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  ASSERT_TRUE(f.good()) << path;
  f.seekg(static_cast<std::streamoff>(offset));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x5a);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(&c, 1);
}

TEST(PriorMap, GivenAStoreWhenOpenedThenKeyframesAreIndexedAndNoCloudIsRead) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  auto map = PriorMap::open(tmp.file("store"));
  ASSERT_TRUE(map.ok()) << map.status().message();
  EXPECT_EQ(map->counters().cloud_loads, 0u);
  EXPECT_EQ(map->counters().loaded_points, 0);
  ASSERT_EQ(map->segments().size(), static_cast<size_t>(kSegments));
  ASSERT_EQ(map->keyframes().size(), static_cast<size_t>(kSegments * kKeyframesPerSegment));
  const hal::PinholeIntrinsics K = metadata().intrinsics;
  for (int k = 0; k < kSegments; ++k) {
    const PriorSegment& s = map->segments()[static_cast<size_t>(k)];
    EXPECT_EQ(s.segment_id, static_cast<uint32_t>(k));
    EXPECT_TRUE(s.T_prior_segment.isApprox(segment_pose(k), 0.0));
    EXPECT_EQ(s.points, kPointsPerSegment);
    EXPECT_FALSE(s.loaded);
    EXPECT_EQ(s.first_keyframe, k * kKeyframesPerSegment);
    EXPECT_EQ(s.keyframe_count, kKeyframesPerSegment);
    for (int j = 0; j < kKeyframesPerSegment; ++j) {
      const StoredKeyframe& in = segments[static_cast<size_t>(k)].keyframes[static_cast<size_t>(j)];
      const PriorKeyframe& kf = map->keyframes()[static_cast<size_t>(k * kKeyframesPerSegment + j)];
      EXPECT_TRUE(s.keyframe_box_prior.contains(in.T_world_cam.translation()));
      EXPECT_EQ(kf.segment_id, static_cast<uint32_t>(k));
      EXPECT_EQ(kf.id, in.id);
      EXPECT_EQ(kf.t_ns, in.t_ns);
      EXPECT_TRUE(kf.T_prior_cam.isApprox(in.T_world_cam, 0.0));
      EXPECT_EQ(kf.gnss_valid, in.gnss_valid);
      EXPECT_EQ(kf.lat_deg, in.lat_deg);
      EXPECT_TRUE(kf.mag_imu_uT.isApprox(in.mag_imu_uT, 0.0));
      ASSERT_EQ(kf.features.size(), kFeaturesPerKeyframe);
      for (int f = 0; f < kFeaturesPerKeyframe; ++f) {
        const StoredFeature& sf = in.features[static_cast<size_t>(f)];
        const estimation::Feature& e = kf.features.feature(f);
        EXPECT_EQ(e.u_px, sf.u_px);
        EXPECT_EQ(e.octave, sf.octave);
        EXPECT_EQ(e.depth_m, sf.depth_m);
        // Eq. (3) in double, from the stored floats.
        const Eigen::Vector3d p_expected =
            sf.depth_m > 0 ? Eigen::Vector3d((sf.u_px - K.cx) * sf.depth_m / K.fx,
                                             (sf.v_px - K.cy) * sf.depth_m / K.fy, sf.depth_m)
                           : Eigen::Vector3d::Zero();
        EXPECT_LT((e.p_cam_m - p_expected).norm(), 1e-9);
        EXPECT_TRUE(std::equal(kf.features.descriptor(f), kf.features.descriptor(f) + 32,
                               in.descriptors.begin() + 32 * f));
      }
    }
  }
}

TEST(PriorMap, GivenAPositionWhenPointsNearThenExactlyThePointsOfTheBallInThePriorFrame) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  PriorMapConfig config = exact_config();
  config.cloud_reach_m = 2.5;  // the synthetic clouds lie within 2 sqrt(3) m of the keyframes
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  std::vector<CloudPoint> out;

  // The whole of segment 1 (its cloud is within 3.5 m of its origin) and nothing else.
  const Eigen::Vector3d c1 = segment_pose(1).translation();
  auto st = map->points_near(c1, 5.0, &out);
  ASSERT_TRUE(st.ok()) << st.status().message();
  EXPECT_EQ(st->segments_used, 1);
  EXPECT_EQ(out.size(), static_cast<size_t>(kPointsPerSegment));
  expect_same_points(expected_near(segments, c1, 5.0), out);
  for (const CloudPoint& p : out) EXPECT_EQ(p.r, 1);  // colour travels with the point
  EXPECT_EQ(map->counters().cloud_loads, 1u);
  EXPECT_TRUE(map->segments()[1].loaded);
  EXPECT_FALSE(map->segments()[0].loaded);

  // Part of segment 2's cloud: a ball of 1.5 m about a point 1 m off its origin.
  const Eigen::Vector3d c2 = segment_pose(2) * Eigen::Vector3d(1.0, 0.3, -0.2);
  st = map->points_near(c2, 1.5, &out);
  ASSERT_TRUE(st.ok());
  const BallOracle e2 = expected_near(segments, c2, 1.5);
  EXPECT_GT(e2.inner.size(), 100u);
  EXPECT_LT(e2.outer.size(), static_cast<size_t>(kPointsPerSegment));
  expect_same_points(e2, out);

  // Again: served from memory.
  st = map->points_near(c2, 1.5, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(map->counters().cloud_loads, 2u);
  EXPECT_EQ(map->counters().cloud_evictions, 0u);

  // Far from everything: nothing, nothing loaded.
  st = map->points_near(Eigen::Vector3d(15.0, 40.0, 0.0), 3.0, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(st->segments_near, 0);
  EXPECT_EQ(map->counters().cloud_loads, 2u);

  // Bad arguments.
  EXPECT_EQ(map->points_near(c1, 0.0, &out).status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(map->points_near(Eigen::Vector3d(NAN, 0, 0), 1.0, &out).status().code(),
            core::ErrorCode::kInvalidArgument);
}

TEST(PriorMap, GivenABudgetOfOneSegmentThenTheLeastRecentlyUsedCloudIsEvicted) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  PriorMapConfig config = exact_config();
  config.cloud_reach_m = 2.5;
  config.max_loaded_points = kPointsPerSegment + kPointsPerSegment / 2;  // room for one cloud
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok());
  std::vector<CloudPoint> out;
  const Eigen::Vector3d c[3] = {segment_pose(0).translation(), segment_pose(1).translation(),
                                segment_pose(2).translation()};
  ASSERT_TRUE(map->points_near(c[0], 4.0, &out).ok());
  ASSERT_TRUE(map->points_near(c[1], 4.0, &out).ok());
  EXPECT_EQ(map->counters().cloud_loads, 2u);
  EXPECT_EQ(map->counters().cloud_evictions, 1u);
  EXPECT_FALSE(map->segments()[0].loaded);
  EXPECT_TRUE(map->segments()[1].loaded);
  EXPECT_LE(map->counters().loaded_points, config.max_loaded_points);
  EXPECT_EQ(map->counters().loaded_segments, 1);
  expect_same_points(expected_near(segments, c[1], 4.0), out);
  // Segment 0 again: read again, segment 1 goes.
  ASSERT_TRUE(map->points_near(c[0], 4.0, &out).ok());
  EXPECT_EQ(map->counters().cloud_loads, 3u);
  EXPECT_EQ(map->counters().cloud_evictions, 2u);
  expect_same_points(expected_near(segments, c[0], 4.0), out);

  // A ball over segments 0 and 1 with room for one: the nearer one (0) is searched, 1 is skipped
  // and said so; the answer is partial, never points of a cloud that was not read.
  const Eigen::Vector3d between = c[0] + 0.2 * (c[1] - c[0]);
  const double radius = (c[1] - between).norm() + 0.5;
  auto st = map->points_near(between, radius, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(st->segments_near, 2);
  EXPECT_EQ(st->segments_used, 1);
  EXPECT_EQ(st->segments_over_budget, 1);
  std::vector<SegmentRecord> only0(segments.begin(), segments.begin() + 1);
  expect_same_points(expected_near(only0, between, radius), out);
  EXPECT_LE(map->counters().loaded_points, config.max_loaded_points);

  // With room for all three, the same ball gives both segments' points.
  PriorMapConfig big = config;
  big.max_loaded_points = 3 * kPointsPerSegment;
  auto map2 = PriorMap::open(tmp.file("store"), big);
  ASSERT_TRUE(map2.ok());
  st = map2->points_near(between, radius, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(st->segments_used, 2);
  expect_same_points(expected_near(segments, between, radius), out);
}

// The thinned cloud of segment k, by brute force: per occupied voxel of its frame (floor(p / voxel)),
// the mean of its points in double, moved to the prior frame.
std::vector<Eigen::Vector3d> thinned_prior(const SegmentRecord& s, double voxel_m) {
  std::map<std::array<long long, 3>, std::pair<Eigen::Vector3d, int>> voxels;
  for (const CloudPoint& p : s.points_segment) {
    const Eigen::Vector3d q(p.x_m, p.y_m, p.z_m);
    auto& v = voxels[{static_cast<long long>(std::floor(p.x_m / voxel_m)),
                      static_cast<long long>(std::floor(p.y_m / voxel_m)),
                      static_cast<long long>(std::floor(p.z_m / voxel_m))}];
    if (v.second == 0) v.first.setZero();
    v.first += q;
    ++v.second;
  }
  std::vector<Eigen::Vector3d> out;
  for (const auto& [key, v] : voxels) out.push_back(s.T_world_segment * (v.first / v.second));
  return out;
}

TEST(PriorMap, GivenAThinningVoxelThenEachCloudHoldsItsVoxelMeansAndPreloadFillsTheBudget) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  constexpr double kVoxel = 0.5;  // the 4 m cube of 2000 points: ~4 points per occupied voxel
  std::vector<std::vector<Eigen::Vector3d>> expected;
  for (const SegmentRecord& s : segments) expected.push_back(thinned_prior(s, kVoxel));
  ASSERT_LT(expected[0].size(), static_cast<size_t>(kPointsPerSegment) / 2);

  PriorMapConfig config;
  config.cloud_reach_m = 2.5;
  config.cloud_voxel_m = kVoxel;
  // Room for the first two thinned clouds, not the third.
  config.max_loaded_points = static_cast<int64_t>(expected[0].size() + expected[1].size());
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  const PreloadStats pre = map->preload_clouds();
  EXPECT_EQ(pre.segments_loaded, 2);
  EXPECT_EQ(pre.segments_in_memory, 2);
  EXPECT_EQ(pre.segments_over_budget, 1);
  EXPECT_EQ(pre.segments_unreadable, 0);
  EXPECT_EQ(pre.points_in_memory, config.max_loaded_points);
  EXPECT_TRUE(map->segments()[0].loaded);
  EXPECT_TRUE(map->segments()[1].loaded);
  EXPECT_FALSE(map->segments()[2].loaded);
  EXPECT_EQ(map->counters().cloud_evictions, 0u);
  EXPECT_EQ(map->counters().points_read, 3 * kPointsPerSegment);  // the third was read, then dropped
  const uint64_t loads = map->counters().cloud_loads;
  // Segment 2 is on disk: not every cloud is in memory; the clouds in memory are the thinned ones.
  EXPECT_FALSE(map->all_clouds_in_memory());
  EXPECT_EQ(map->cloud(0).size(), expected[0].size());
  EXPECT_TRUE(map->cloud(2).empty());
  uint64_t generation = map->cloud_generation();

  // Segment 1 whole: its voxel means, from memory.
  std::vector<CloudPoint> out;
  auto st = map->points_near(segment_pose(1).translation(), 5.0, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(map->counters().cloud_loads, loads);
  ASSERT_EQ(out.size(), expected[1].size());
  for (const CloudPoint& p : out) {
    const Eigen::Vector3d q(p.x_m, p.y_m, p.z_m);
    double nearest = 1e9;
    for (const Eigen::Vector3d& e : expected[1]) nearest = std::min(nearest, (e - q).norm());
    EXPECT_LT(nearest, 1e-4);
  }
  EXPECT_EQ(map->cloud_generation(), generation);  // served from memory: no cloud changed
  // Segment 2 needs room: read now, the least recently used preloaded cloud (segment 0) goes.
  st = map->points_near(segment_pose(2).translation(), 5.0, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(out.size(), expected[2].size());
  EXPECT_GT(map->cloud_generation(), generation);  // a structure built over the old clouds is stale
  EXPECT_TRUE(map->cloud(0).empty());
  EXPECT_FALSE(map->segments()[0].loaded);
  EXPECT_LE(map->counters().loaded_points, config.max_loaded_points);
  // A budget for all three: every cloud in memory after the preload.
  PriorMapConfig roomy = config;
  roomy.max_loaded_points = 3 * kPointsPerSegment;
  auto all = PriorMap::open(tmp.file("store"), roomy);
  ASSERT_TRUE(all.ok());
  EXPECT_FALSE(all->all_clouds_in_memory());
  EXPECT_EQ(all->preload_clouds().segments_in_memory, 3);
  EXPECT_TRUE(all->all_clouds_in_memory());

  // Without the preload, a cloud never read is read and thinned before the budget judges it: the
  // stored 2000 points would not fit a budget of the thinned count, the thinned cloud does.
  PriorMapConfig tight = config;
  tight.max_loaded_points = static_cast<int64_t>(expected[1].size());
  ASSERT_LT(tight.max_loaded_points, kPointsPerSegment);
  auto cold = PriorMap::open(tmp.file("store"), tight);
  ASSERT_TRUE(cold.ok());
  st = cold->points_near(segment_pose(1).translation(), 5.0, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(st->segments_used, 1);
  EXPECT_EQ(st->segments_over_budget, 0);
  EXPECT_EQ(out.size(), expected[1].size());
  // Then segment 0 needs the room: segment 1 goes (least recently used, not needed).
  st = cold->points_near(segment_pose(0).translation(), 5.0, &out);
  ASSERT_TRUE(st.ok());
  if (expected[0].size() <= expected[1].size()) {
    EXPECT_EQ(st->segments_used, 1);
    EXPECT_EQ(out.size(), expected[0].size());
    EXPECT_FALSE(cold->segments()[1].loaded);
  } else {
    EXPECT_EQ(st->segments_over_budget, 1);  // larger thinned than the budget: read, then dropped
    EXPECT_TRUE(out.empty());
  }
  EXPECT_LE(cold->counters().loaded_points, tight.max_loaded_points);

  PriorMapConfig bad = config;
  bad.cloud_voxel_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(PriorMap::open(tmp.file("store"), bad).status().code(), core::ErrorCode::kInvalidArgument);
  bad.cloud_voxel_m = -0.05;
  EXPECT_EQ(PriorMap::open(tmp.file("store"), bad).status().code(), core::ErrorCode::kInvalidArgument);
}

TEST(PriorMap, GivenKeepGoingSaysStopThenThePreloadStopsThereAndQueriesReadTheRest) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  PriorMapConfig config;
  config.cloud_reach_m = 2.5;
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  int asked = 0;
  const PreloadStats pre = map->preload_clouds([&] { return ++asked <= 1; });  // one read, then stop
  EXPECT_TRUE(pre.cancelled);
  EXPECT_EQ(asked, 2);
  EXPECT_EQ(pre.segments_loaded, 1);
  EXPECT_EQ(pre.segments_in_memory, 1);
  EXPECT_TRUE(map->segments()[0].loaded);
  EXPECT_FALSE(map->segments()[1].loaded);
  EXPECT_EQ(map->counters().cloud_loads, 1u);
  // What was left on disk is read when a query needs it.
  std::vector<CloudPoint> out;
  auto st = map->points_near(segment_pose(2).translation(), 5.0, &out);
  ASSERT_TRUE(st.ok()) << st.status().message();
  EXPECT_EQ(st->segments_used, 1);
  EXPECT_FALSE(out.empty());
  EXPECT_EQ(map->counters().cloud_loads, 2u);
  EXPECT_TRUE(map->segments()[2].loaded);
  // A preload that is not stopped reads the rest and says so.
  const PreloadStats rest = map->preload_clouds([] { return true; });
  EXPECT_FALSE(rest.cancelled);
  EXPECT_EQ(rest.segments_in_memory, static_cast<int>(segments.size()));
}

TEST(PriorMap, GivenAMissingOrDamagedStoreThenTheErrorNamesTheFile) {
  TempDir tmp;
  auto missing = PriorMap::open(tmp.file("store") + "/nope");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(missing.status().message().find("nope"), std::string::npos) << missing.status().message();

  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  // A damaged cloud is found when it is needed (the clouds are lazy), not at open; it is then
  // skipped, counted and never read again, and the other segments still answer.
  const std::string cloud1 = tmp.file("store") + "/segments/seg_000001/cloud.bin";
  flip_byte(cloud1, 48 + 100);
  PriorMapConfig config = exact_config();
  config.cloud_reach_m = 2.5;
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  std::vector<CloudPoint> out;
  ASSERT_TRUE(map->points_near(segment_pose(0).translation(), 4.0, &out).ok());
  EXPECT_EQ(map->counters().cloud_loads, 1u);
  auto bad = map->points_near(segment_pose(1).translation(), 4.0, &out);
  ASSERT_TRUE(bad.ok()) << bad.status().message();
  EXPECT_EQ(bad->segments_near, 1);
  EXPECT_EQ(bad->segments_unreadable, 1);
  EXPECT_EQ(bad->segments_used, 0);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(map->counters().unreadable_segments, 1);
  EXPECT_TRUE(map->segments()[1].unreadable);
  EXPECT_FALSE(map->segments()[1].loaded);
  EXPECT_EQ(map->counters().cloud_loads, 1u);
  // A ball over segments 0 and 1: segment 0's points, exactly; segment 1 is not tried again.
  const Eigen::Vector3d c0 = segment_pose(0).translation(), c1 = segment_pose(1).translation();
  const Eigen::Vector3d between = c0 + 0.2 * (c1 - c0);
  const double radius = (c1 - between).norm() + 0.5;
  auto partial = map->points_near(between, radius, &out);
  ASSERT_TRUE(partial.ok()) << partial.status().message();
  EXPECT_EQ(partial->segments_near, 2);
  EXPECT_EQ(partial->segments_used, 1);
  EXPECT_EQ(partial->segments_unreadable, 1);
  std::vector<SegmentRecord> only0(segments.begin(), segments.begin() + 1);
  expect_same_points(expected_near(only0, between, radius), out);
  EXPECT_FALSE(out.empty());
  EXPECT_EQ(map->counters().unreadable_segments, 1);
  EXPECT_EQ(map->counters().cloud_loads, 1u);

  // A damaged keyframes.bin fails open().
  const std::string kf2 = tmp.file("store") + "/segments/seg_000002/keyframes.bin";
  flip_byte(kf2, 48 + 20);
  auto broken = PriorMap::open(tmp.file("store"), config);
  ASSERT_FALSE(broken.ok());
  EXPECT_EQ(broken.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(broken.status().message().find(kf2), std::string::npos) << broken.status().message();
}

TEST(PriorMap, GivenRoomForTwoOfThreeCloudsThenTheLeastRecentlyUsedUnneededOneIsTheVictim) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  PriorMapConfig config = exact_config();
  config.cloud_reach_m = 2.5;
  config.max_loaded_points = 2 * kPointsPerSegment + kPointsPerSegment / 2;  // room for two clouds
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  std::vector<CloudPoint> out;
  const Eigen::Vector3d c[3] = {segment_pose(0).translation(), segment_pose(1).translation(),
                                segment_pose(2).translation()};
  ASSERT_TRUE(map->points_near(c[0], 4.0, &out).ok());
  ASSERT_TRUE(map->points_near(c[1], 4.0, &out).ok());
  EXPECT_EQ(map->counters().cloud_evictions, 0u);
  // Segment 0 used again: segment 1 is now the least recently used, so segment 2 evicts it (not 0,
  // the first loaded nor the lowest index).
  ASSERT_TRUE(map->points_near(c[0], 4.0, &out).ok());
  ASSERT_TRUE(map->points_near(c[2], 4.0, &out).ok());
  EXPECT_EQ(map->counters().cloud_loads, 3u);
  EXPECT_EQ(map->counters().cloud_evictions, 1u);
  EXPECT_TRUE(map->segments()[0].loaded);
  EXPECT_FALSE(map->segments()[1].loaded);
  EXPECT_TRUE(map->segments()[2].loaded);
  expect_same_points(expected_near(segments, c[2], 4.0), out);
  // Now 0 is the oldest: segment 1 comes back in its place.
  ASSERT_TRUE(map->points_near(c[1], 4.0, &out).ok());
  EXPECT_FALSE(map->segments()[0].loaded);
  EXPECT_TRUE(map->segments()[1].loaded);
  EXPECT_TRUE(map->segments()[2].loaded);
  EXPECT_EQ(map->counters().cloud_evictions, 2u);
  EXPECT_LE(map->counters().loaded_points, config.max_loaded_points);
}

TEST(PriorMap, GivenASegmentLoadedForItsEstimatedBoxButNotNearThenItCanBeEvictedInTheSameQuery) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  // A reach of 28 m: before their clouds are read, segments 0 and 2 (30 m away) seem within 4 m of
  // segment 1's origin (about 1.5 and 2 m: 0 comes first); their clouds show they are not.
  PriorMapConfig config = exact_config();
  config.cloud_reach_m = 28.0;
  config.max_loaded_points = 2 * kPointsPerSegment + kPointsPerSegment / 2;  // room for two clouds
  auto map = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(map.ok()) << map.status().message();
  std::vector<CloudPoint> out;
  const Eigen::Vector3d c1 = segment_pose(1).translation();
  auto st = map->points_near(c1, 4.0, &out);
  ASSERT_TRUE(st.ok()) << st.status().message();
  EXPECT_EQ(st->segments_near, 3);
  EXPECT_EQ(st->segments_used, 1);
  // Segment 0, loaded and found far, is evicted to read segment 2 instead of that being refused.
  EXPECT_EQ(st->segments_over_budget, 0);
  EXPECT_EQ(map->counters().cloud_loads, 3u);
  EXPECT_EQ(map->counters().cloud_evictions, 1u);
  EXPECT_FALSE(map->segments()[0].loaded);
  EXPECT_TRUE(map->segments()[1].loaded);
  EXPECT_TRUE(map->segments()[2].loaded);
  EXPECT_TRUE(map->segments()[0].cloud_box_known && map->segments()[2].cloud_box_known);
  expect_same_points(expected_near(segments, c1, 4.0), out);
  EXPECT_EQ(out.size(), static_cast<size_t>(kPointsPerSegment));
  // Their boxes are known now: the same query reads nothing more.
  st = map->points_near(c1, 4.0, &out);
  ASSERT_TRUE(st.ok());
  EXPECT_EQ(st->segments_near, 1);
  EXPECT_EQ(map->counters().cloud_loads, 3u);
}

TEST(PriorMap, GivenMoreKeyframeFeaturesThanTheBoundThenOpenFailsSayingSo) {
  TempDir tmp;
  write_store(tmp.file("store"), make_segments());
  constexpr int kTotal = kSegments * kKeyframesPerSegment * kFeaturesPerKeyframe;  // 300
  PriorMapConfig config = exact_config();
  config.max_prior_features = kTotal;
  auto fits = PriorMap::open(tmp.file("store"), config);
  ASSERT_TRUE(fits.ok()) << fits.status().message();
  config.max_prior_features = kTotal - 1;
  auto over = PriorMap::open(tmp.file("store"), config);
  ASSERT_FALSE(over.ok());
  EXPECT_EQ(over.status().code(), core::ErrorCode::kOutOfRange);
  EXPECT_NE(over.status().message().find("max_prior_features"), std::string::npos) << over.status().message();
  config.max_prior_features = 0;
  EXPECT_EQ(PriorMap::open(tmp.file("store"), config).status().code(), core::ErrorCode::kInvalidArgument);
}

TEST(MapStore, GivenASegmentWhenReadKeyframesThenKeyframesWithoutTheCloud) {
  TempDir tmp;
  const std::vector<SegmentRecord> segments = make_segments();
  write_store(tmp.file("store"), segments);
  auto store = MapStore::open_existing(tmp.file("store"));
  ASSERT_TRUE(store.ok());
  // Even with its cloud gone: keyframes.bin and segment.yaml are all it reads.
  fs::remove(tmp.file("store") + "/segments/seg_000001/cloud.bin");
  auto rec = store->read_keyframes(1);
  ASSERT_TRUE(rec.ok()) << rec.status().message();
  EXPECT_TRUE(rec->points_segment.empty());
  ASSERT_EQ(rec->keyframes.size(), static_cast<size_t>(kKeyframesPerSegment));
  EXPECT_EQ(rec->keyframes[1].descriptors, segments[1].keyframes[1].descriptors);
  EXPECT_TRUE(rec->T_world_segment.isApprox(segment_pose(1), 0.0));
  EXPECT_EQ(store->read_segment(1).status().code(), core::ErrorCode::kCorruptData);
  EXPECT_EQ(store->read_keyframes(7).status().code(), core::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace hwr::recon
