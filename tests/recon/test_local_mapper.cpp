// The local mapper (issue #4 items 2 and 4) on the simulator's lab walk: keyframes every ~0.3 s with
// ORB features and rendered depth, poses from ground truth with independent per-keyframe noise (an
// odometry whose relative poses are off by ~1.5 cm). Oracles: segments close on travel or on point
// count, never both thresholds exceeded by more than one keyframe; every keyframe lands in exactly
// one segment, in order; each junction is seeded by ORB and its refined T_a_b is closer to the true
// relative pose than the noisy odometry (whose disagreement with the measurement keeps it out of
// the fusion), and with an odometry as good as its prior the fused junction beats the odometry;
// points are stored in the segment frame (they land on the
// rendered surfaces when moved back to the world with T_world_segment).

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "hwr/core/so3.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/recon/local_mapper.hpp"
#include "hwr/recon/segment_writer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"

namespace hwr::recon {
namespace {

struct LabKeyframes {
  hal::PinholeIntrinsics K;
  std::vector<hal::RgbdFrame> frames;
  std::vector<Eigen::Isometry3d> T_world_cam_true;
};

// Every `step`-th frame of the first `duration_s` of the lab walk.
const LabKeyframes& lab_keyframes() {
  static const LabKeyframes data = [] {
    LabKeyframes d;
    auto spec = sim::load_scenario("lab");
    EXPECT_TRUE(spec.ok());
    auto live = sim::open_sim_live_log(spec.value(), 40.0);
    EXPECT_TRUE(live.ok()) << live.status().message();
    d.K = live->log.info.intrinsics;
    for (size_t i = 30; i < live->log.frame_t_ns.size(); i += 8) {
      hal::RgbdFrame f;
      f.bgr.create(d.K.height, d.K.width, CV_8UC3);
      f.depth_m.create(d.K.height, d.K.width, CV_32FC1);
      EXPECT_TRUE(live->log.load_frame(i, &f).ok());
      d.frames.push_back(f);
      d.T_world_cam_true.push_back(live->groundtruth_T_world_cam_at_frames[i].T_world_body);
    }
    return d;
  }();
  return data;
}

Eigen::Isometry3d perturb(const Eigen::Isometry3d& T, std::mt19937* rng, double sigma_m, double sigma_rad) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Isometry3d d = Eigen::Isometry3d::Identity();
  d.linear() = core::so3_exp(Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * sigma_rad);
  d.translation() = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)) * sigma_m;
  return T * d;
}

struct MapperRun {
  std::vector<SegmentRecord> segments;
  std::vector<Eigen::Isometry3d> T_world_cam_used;  // the noisy "odometry" given to the mapper
  LocalMapperCounters counters;
};

struct StreamCall {
  uint32_t segment_id;
  Eigen::Isometry3d T_world_segment;
  std::vector<CloudPoint> points;
  std::vector<uint32_t> ids;
  bool complete;
};
struct StreamCollector : MapStreamSink {
  std::vector<StreamCall> calls;
  void stream(uint32_t segment_id, const Eigen::Isometry3d& T_world_segment, const CloudPoint* points,
              const uint32_t* ids, int n, bool complete) override {
    calls.push_back({segment_id, T_world_segment, std::vector<CloudPoint>(points, points + n),
                     std::vector<uint32_t>(ids, ids + n), complete});
  }
};

MapperRun run_mapper(const LocalMapperConfig& config, double sigma_m, double sigma_rad,
                     MapStreamSink* stream = nullptr) {
  const LabKeyframes& lab = lab_keyframes();
  estimation::KeyframeStoreConfig kcfg;
  kcfg.capacity = 64;
  kcfg.image_slots = 8;
  kcfg.feature_capacity = 800;
  kcfg.width = lab.K.width;
  kcfg.height = lab.K.height;
  estimation::KeyframeStore store(kcfg);
  estimation::OrbConfig ocfg;
  estimation::GridOrbExtractor orb(ocfg, lab.K.width, lab.K.height);
  auto mapper = LocalMapper::create(config, lab.K, 800);
  EXPECT_TRUE(mapper.ok()) << mapper.status().message();
  mapper->set_stream_sink(stream);
  SegmentCollector sink;
  MapperRun run;
  std::mt19937 rng(7);
  cv::Mat gray;
  for (size_t i = 0; i < lab.frames.size(); ++i) {
    const Eigen::Isometry3d T = perturb(lab.T_world_cam_true[i], &rng, sigma_m, sigma_rad);
    run.T_world_cam_used.push_back(T);
    estimation::Keyframe* kf = store.insert(lab.frames[i].t_ns, T);
    cv::cvtColor(lab.frames[i].bgr, gray, cv::COLOR_BGR2GRAY);
    EXPECT_TRUE(orb.extract(gray, lab.frames[i].depth_m, lab.K, &kf->features).ok());
    store.store_images(kf->id, lab.frames[i].bgr, lab.frames[i].depth_m);
    mapper->update(store, &sink);
  }
  mapper->finish(store, &sink);
  run.segments = std::move(sink.segments);
  run.counters = mapper->counters();
  return run;
}

