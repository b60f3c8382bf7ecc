// PriorMapUpdater on rendered sim lab frames: the prior segment (made from the same place, truth
// poses) holds a "ghost" plate floating in what the current frames see as free space (a plate that
// was moved away). With the true poses the update deletes most of it and keeps the static geometry
// (issue #6 acceptance: point loss on unchanged surfaces <= 1 %); with a relocalization-sized pose
// error (2 cm, 0.3 deg) the pose refinement (prior_pose_refiner.hpp) lets it do the same, and with
// a large one it deletes nothing (the refinement gives up, the carver's pose check fails closed).
// The refinement itself: exact poses are hardly moved; from the relocalization-sized error, the
// directions the views constrain are recovered (the walk's views are floor-dominated: along the
// corridor the translation is unconstrained, a wall only now and then).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "sim_frames.hpp"
#include "temp_dir.hpp"
#include "hwr/core/arena.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/prior_map_updater.hpp"
#include "hwr/recon/prior_pose_refiner.hpp"
#include "hwr/recon/voxel_map.hpp"

namespace hwr::recon {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// The relocalization-sized error: 0.3 deg about the prior's z axis and (1.5, -1, 0.8) cm, applied in
// the prior frame (an error of T_prior_world), about 2-5 cm at the cameras.
Eigen::Isometry3d relocalization_error() {
  Eigen::Isometry3d error = Eigen::Isometry3d::Identity();
  error.linear() = Eigen::AngleAxisd(0.3 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  error.translation() = Eigen::Vector3d(0.015, -0.01, 0.008);
  return error;
}

struct CurrentFrame {
  cv::Mat depth_m;
  Eigen::Isometry3d T_prior_cam_true = Eigen::Isometry3d::Identity();
};

struct Scene {
  hwr::testing::TempDir tmp{"hwr_map_update"};
  std::string prior_dir;
  hal::PinholeIntrinsics K;
  std::vector<CurrentFrame> current;
  Eigen::Isometry3d T_prior_segment = Eigen::Isometry3d::Identity();
  Eigen::AlignedBox3d ghost_box_segment;  // the ghost plate's points, segment frame (inflated 1 mm)
  int ghost_points = 0;
  int static_points_near = 0;              // static prior points within 4 m of a current camera
  int total_points = 0;                    // in the prior segment
  std::vector<CloudPoint> points_segment;  // the prior segment's points (ghost included)
  SegmentRecord record;                    // the prior segment as stored
};

bool near_a_camera(const Scene& s, const Eigen::Vector3d& p_prior) {
  for (const CurrentFrame& f : s.current) {
    if ((f.T_prior_cam_true.translation() - p_prior).norm() < 4.0) return true;
  }
  return false;
}

const Scene& scene() {
  // Held until the process exits, when its TempDir removes the prior store (a leaked pointer left it
  // in the temp dir after every test process).
  static const std::unique_ptr<Scene> s = [] {
    auto out = std::make_unique<Scene>();
    out->prior_dir = out->tmp.path() + "/prior";
    SegmentRecord seg;
    KeyframeCloudConfig cloud_config;
    std::unique_ptr<core::Arena> arena;
    auto voxels = VoxelMap::create({0.02, 1'000'000});
    EXPECT_TRUE(voxels.ok());
    estimation::FrameFeatures none(1, 1, 1);
    // The prior: every 12th frame of 41-51 s; the current run: every 24th, half a step later.
    hwr::testing::for_each_sim_frame(
        "lab", 1230, 1530, 6,
        [&](size_t i, const hal::RgbdFrame& f, const Eigen::Isometry3d& T, const hal::PinholeIntrinsics& K) {
          out->K = K;
          if (i % 24 == 0) {
            CurrentFrame c;
            c.depth_m = f.depth_m.clone();
            c.T_prior_cam_true = T;
            out->current.push_back(c);
          }
          if (i % 12 != 6) return;
          if (!arena)
            arena =
                std::make_unique<core::Arena>(keyframe_cloud_capacity_bytes(K.width, K.height, cloud_config));
          if (seg.keyframes.empty()) seg.T_world_segment = T;
          arena->reset();
          auto cloud = build_keyframe_cloud(f.bgr, f.depth_m, K, seg.T_world_segment.inverse() * T,
                                            cloud_config, arena.get());
          ASSERT_TRUE(cloud.ok());
          voxels->insert(cloud.value());
          seg.keyframes.push_back(
              hwr::testing::stored_keyframe(none, T, static_cast<int32_t>(seg.keyframes.size()), f.t_ns));
        });
    hwr::testing::append_voxel_points(voxels.value(), &seg.points_segment);
    out->T_prior_segment = seg.T_world_segment;
    // The ghost: a 0.16 x 0.16 m plate (1 cm grid) facing a current camera 1.2 m in front of it, where
    // that camera's centre pixel sees at least 2.5 m deep (free space in front of the surface).
    for (const CurrentFrame& c : out->current) {
      const float z = c.depth_m.at<float>(out->K.height / 2, out->K.width / 2);
      if (!(z > 2.5f)) continue;
      for (int a = -8; a <= 8; ++a) {
        for (int b = -8; b <= 8; ++b) {
          const Eigen::Vector3d p_cam(0.01 * a, 0.01 * b, 1.2);
          const Eigen::Vector3d p_seg = seg.T_world_segment.inverse() * c.T_prior_cam_true * p_cam;
          CloudPoint p;
          p.x_m = static_cast<float>(p_seg.x());
          p.y_m = static_cast<float>(p_seg.y());
          p.z_m = static_cast<float>(p_seg.z());
          seg.points_segment.push_back(p);
          out->ghost_box_segment.extend(p_seg);
          ++out->ghost_points;
        }
      }
      break;
    }
    EXPECT_GT(out->ghost_points, 0) << "no current view with free space ahead";
    out->ghost_box_segment =
        Eigen::AlignedBox3d(out->ghost_box_segment.min() - Eigen::Vector3d::Constant(0.001),
                            out->ghost_box_segment.max() + Eigen::Vector3d::Constant(0.001));
    for (const CloudPoint& p : seg.points_segment) {
      const Eigen::Vector3d q(p.x_m, p.y_m, p.z_m);
      if (!out->ghost_box_segment.contains(q) && near_a_camera(*out, seg.T_world_segment * q)) {
        ++out->static_points_near;
      }
    }
    out->total_points = static_cast<int>(seg.points_segment.size());
    out->points_segment = seg.points_segment;
    StoreMetadata meta;
    meta.run_id = "map-update-prior";
    meta.intrinsics = out->K;
    auto store = MapStore::open(out->prior_dir, meta);
    EXPECT_TRUE(store.ok());
    EXPECT_TRUE(store->write_segment(seg).ok());
    out->record = seg;
    return out;
  }();
  return *s;
}

struct Collect final : UpdatedSegmentSink {
  std::vector<SegmentRecord> segments;
  std::vector<int> versions, deleted;
  // The final versions (what the map store gets); the intermediate ones are counted.
  int intermediate = 0;
  void take_updated(const SegmentRecord& s, int version, int points_deleted, bool final) override {
    if (!final) {
      ++intermediate;
      return;
    }
    segments.push_back(s);
    versions.push_back(version);
    deleted.push_back(points_deleted);
  }
};

// A store under the scene's folder holding `segments` (the tests below vary the prior's segments).
std::string write_store(const Scene& s, const std::string& name, const std::vector<SegmentRecord>& segments) {
  const std::string dir = s.tmp.path() + "/" + name;
  StoreMetadata meta;
  meta.run_id = "map-update-" + name;
  meta.intrinsics = s.K;
  auto store = MapStore::open(dir, meta);
  EXPECT_TRUE(store.ok()) << store.status().message();
  for (const SegmentRecord& seg : segments) EXPECT_TRUE(store.ok() && store->write_segment(seg).ok());
  return dir;
}

// The scene's current views through an updater with `config` over the store at `dir`; the final
// versions go to *sink, the counters to *counters.
void run_updater(const Scene& s, const std::string& dir, const PriorMapUpdaterConfig& config, Collect* sink,
                 PriorMapUpdaterCounters* counters) {
  auto u = PriorMapUpdater::create(dir, config, s.K);
  ASSERT_TRUE(u.ok()) << u.status().message();
  for (const CurrentFrame& f : s.current) ASSERT_TRUE(u->observe(f.depth_m, f.T_prior_cam_true, sink).ok());
  ASSERT_TRUE(u->finish(sink).ok());
  *counters = u->counters();
}

// A decoy: the scene's segment under another id, its keyframes turned about their y axis (looking
// elsewhere, the points unchanged).
SegmentRecord turned_copy(const SegmentRecord& record, uint32_t id, double turn_deg) {
  SegmentRecord out = record;
  out.segment_id = id;
  const Eigen::Isometry3d turn(Eigen::AngleAxisd(turn_deg * kDeg, Eigen::Vector3d::UnitY()));
  for (StoredKeyframe& kf : out.keyframes) kf.T_world_cam = kf.T_world_cam * turn;
  return out;
}

// The ghost's points left in an updated segment.
int ghost_points_in(const Scene& s, const SegmentRecord& seg) {
  int n = 0;
  for (const CloudPoint& p : seg.points_segment) {
    n += s.ghost_box_segment.contains(Eigen::Vector3d(p.x_m, p.y_m, p.z_m)) ? 1 : 0;
  }
  return n;
}

struct Outcome {
  int ghost_left = 0, static_left_near = 0;
  PriorMapUpdaterCounters counters;
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  Collect sink;
};

// Runs the update over every current frame with T_prior_cam = error * truth.
void run_update(const Eigen::Isometry3d& error, Outcome* out) {
  const Scene& s = scene();
  auto u = PriorMapUpdater::create(s.prior_dir, {}, s.K);
  ASSERT_TRUE(u.ok()) << u.status().message();
  for (const CurrentFrame& f : s.current) {
    ASSERT_TRUE(u->observe(f.depth_m, error * f.T_prior_cam_true, &out->sink).ok());
  }
  ASSERT_TRUE(u->finish(&out->sink).ok());
  out->counters = u->counters();
  out->correction = u->correction();
  if (out->sink.segments.empty()) {
    out->ghost_left = s.ghost_points;
    out->static_left_near = s.static_points_near;
  } else {
    ASSERT_EQ(out->sink.segments.size(), 1u);
    for (const CloudPoint& p : out->sink.segments[0].points_segment) {
      const Eigen::Vector3d q(p.x_m, p.y_m, p.z_m);
      if (s.ghost_box_segment.contains(q)) {
        ++out->ghost_left;
      } else if (near_a_camera(s, s.T_prior_segment * q)) {
        ++out->static_left_near;
      }
    }
  }
  std::printf(
      "[ update   ] ghost %d -> %d, static near the cameras %d -> %d (%.3f %% lost); keyframes %llu, "
      "carving views %llu, failed the pose check %llu; poses refined %llu (not converged %llu, too few rays "
      "%llu, too large %llu)\n",
      s.ghost_points, out->ghost_left, s.static_points_near, out->static_left_near,
      100.0 * (s.static_points_near - out->static_left_near) / s.static_points_near,
      static_cast<unsigned long long>(out->counters.keyframes),
      static_cast<unsigned long long>(out->counters.frames_carved),
      static_cast<unsigned long long>(out->counters.frames_misaligned),
      static_cast<unsigned long long>(out->counters.poses_refined),
      static_cast<unsigned long long>(out->counters.refine_not_converged),
      static_cast<unsigned long long>(out->counters.refine_too_few_rays),
      static_cast<unsigned long long>(out->counters.refine_too_large));
}

TEST(PriorMapUpdater, GivenAPlateThatIsGoneThenItIsDeletedAndStaticGeometryIsKept) {
  Outcome o;
  run_update(Eigen::Isometry3d::Identity(), &o);
  ASSERT_EQ(o.sink.segments.size(), 1u);
  EXPECT_GE(o.sink.versions[0], 1);
  EXPECT_EQ(o.sink.versions[0], o.sink.intermediate) << "one version per close that deleted points";
  EXPECT_EQ(o.sink.deleted[0],
            scene().total_points - static_cast<int>(o.sink.segments[0].points_segment.size()))
      << "the final version's count is the total deleted since the prior";
  EXPECT_EQ(o.sink.segments[0].segment_id, 0u);
  // Measured: 76 % (the plate's rim is seen by fewer rays than min_free_hits needs; views where it
  // covers too much of a surface cluster fail the pose check, which fails closed).
  EXPECT_LT(o.ghost_left, scene().ghost_points / 3) << "at least two thirds of the gone plate deleted";
  EXPECT_GE(o.static_left_near, scene().static_points_near * 0.99) << "static loss <= 1 %";
  EXPECT_GT(o.counters.frames_carved, 0u);
}

TEST(PriorMapUpdater, GivenARelocalizationSizedPoseErrorThenThePlateIsDeletedAndStaticGeometryIsKept) {
  // 2 cm and 0.3 deg: the relocalizer's acceptance limits (issue #6), applied to the whole run.
  const Eigen::Isometry3d error = relocalization_error();
  Outcome o;
  run_update(error, &o);
  EXPECT_EQ(o.counters.keyframes, scene().current.size());
  // Measured: 240 of 289 (83 %); without the refinement 0 (every view failed the check).
  EXPECT_LE(o.ghost_left, 0.3 * scene().ghost_points) << "at least 70 % of the gone plate deleted";
  EXPECT_GE(o.static_left_near, scene().static_points_near * 0.99) << "static loss <= 1 %";
  EXPECT_GE(o.counters.poses_refined, 10u);
  // The carried correction undoes the error where the walk's views constrain it, at the last camera:
  // height and across the corridor (world z, x), and the rotation. Along the corridor (world y) no
  // surface faces the cameras within their 4 m: it stays off.
  const Eigen::Isometry3d& T_true = scene().current.back().T_prior_cam_true;
  const Eigen::Isometry3d d = T_true.inverse() * o.correction * error * T_true;
  const Eigen::Vector3d e_world = T_true.linear() * d.translation();
  const double deg = Eigen::AngleAxisd(d.linear()).angle() / kDeg;
  const Eigen::Vector3d e0_world = error * T_true.translation() - T_true.translation();
  std::printf("[ update   ] last camera: %.1f %.1f %.1f mm %.3f deg off (from %.1f %.1f %.1f mm 0.300 deg)\n",
              e_world.x() * 1e3, e_world.y() * 1e3, e_world.z() * 1e3, deg, e0_world.x() * 1e3,
              e0_world.y() * 1e3, e0_world.z() * 1e3);
  EXPECT_LE(std::abs(e_world.z()), 0.002);
  EXPECT_LE(std::abs(e_world.x()), 0.003);
  EXPECT_LE(deg, 0.15);
}

TEST(PriorMapUpdater, GivenALargePoseErrorThenNothingIsDeleted) {
  Eigen::Isometry3d error = Eigen::Isometry3d::Identity();
  // 10 cm up: every view holds the floor, whose check sees it. (A translation parallel to every
  // surface in view is invisible to the check; free_space_carver.hpp, limitations.)
  error.translation() = Eigen::Vector3d(0.0, 0.0, 0.10);
  Outcome o;
  run_update(error, &o);
  EXPECT_TRUE(o.sink.segments.empty()) << "a frame placed 10 cm off must not carve";
  EXPECT_EQ(o.counters.frames_carved, 0u);
  EXPECT_GT(o.counters.frames_misaligned, 0u);
}

// The scene's prior points in one carver: the refiner's view of its single prior segment.
FreeSpaceCarver make_prior_carver(const Scene& s, const PriorMapUpdaterConfig& uc) {
  auto carver = FreeSpaceCarver::create(uc.carver, s.total_points);
  if (!carver.ok()) {
    ADD_FAILURE() << carver.status().message();
    std::abort();  // nothing to test without it
  }
  EXPECT_TRUE(carver->set_prior(s.points_segment.data(), s.total_points).ok());
  return std::move(carver).value();
}

// The refiner alone on the sim lab's current views (each on its own, no carried correction).
struct RefinerRun {
  double worst_m = 0, worst_deg = 0;  // exact starts: how far the result moved
  int converged = 0;
};

TEST(PriorPoseRefiner, GivenExactPosesThenTheyAreHardlyMoved) {
  const Scene& s = scene();
  const PriorMapUpdaterConfig uc;
  FreeSpaceCarver carver = make_prior_carver(s, uc);
  const PriorView view{&carver, s.T_prior_segment};
  auto refiner = PriorPoseRefiner::create(uc.refine, s.K);
  ASSERT_TRUE(refiner.ok()) << refiner.status().message();
  RefinerRun run;
  for (const CurrentFrame& f : s.current) {
    PriorPoseGuess guess;
    guess.T_prior_cam = guess.T_prior_cam_anchor = f.T_prior_cam_true;
    auto r = refiner->refine(&view, 1, f.depth_m, guess);
    ASSERT_TRUE(r.ok()) << r.status().message();
    run.converged += r->result == PoseRefinement::kConverged ? 1 : 0;
    const Eigen::Isometry3d d = f.T_prior_cam_true.inverse() * r->T_prior_cam;
    run.worst_m = std::max(run.worst_m, d.translation().norm());
    run.worst_deg = std::max(run.worst_deg, Eigen::AngleAxisd(d.linear()).angle() / kDeg);
  }
  std::printf("[ refine   ] exact poses: %d of %zu converged, moved at most %.2f mm / %.3f deg\n",
              run.converged, s.current.size(), run.worst_m * 1e3, run.worst_deg);
  EXPECT_GE(run.converged, 10);
  // Measured: 1.83 mm / 0.058 deg (the noise of one view's estimate along its weaker directions).
  EXPECT_LE(run.worst_m, 0.002);
  EXPECT_LE(run.worst_deg, 0.1);
}

// Fail closed: each way a refinement can fail returns the guess unchanged (the carver's pose check
// then decides), and a configuration that could never converge is refused.
TEST(PriorPoseRefiner, GivenATooLargeCorrectionTooFewRaysOrNoConvergenceThenTheGuessComesBackUnchanged) {
  const Scene& s = scene();
  const PriorMapUpdaterConfig uc;
  FreeSpaceCarver carver = make_prior_carver(s, uc);
  const PriorView view{&carver, s.T_prior_segment};
  auto refine_with = [&](PriorPoseRefinerConfig c, const CurrentFrame& f, const PriorPoseGuess& guess) {
    auto refiner = PriorPoseRefiner::create(c, s.K);
    EXPECT_TRUE(refiner.ok()) << refiner.status().message();
    auto r = refiner->refine(&view, 1, f.depth_m, guess);
    EXPECT_TRUE(r.ok()) << r.status().message();
    return *r;
  };
  // The first view whose 2 cm / 0.3 deg error the default configuration corrects.
  const CurrentFrame* frame = nullptr;
  PriorPoseGuess guess;
  for (const CurrentFrame& f : s.current) {
    guess.T_prior_cam = guess.T_prior_cam_anchor = relocalization_error() * f.T_prior_cam_true;
    if (refine_with(uc.refine, f, guess).result == PoseRefinement::kConverged) {
      frame = &f;
      break;
    }
  }
  ASSERT_NE(frame, nullptr);
  auto expect_guess_back = [&](const char* what, const PriorPoseRefinement& r, PoseRefinement expected) {
    EXPECT_EQ(r.result, expected) << what << ": " << to_string(r.result);
    EXPECT_TRUE(r.T_prior_cam.isApprox(guess.T_prior_cam, 0.0)) << what;
  };
  PriorPoseRefinerConfig c = uc.refine;
  c.max_correction_m = 1e-4;  // the correction it found is ~2 cm
  const PriorPoseRefinement too_large = refine_with(c, *frame, guess);
  expect_guess_back("1e-4 m limit", too_large, PoseRefinement::kTooLarge);
  EXPECT_GT(too_large.correction_m, 1e-4);
  c = uc.refine;
  c.min_rays = 1'000'000;  // more rays than the image has
  expect_guess_back("1e6 rays", refine_with(c, *frame, guess), PoseRefinement::kTooFewRays);
  c = uc.refine;
  c.max_iterations = c.min_iterations = 1;  // one 2 cm step is not a converged one
  expect_guess_back("one iteration", refine_with(c, *frame, guess), PoseRefinement::kNotConverged);
  c = uc.refine;
  c.min_iterations = c.max_iterations + 1;
  EXPECT_FALSE(PriorPoseRefiner::create(c, s.K).ok());
  c = uc.refine;
  c.min_rays = 0;
  EXPECT_FALSE(PriorPoseRefiner::create(c, s.K).ok());
}

// From the relocalization-sized error, per view: the error that is left along each direction the
// view constrains to sigma <= 1 mm (eigenvectors of the returned information, the rotation scaled
// by the refiner's lever) is within 2 mm, where it was up to ~5 cm.
TEST(PriorPoseRefiner, GivenARelocalizationSizedErrorThenTheConstrainedDirectionsAreRecovered) {
  const Scene& s = scene();
  const PriorMapUpdaterConfig uc;
  FreeSpaceCarver carver = make_prior_carver(s, uc);
  const PriorView view{&carver, s.T_prior_segment};
  auto refiner = PriorPoseRefiner::create(uc.refine, s.K);
  ASSERT_TRUE(refiner.ok());
  const Eigen::Isometry3d error = relocalization_error();
  double worst_before_m = 0, worst_after_m = 0;
  int converged = 0, directions = 0;
  for (const CurrentFrame& f : s.current) {
    PriorPoseGuess guess;
    guess.T_prior_cam = guess.T_prior_cam_anchor = error * f.T_prior_cam_true;
    auto r = refiner->refine(&view, 1, f.depth_m, guess);
    ASSERT_TRUE(r.ok()) << r.status().message();
    if (r->result != PoseRefinement::kConverged) continue;
    ++converged;
    // Errors as xi in the camera frame (T_true = T * exp(xi)), rotation scaled by the lever.
    const double lever = uc.refine.lever_m;
    auto scaled_xi = [&](const Eigen::Isometry3d& T) {
      const Eigen::Isometry3d d = T.inverse() * f.T_prior_cam_true;
      const Eigen::AngleAxisd aa(d.linear());
      Eigen::Matrix<double, 6, 1> xi;
      xi.head<3>() = lever * aa.angle() * aa.axis();
      xi.tail<3>() = d.translation();
      return xi;
    };
    Eigen::Matrix<double, 6, 1> S;
    S << 1 / lever, 1 / lever, 1 / lever, 1, 1, 1;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(S.asDiagonal() * r->information *
                                                                         S.asDiagonal());
    for (int k = 0; k < 6; ++k) {
      if (!(eig.eigenvalues()(k) >= 1.0 / (0.001 * 0.001))) continue;  // sigma <= 1 mm
      ++directions;
      const Eigen::Matrix<double, 6, 1> u = eig.eigenvectors().col(k);
      worst_before_m = std::max(worst_before_m, std::abs(u.dot(scaled_xi(guess.T_prior_cam))));
      worst_after_m = std::max(worst_after_m, std::abs(u.dot(scaled_xi(r->T_prior_cam))));
    }
  }
  std::printf(
      "[ refine   ] 2 cm / 0.3 deg: %d of %zu converged; along %d well-constrained directions the error "
      "went from at most %.1f mm to %.2f mm\n",
      converged, s.current.size(), directions, worst_before_m * 1e3, worst_after_m * 1e3);
  EXPECT_GE(converged, 10);
  EXPECT_GE(directions, 2 * converged);
  EXPECT_GE(worst_before_m, 0.01);
  EXPECT_LE(worst_after_m, 0.002);
}

// Which prior segment a keyframe opens when there are more in range than slots: the one whose
// keyframes looked where this camera looks. Two segments hold the same points (ghost included) and
// keyframes at the same places, both boxes hold every camera; the decoy, segment 0, has its
// keyframes turned to look back. With one slot the update opens segment 1 only and deletes the ghost
// there. (By box distance alone both tie at 0 and the lower id, the decoy, won.)
TEST(PriorMapUpdater, GivenMoreSegmentsInRangeThanSlotsThenTheOneThatLookedAtTheViewIsOpened) {
  const Scene& s = scene();
  const SegmentRecord decoy = turned_copy(s.record, 0, 180.0);
  SegmentRecord real = s.record;
  real.segment_id = 1;
  const std::string dir = write_store(s, "two_segments", {decoy, real});

  PriorMapUpdaterConfig config;
  config.max_open_segments = 1;
  Collect sink;
  PriorMapUpdaterCounters counters;
  ASSERT_NO_FATAL_FAILURE(run_updater(s, dir, config, &sink, &counters));
  EXPECT_EQ(counters.segments_opened, 1u);
  ASSERT_EQ(sink.segments.size(), 1u);
  EXPECT_EQ(sink.segments[0].segment_id, 1u);
  EXPECT_LT(ghost_points_in(s, sink.segments[0]), s.ghost_points / 2);
  config.look_ahead_m = -1;
  EXPECT_EQ(PriorMapUpdater::create(dir, config, s.K).status().code(), core::ErrorCode::kInvalidArgument);
}

// Ranking by what the segments' keyframes saw (view samples), not only where they looked: the
// target segment's keyframes stood 4 m to the side looking at the current view (their look-at
// points 2.8 m from where the cameras of the walk look), the decoy's at the cameras turned 90 deg
// (look-at points 1.5 m to the side of the walk, nothing of the current view in their images). In the lab
// revisit the segments of the first run's first pass by the moved plate had looked at it from elsewhere and
// were never opened while it was in view (docs/prior_map_update.md). One slot: the target must
// be opened and its ghost deleted; ranked by look-at alone the decoy is.
TEST(PriorMapUpdater, GivenASegmentThatSawTheViewFromFartherBackThenItIsOpenedBeforeOneThatLookedNearer) {
  const Scene& s = scene();
  const SegmentRecord decoy = turned_copy(s.record, 0, 90.0);
  SegmentRecord target = s.record;
  target.segment_id = 1;
  for (StoredKeyframe& kf : target.keyframes) {
    // 4 m to the camera's right, turned to look at where it looked (1.5 m ahead): the view is in its
    // image, its own look-at point 2.8 m from the original one.
    const Eigen::Vector3d eye = kf.T_world_cam * Eigen::Vector3d(4.0, 0.0, 0.0);
    const Eigen::Vector3d z = (kf.T_world_cam * Eigen::Vector3d(0.0, 0.0, 1.5) - eye).normalized();
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();  // world z is up
    kf.T_world_cam.linear().col(0) = x;
    kf.T_world_cam.linear().col(1) = z.cross(x);
    kf.T_world_cam.linear().col(2) = z;
    kf.T_world_cam.translation() = eye;
  }
  const std::string dir = write_store(s, "seen_from_back", {decoy, target});
  for (const bool by_view_samples : {true, false}) {
    PriorMapUpdaterConfig config;
    config.max_open_segments = 1;
    config.rank_by_view_samples = by_view_samples;
    Collect sink;
    PriorMapUpdaterCounters counters;
    ASSERT_NO_FATAL_FAILURE(run_updater(s, dir, config, &sink, &counters));
    int target_ghost_left = s.ghost_points;
    for (const SegmentRecord& seg : sink.segments) {
      if (seg.segment_id == 1) target_ghost_left = ghost_points_in(s, seg);
    }
    std::printf("[ update   ] ranked by %s: %zu segments updated, target's ghost %d -> %d\n",
                by_view_samples ? "view samples" : "look-at alone", sink.segments.size(), s.ghost_points,
                target_ghost_left);
    if (by_view_samples) {
      EXPECT_EQ(counters.segments_opened, 1u);
      EXPECT_LT(target_ghost_left, s.ghost_points / 2);
    } else {
      EXPECT_EQ(target_ghost_left, s.ghost_points) << "control: the decoy is opened instead";
    }
  }
}

// Two prior segments of the same place that disagree by 8 mm (the second one's frame, keyframes and
// all, 8 mm higher): in the lab revisit overlapping segments disagree by up to 1.3 cm / 0.19 deg at
// the camera, more than the pose check allows (2 mm). The joint refinement settles between them
// and fails the check in at least one; refined against each segment alone (refine_per_segment),
// each is carved with its own pose and both ghosts go.
TEST(PriorMapUpdater, GivenTwoSegmentsThatDisagreeByMillimetresThenEachIsCarvedWithItsOwnPose) {
  const Scene& s = scene();
  SegmentRecord a = s.record;
  a.segment_id = 0;
  SegmentRecord b = s.record;
  b.segment_id = 1;
  const Eigen::Isometry3d up(Eigen::Translation3d(0.0, 0.0, 0.008));
  b.T_world_segment = up * b.T_world_segment;
  for (StoredKeyframe& kf : b.keyframes) kf.T_world_cam = up * kf.T_world_cam;
  const std::string dir = write_store(s, "disagreeing", {a, b});
  for (const bool per_segment : {true, false}) {
    PriorMapUpdaterConfig config;
    config.refine_per_segment = per_segment;
    Collect sink;
    PriorMapUpdaterCounters counters;
    ASSERT_NO_FATAL_FAILURE(run_updater(s, dir, config, &sink, &counters));
    int ghost_left[2] = {s.ghost_points, s.ghost_points};
    int static_lost[2] = {0, 0};
    for (const SegmentRecord& seg : sink.segments) {
      ASSERT_LT(seg.segment_id, 2u);
      const int ghost = ghost_points_in(s, seg);
      const int kept = static_cast<int>(seg.points_segment.size());
      ghost_left[seg.segment_id] = ghost;
      static_lost[seg.segment_id] = (s.total_points - s.ghost_points) - (kept - ghost);
    }
    std::printf(
        "[ update   ] %s: ghosts %d -> %d and %d, static points lost %d and %d (of %d near the cameras); "
        "views carved %llu, failed the check %llu, segment poses %llu\n",
        per_segment ? "per segment" : "joint pose only", s.ghost_points, ghost_left[0], ghost_left[1],
        static_lost[0], static_lost[1], s.static_points_near,
        static_cast<unsigned long long>(counters.frames_carved),
        static_cast<unsigned long long>(counters.frames_misaligned),
        static_cast<unsigned long long>(counters.segment_poses_refined));
    if (per_segment) {
      for (int i = 0; i < 2; ++i) {
        EXPECT_LT(ghost_left[i], s.ghost_points / 3) << "segment " << i;
        EXPECT_LE(static_lost[i], 0.01 * s.static_points_near) << "segment " << i;
      }
    } else {
      EXPECT_GT(std::max(ghost_left[0], ghost_left[1]), s.ghost_points / 3)
          << "control: the joint pose cannot carve both";
    }
  }
}

TEST(PriorMapUpdater, GivenBadInputsThenClearErrors) {
  const Scene& s = scene();
  auto missing = PriorMapUpdater::create(s.tmp.path() + "/nothing", {}, s.K);
  ASSERT_FALSE(missing.ok());
  auto u = PriorMapUpdater::create(s.prior_dir, {}, s.K);
  ASSERT_TRUE(u.ok());
  cv::Mat depth16(s.K.height, s.K.width, CV_16UC1, cv::Scalar(1000));
  const core::Status st = u->observe(depth16, s.current[0].T_prior_cam_true, nullptr);
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
  PriorMapUpdaterConfig bad;
  bad.max_open_segments = 0;
  EXPECT_FALSE(PriorMapUpdater::create(s.prior_dir, bad, s.K).ok());
  bad = {};
  bad.carried_information = 1.5;
  EXPECT_EQ(PriorMapUpdater::create(s.prior_dir, bad, s.K).status().code(),
            core::ErrorCode::kInvalidArgument);
  bad = {};
  bad.refine.min_eigen_ratio = 0.0;
  EXPECT_EQ(PriorMapUpdater::create(s.prior_dir, bad, s.K).status().code(),
            core::ErrorCode::kInvalidArgument);
  // The refiner's own input checks.
  auto refiner = PriorPoseRefiner::create({}, s.K);
  ASSERT_TRUE(refiner.ok());
  PriorView no_carver;
  EXPECT_EQ(refiner->refine(&no_carver, 1, s.current[0].depth_m, {}).status().code(),
            core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(refiner->refine(nullptr, 1, s.current[0].depth_m, {}).status().code(),
            core::ErrorCode::kInvalidArgument);
  PriorPoseGuess nan_guess;
  nan_guess.information(0, 0) = std::nan("");
  EXPECT_EQ(refiner->refine(nullptr, 0, s.current[0].depth_m, nan_guess).status().code(),
            core::ErrorCode::kInvalidArgument);
  auto off = refiner->refine(nullptr, 0, s.current[0].depth_m, {});
  ASSERT_TRUE(off.ok());
  EXPECT_EQ(off->result, PoseRefinement::kOff);
  // refine_again needs the planes of a refine() that measured some: none yet, the guess comes back.
  EXPECT_EQ(refiner->plane_count(), 0);
  EXPECT_EQ(refiner->refine_again(&no_carver, 1, {}).status().code(), core::ErrorCode::kInvalidArgument);
  FreeSpaceCarver carver = make_prior_carver(s, {});
  const PriorView view{&carver, s.T_prior_segment};
  auto again = refiner->refine_again(&view, 1, {});
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->result, PoseRefinement::kOff);
}

}  // namespace
}  // namespace hwr::recon