double translation_error_m(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  return (A.inverse() * B).translation().norm();
}

TEST(LocalMapper, GivenTravelThresholdThenSegmentsCloseAndJunctionsBeatOdometry) {
  LocalMapperConfig config;
  config.segment_max_travel_m = 2.0;
  const MapperRun run = run_mapper(config, 0.01, 0.004);
  const LabKeyframes& lab = lab_keyframes();
  ASSERT_GE(run.segments.size(), 3u);
  EXPECT_EQ(run.counters.segments_closed, run.segments.size());
  EXPECT_EQ(run.counters.keyframes_fused, lab.frames.size());

  int expected_id = 0;
  for (size_t s = 0; s < run.segments.size(); ++s) {
    const SegmentRecord& seg = run.segments[s];
    EXPECT_EQ(seg.segment_id, s);
    ASSERT_FALSE(seg.keyframes.empty());
    for (const StoredKeyframe& kf : seg.keyframes) EXPECT_EQ(kf.id, expected_id++);
    // The segment frame is its first keyframe's camera at the pose the mapper was given.
    EXPECT_TRUE(seg.T_world_segment.isApprox(run.T_world_cam_used[static_cast<size_t>(seg.keyframes[0].id)]));
    EXPECT_LT(seg.travelled_m, config.segment_max_travel_m);
    EXPECT_GT(seg.points_segment.size(), 1000u);
    EXPECT_EQ(seg.keyframes[0].descriptors.size(), seg.keyframes[0].features.size() * 32);
  }
  EXPECT_EQ(expected_id, static_cast<int>(lab.frames.size()));

  // Junctions: the refined relative pose of keyframes a -> b against the truth.
  double sum_refined = 0, sum_odometry = 0;
  for (size_t s = 1; s < run.segments.size(); ++s) {
    const SegmentRecord& prev = run.segments[s - 1];
    const JunctionRecord& j = run.segments[s].junction;
    const size_t a = static_cast<size_t>(j.keyframe_before), b = static_cast<size_t>(j.keyframe_after);
    ASSERT_EQ(j.keyframe_before, prev.keyframes.back().id);
    ASSERT_EQ(j.keyframe_after, run.segments[s].keyframes.front().id);
    EXPECT_TRUE(j.valid);
    EXPECT_GE(j.orb_inliers, config.junction.min_orb_inliers) << "junction " << s;
    const Eigen::Isometry3d T_a_b_true = lab.T_world_cam_true[a].inverse() * lab.T_world_cam_true[b];
    const Eigen::Isometry3d T_prevseg_a = prev.T_world_segment.inverse() * run.T_world_cam_used[a];
    const Eigen::Isometry3d T_a_b_refined = T_prevseg_a.inverse() * j.T_prev_segment_segment;
    const Eigen::Isometry3d T_a_b_odometry = T_prevseg_a.inverse() * j.T_prev_segment_segment_odometry;
    const double e_refined = translation_error_m(T_a_b_true, T_a_b_refined);
    const double e_odometry = translation_error_m(T_a_b_true, T_a_b_odometry);
    EXPECT_LT(e_refined, 0.01) << "junction " << s;
    // The odometry is ~7x worse than the configured prior: the gate keeps the measurement alone.
    EXPECT_FALSE(j.fused) << "junction " << s;
    sum_refined += e_refined;
    sum_odometry += e_odometry;
  }
  EXPECT_LT(sum_refined, 0.5 * sum_odometry);
}

double rotation_error_rad(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  return Eigen::AngleAxisd((A.inverse() * B).linear()).angle();
}

// With an odometry as good as its configured prior, the fused junction (MAP of the ORB/NDT
// measurement and the odometry) is closer to the truth than the odometry, summed over the cuts.
TEST(LocalMapper, GivenOdometryAsGoodAsItsPriorThenFusedJunctionsBeatTheOdometry) {
  LocalMapperConfig config;
  config.segment_max_travel_m = 1.0;
  // Per-keyframe noise sigma: the relative pose of two keyframes is off by ~sqrt(2) sigma per axis.
  const double sigma_m = 0.0015, sigma_rad = 0.0006;
  config.junction.odometry_sigma_m = std::sqrt(2.0) * sigma_m;
  config.junction.odometry_sigma_rad = std::sqrt(2.0) * sigma_rad;
  // This odometry's noise is drawn independently of the images, so an ORB pose alone is
  // independent information too (a real tracker's is not: junction.hpp, fuse_orb_alone).
  config.junction.fuse_orb_alone = true;
  const MapperRun run = run_mapper(config, sigma_m, sigma_rad);
  const LabKeyframes& lab = lab_keyframes();
  ASSERT_GE(run.segments.size(), 6u);
  double fused_rad = 0, measured_rad = 0, odometry_rad = 0, fused_m = 0, measured_m = 0, odometry_m = 0;
  int fused = 0;
  for (size_t s = 1; s < run.segments.size(); ++s) {
    const SegmentRecord& prev = run.segments[s - 1];
    const JunctionRecord& j = run.segments[s].junction;
    fused += j.fused ? 1 : 0;
    const size_t a = static_cast<size_t>(j.keyframe_before), b = static_cast<size_t>(j.keyframe_after);
    const Eigen::Isometry3d T_a_b_true = lab.T_world_cam_true[a].inverse() * lab.T_world_cam_true[b];
    const Eigen::Isometry3d T_a_prevseg = run.T_world_cam_used[a].inverse() * prev.T_world_segment;
    const Eigen::Isometry3d T_fused = T_a_prevseg * j.T_prev_segment_segment;
    const Eigen::Isometry3d T_measured = T_a_prevseg * j.T_prev_segment_segment_measured;
    const Eigen::Isometry3d T_odometry = T_a_prevseg * j.T_prev_segment_segment_odometry;
    fused_rad += rotation_error_rad(T_a_b_true, T_fused);
    measured_rad += rotation_error_rad(T_a_b_true, T_measured);
    odometry_rad += rotation_error_rad(T_a_b_true, T_odometry);
    fused_m += translation_error_m(T_a_b_true, T_fused);
    measured_m += translation_error_m(T_a_b_true, T_measured);
    odometry_m += translation_error_m(T_a_b_true, T_odometry);
  }
  EXPECT_EQ(fused, static_cast<int>(run.segments.size()) - 1);
  // FLANN seeds its LSH tables from std::random_device (flann/util/lsh_table.h), so the ORB matches,
  // and with them the measurement, differ from run to run. Measured over 5 runs (10 junctions
  // each): fused 0.0211-0.0218 m, measurement alone 0.0210-0.0246 m, odometry 0.0371 m.
  // Translation: far better than the odometry and no worse than the measurement beyond that spread.
  // Rotation: better than the odometry and close to the measurement (the default
  // orb_covariance_scale is set for real depth noise, so on these rendered keyframes it weights the
  // ORB rotation less than it deserves; measured: 0.0081 vs 0.0064 rad).
  EXPECT_LT(fused_m, 0.75 * odometry_m);
  EXPECT_LT(fused_m, 1.15 * measured_m);
  EXPECT_LT(fused_rad, odometry_rad);
  EXPECT_LT(fused_rad, 1.5 * measured_rad);
  // The default: an ORB pose that NDT did not refine is not fused; such a junction keeps the
  // odometry (or, gated out, the measurement), and only NDT's poses are fused.
  config.junction.fuse_orb_alone = false;
  const MapperRun kept = run_mapper(config, sigma_m, sigma_rad);
  ASSERT_EQ(kept.segments.size(), run.segments.size());
  int kept_odometry = 0, fused_ndt = 0;
  for (size_t s = 1; s < kept.segments.size(); ++s) {
    const JunctionRecord& j = kept.segments[s].junction;
    EXPECT_FALSE(j.fused && j.odometry_kept) << "junction " << s;
    if (j.fused) {
      EXPECT_TRUE(j.ndt_used) << "junction " << s;
      ++fused_ndt;
    } else if (j.odometry_kept) {
      EXPECT_FALSE(j.ndt_used) << "junction " << s;
      EXPECT_TRUE(j.T_prev_segment_segment.isApprox(j.T_prev_segment_segment_odometry, 1e-12))
          << "junction " << s;
      EXPECT_FALSE(j.T_prev_segment_segment.isApprox(j.T_prev_segment_segment_measured, 1e-9))
          << "junction " << s;
      ++kept_odometry;
    }
  }
  // The lab walk has both kinds (measured: 6 fused, 4 kept over 10 junctions).
  EXPECT_GT(kept_odometry, 0);
  EXPECT_GT(fused_ndt, 0);
  // Disabled, the junction is the measurement alone (the paper's method).
  config.junction.fuse_odometry = false;
  const MapperRun paper = run_mapper(config, sigma_m, sigma_rad);
  for (size_t s = 1; s < paper.segments.size(); ++s) {
    const JunctionRecord& j = paper.segments[s].junction;
    EXPECT_FALSE(j.fused);
    EXPECT_TRUE(j.T_prev_segment_segment.isApprox(j.T_prev_segment_segment_measured));
  }
}

// Streaming while the map fills: every voxel of every closed segment is streamed exactly once, in
// its segment, near its final mean (inside its voxel), and most of a segment is out before it
// closes; each segment's last call, and only it, says complete.
TEST(LocalMapper, GivenAStreamSinkThenEveryVoxelIsStreamedOnceAndMostBeforeTheClose) {
  LocalMapperConfig config;
  config.segment_max_travel_m = 3.0;
  config.stream_min_points = 5'000;
  StreamCollector stream;
  const MapperRun run = run_mapper(config, 0.0, 0.0, &stream);
  ASSERT_GE(run.segments.size(), 2u);
  size_t call = 0;
  for (const SegmentRecord& seg : run.segments) {
    std::vector<CloudPoint> streamed;
    size_t before_close = 0;
    for (; call < stream.calls.size(); ++call) {
      const StreamCall& c = stream.calls[call];
      ASSERT_EQ(c.segment_id, seg.segment_id);
      EXPECT_TRUE(c.T_world_segment.isApprox(seg.T_world_segment));
      streamed.insert(streamed.end(), c.points.begin(), c.points.end());
      if (c.complete) break;
      before_close += c.points.size();
    }
    ASSERT_LT(call, stream.calls.size()) << "segment " << seg.segment_id << " never completed";
    ++call;
    ASSERT_EQ(streamed.size(), seg.points_segment.size()) << "segment " << seg.segment_id;
    // Each streamed point lies in the voxel of exactly one final point.
    auto voxel_of = [&](const CloudPoint& p) {
      const double v = config.voxels.voxel_m;
      return std::make_tuple(std::floor(p.x_m / v), std::floor(p.y_m / v), std::floor(p.z_m / v));
    };
    std::vector<std::tuple<double, double, double>> a, b;
    for (const CloudPoint& p : streamed) a.push_back(voxel_of(p));
    for (const CloudPoint& p : seg.points_segment) b.push_back(voxel_of(p));
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    EXPECT_EQ(a, b) << "segment " << seg.segment_id;
    if (seg.points_segment.size() > 4u * static_cast<size_t>(config.stream_min_points)) {
      EXPECT_GT(before_close, seg.points_segment.size() / 2) << "segment " << seg.segment_id;
    }
  }
  EXPECT_EQ(call, stream.calls.size());
}

TEST(LocalMapper, GivenPointThresholdThenSegmentsCloseOnPointCount) {
  LocalMapperConfig config;
  config.segment_max_travel_m = 1000.0;
  config.segment_max_points = 100'000;
  const MapperRun run = run_mapper(config, 0.0, 0.0);
  ASSERT_GE(run.segments.size(), 2u);
  for (size_t s = 0; s + 1 < run.segments.size(); ++s) {
    // Closed once it held the threshold: at least that many, at most one keyframe more.
    EXPECT_GE(run.segments[s].points_segment.size(), 100'000u);
    EXPECT_LT(run.segments[s].points_segment.size(), 100'000u + 320u * 240u);
  }
}

TEST(LocalMapper, GivenSegmentsThenPointsAreInTheSegmentFrame) {
  LocalMapperConfig config;
  config.segment_max_travel_m = 2.0;
  const MapperRun run = run_mapper(config, 0.0, 0.0);
  const LabKeyframes& lab = lab_keyframes();
  ASSERT_GE(run.segments.size(), 2u);
  // A point seen by the segment's first keyframe re-projects into that keyframe's depth image at
  // its depth when taken through T_world_segment back to the world and into the true camera.
  for (const SegmentRecord& seg : run.segments) {
    const size_t k = static_cast<size_t>(seg.keyframes[0].id);
    const Eigen::Isometry3d T_cam_segment = lab.T_world_cam_true[k].inverse() * seg.T_world_segment;
    int checked = 0, agree = 0;
    for (size_t i = 0; i < seg.points_segment.size(); i += 97) {
      const CloudPoint& p = seg.points_segment[i];
      const Eigen::Vector3d c = T_cam_segment * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
      if (c.z() < 0.3) continue;
      const int u = static_cast<int>(std::lround(lab.K.fx * c.x() / c.z() + lab.K.cx));
      const int v = static_cast<int>(std::lround(lab.K.fy * c.y() / c.z() + lab.K.cy));
      if (u < 0 || v < 0 || u >= lab.K.width || v >= lab.K.height) continue;
      const float z = lab.frames[k].depth_m.at<float>(v, u);
      if (!(z > 0)) continue;
      ++checked;
      // Occluded points (seen by later keyframes) are behind the surface; visible ones agree.
      if (std::abs(z - c.z()) < 0.03 + 0.01 * c.z()) ++agree;
    }
    ASSERT_GT(checked, 100);
    EXPECT_GT(static_cast<double>(agree) / checked, 0.5) << "segment " << seg.segment_id;
  }
}

}  // namespace
}  // namespace hwr::recon
