// RelocalizationWorker: attempts run on the worker thread against a prior map written from rendered
// sim lab keyframes; the scheduler-side calls never block or allocate, attempts are spaced by the
// motion rule, and a success fixes T_prior_world.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "sim_frames.hpp"
#include "temp_dir.hpp"
#include "hwr/core/alloc_counter.hpp"
#include "hwr/core/arena.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/map_store.hpp"
#include "hwr/recon/prior_map.hpp"
#include "hwr/recon/relocalization_worker.hpp"
#include "hwr/recon/voxel_map.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"

namespace hwr::recon {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr int kMaxFeatures = 800;

struct Rendered {
  hal::PinholeIntrinsics K;
  std::string prior_dir;
  // The query: its keyframe's features and pose, and its local map, in a current world frame placed
  // by kT_prior_world.
  std::unique_ptr<estimation::FrameFeatures> features;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::unique_ptr<VoxelMap> local_map;
  std::unique_ptr<estimation::FrameFeatures> outdoor_features;
  std::unique_ptr<VoxelMap> outdoor_map;
  Eigen::Isometry3d T_world_cam_outdoor = Eigen::Isometry3d::Identity();
};

Eigen::Isometry3d known_T_prior_world() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(-25.0 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(-2.0, 1.5, 0.0);
  return T;
}

// Renders frames of `scenario`; with `store` each keyframe goes into a segment of the store (one
// segment, truth poses, 2 cm voxels), else into `map` (5 cm voxels, moved by T_world_truth) and the
// last one's features into `features`.
void render(const std::string& scenario, size_t first, size_t last, size_t step, MapStore* store,
            const Eigen::Isometry3d& T_world_truth, VoxelMap* map, estimation::FrameFeatures* features,
            Eigen::Isometry3d* T_world_cam, hal::PinholeIntrinsics* K_out) {
  std::unique_ptr<estimation::GridOrbExtractor> orb;
  std::unique_ptr<estimation::FrameFeatures> kf_features;
  std::unique_ptr<core::Arena> arena;
  KeyframeCloudConfig cloud_config;
  auto voxels = VoxelMap::create({0.02, 1'000'000});
  ASSERT_TRUE(voxels.ok());
  cv::Mat gray;
  SegmentRecord seg;
  hwr::testing::for_each_sim_frame(
      scenario, first, last, step,
      [&](size_t, const hal::RgbdFrame& f, const Eigen::Isometry3d& T_truth_cam,
          const hal::PinholeIntrinsics& K) {
        if (!orb) {
          if (K_out != nullptr) *K_out = K;
          estimation::OrbConfig ocfg;
          ocfg.max_features = kMaxFeatures;
          orb = std::make_unique<estimation::GridOrbExtractor>(ocfg, K.width, K.height);
          kf_features = std::make_unique<estimation::FrameFeatures>(kMaxFeatures, K.width, K.height);
          arena =
              std::make_unique<core::Arena>(keyframe_cloud_capacity_bytes(K.width, K.height, cloud_config));
        }
        cv::cvtColor(f.bgr, gray, cv::COLOR_BGR2GRAY);
        ASSERT_TRUE(orb->extract(gray, f.depth_m, K, kf_features.get()).ok());
        arena->reset();
        if (store != nullptr) {
          if (seg.keyframes.empty()) seg.T_world_segment = T_truth_cam;
          auto cloud = build_keyframe_cloud(f.bgr, f.depth_m, K, seg.T_world_segment.inverse() * T_truth_cam,
                                            cloud_config, arena.get());
          ASSERT_TRUE(cloud.ok());
          voxels->insert(cloud.value());
          seg.keyframes.push_back(hwr::testing::stored_keyframe(
              *kf_features, T_truth_cam, static_cast<int32_t>(seg.keyframes.size()), f.t_ns));
        } else {
          const Eigen::Isometry3d T_world_cam_i = T_world_truth * T_truth_cam;
          auto cloud = build_keyframe_cloud(f.bgr, f.depth_m, K, T_world_cam_i, cloud_config, arena.get());
          ASSERT_TRUE(cloud.ok());
          map->insert(cloud.value());
          *features = *kf_features;
          *T_world_cam = T_world_cam_i;
        }
      });
  if (store != nullptr) {
    hwr::testing::append_voxel_points(voxels.value(), &seg.points_segment);
    ASSERT_TRUE(store->write_segment(seg).ok());
  }
}

const Rendered& rendered() {
  static hwr::testing::TempDir tmp("hwr_reloc_worker");
  static const Rendered* r = [] {
    auto* out = new Rendered;
    out->prior_dir = tmp.path() + "/prior";
    StoreMetadata meta;
    meta.run_id = "worker-prior";
    auto lab = sim::load_scenario("lab");
    EXPECT_TRUE(lab.ok());
    meta.intrinsics = lab->camera.intrinsics;
    auto store = MapStore::open(out->prior_dir, meta);
    EXPECT_TRUE(store.ok());
    render("lab", 1230, 1530, 12, &store.value(), Eigen::Isometry3d::Identity(), nullptr, nullptr, nullptr,
           &out->K);
    out->features = std::make_unique<estimation::FrameFeatures>(kMaxFeatures, out->K.width, out->K.height);
    out->outdoor_features =
        std::make_unique<estimation::FrameFeatures>(kMaxFeatures, out->K.width, out->K.height);
    out->local_map = std::make_unique<VoxelMap>(VoxelMap::create({0.05, 400'000}).value());
    out->outdoor_map = std::make_unique<VoxelMap>(VoxelMap::create({0.05, 400'000}).value());
    // Half a step after the prior's keyframes: never the same image. The current world is the prior
    // moved by kT_prior_world^-1.
    render("lab", 1326 + 6, 1420, 12, nullptr, known_T_prior_world().inverse(), out->local_map.get(),
           out->features.get(), &out->T_world_cam, nullptr);
    render("outdoor", 600, 700, 12, nullptr, Eigen::Isometry3d::Identity(), out->outdoor_map.get(),
           out->outdoor_features.get(), &out->T_world_cam_outdoor, nullptr);
    return out;
  }();
  return *r;
}

std::unique_ptr<RelocalizationWorker> start_worker(const Rendered& r, RelocalizationWorkerConfig config) {
  auto prior = PriorMap::open(r.prior_dir);
  EXPECT_TRUE(prior.ok()) << prior.status().message();
  auto w = RelocalizationWorker::start(std::move(prior.value()), config, r.K, kMaxFeatures);
  EXPECT_TRUE(w.ok()) << w.status().message();
  return std::move(w.value());
}

TEST(RelocalizationWorker, GivenAQueryInsideThePriorThenTheWorkerLocalizesOffTheCallersThread) {
  const Rendered& r = rendered();
  RelocalizationWorkerConfig config;
  config.first_attempt_m = 1.0;
  auto w = start_worker(r, config);
  w->wait_idle();  // the appearance index is built
  const RelocalizationPriors none;
  EXPECT_FALSE(w->offer(*r.features, r.T_world_cam, *r.local_map, Eigen::Isometry3d::Identity(), 0.5, none))
      << "taken before first_attempt_m of motion";
  bool taken = false;
  {
    core::AllocationScope scope;
    taken = w->offer(*r.features, r.T_world_cam, *r.local_map, Eigen::Isometry3d::Identity(), 1.2, none);
    EXPECT_EQ(scope.allocations(), 0u) << "offer() copies into buffers sized at start()";
  }
  ASSERT_TRUE(taken);
  EXPECT_FALSE(w->offer(*r.features, r.T_world_cam, *r.local_map, Eigen::Isometry3d::Identity(), 5.0, none))
      << "an attempt is running (or has localized): nothing more is taken";
  w->wait_idle();
  const RelocalizationWorkerStatus s = w->status();
  ASSERT_TRUE(w->localized()) << s.last_message;
  const Eigen::Isometry3d d = known_T_prior_world().inverse() * w->T_prior_world();
  std::printf("[ worker   ] localized in %.2f s: %.2f cm %.3f deg; %s\n", s.wall_s_total,
              d.translation().norm() * 100, Eigen::AngleAxisd(d.linear()).angle() / kDeg,
              s.last_message.c_str());
  EXPECT_LT(d.translation().norm(), 0.03);
  EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 0.3 * kDeg);
  EXPECT_EQ(s.attempts, 1);
  ASSERT_EQ(s.log.size(), 1u);
  EXPECT_DOUBLE_EQ(s.log[0].moved_m, 1.2);
  EXPECT_GT(s.log[0].local_points, 1000);
  EXPECT_DOUBLE_EQ(s.moved_at_localization_m, 1.2);
  EXPECT_FALSE(w->offer(*r.features, r.T_world_cam, *r.local_map, Eigen::Isometry3d::Identity(), 9.0, none))
      << "localized: no more attempts";
}

TEST(RelocalizationWorker, GivenQueriesFromOutsideThePriorThenNotLocalizedAndRetriesFollowTheMotionRule) {
  const Rendered& r = rendered();
  RelocalizationWorkerConfig config;
  config.first_attempt_m = 0.0;
  config.retry_every_m = 2.0;
  auto w = start_worker(r, config);
  w->wait_idle();
  const RelocalizationPriors none;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  ASSERT_TRUE(w->offer(*r.outdoor_features, r.T_world_cam_outdoor, *r.outdoor_map, I, 1.0, none));
  w->wait_idle();
  EXPECT_FALSE(w->localized()) << w->status().last_message;
  EXPECT_FALSE(w->offer(*r.outdoor_features, r.T_world_cam_outdoor, *r.outdoor_map, I, 2.5, none))
      << "less than retry_every_m since the last attempt";
  ASSERT_TRUE(w->offer(*r.outdoor_features, r.T_world_cam_outdoor, *r.outdoor_map, I, 3.0, none));
  w->wait_idle();
  const RelocalizationWorkerStatus s = w->status();
  EXPECT_FALSE(s.localized);
  EXPECT_EQ(s.attempts, 2);
  ASSERT_EQ(s.log.size(), 2u);
  EXPECT_NE(s.log[1].reason, RelocalizationReason::kLocalized);
  EXPECT_FALSE(s.last_message.empty());
  EXPECT_EQ(w->offers_taken(), 2u);
}

// A weak fit without a position prior waits for a later attempt that agrees
// (relocalization_confirmation.hpp). Every fine NDT fit is judged degenerate here, so every fit is a
// weak one (the pose from the ORB fit); the second attempt, from the same view, agrees with the first.
// The same view is the same evidence: with the default min_separation_m it confirms nothing; the
// worker given min_separation_m = 0 takes it as a confirmation.
TEST(RelocalizationWorker, GivenAWeakFitFromTheSameViewAgainThenItStaysPendingUnlessNoSeparationIsAsked) {
  const Rendered& r = rendered();
  RelocalizationWorkerConfig config;
  config.first_attempt_m = 0.0;
  config.retry_every_m = 0.5;
  config.relocalizer.ndt_fine.degenerate_eigenvalue_ratio = 0.99;
  const RelocalizationPriors none;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  {
    auto w = start_worker(r, config);
    w->wait_idle();
    ASSERT_TRUE(w->offer(*r.features, r.T_world_cam, *r.local_map, I, 1.0, none));
    w->wait_idle();
    ASSERT_TRUE(w->offer(*r.features, r.T_world_cam, *r.local_map, I, 1.6, none));
    w->wait_idle();
    const RelocalizationWorkerStatus s = w->status();
    EXPECT_FALSE(w->localized()) << s.last_message;
    ASSERT_EQ(s.log.size(), 2u);
    EXPECT_EQ(s.log[1].reason, RelocalizationReason::kLocalized) << s.last_message;
    EXPECT_TRUE(s.log[1].pending_confirmation);
  }
  config.confirmation.min_separation_m = 0.0;
  auto w = start_worker(r, config);
  w->wait_idle();
  ASSERT_TRUE(w->offer(*r.features, r.T_world_cam, *r.local_map, I, 1.0, none));
  w->wait_idle();
  RelocalizationWorkerStatus s = w->status();
  EXPECT_FALSE(w->localized()) << s.last_message;
  ASSERT_EQ(s.log.size(), 1u);
  EXPECT_EQ(s.log[0].reason, RelocalizationReason::kLocalized) << s.last_message;
  EXPECT_TRUE(s.log[0].pending_confirmation);
  EXPECT_NE(s.last_message.find("pending"), std::string::npos) << s.last_message;
  EXPECT_NE(s.last_message.find("NDT weak"), std::string::npos) << s.last_message;

  ASSERT_TRUE(w->offer(*r.features, r.T_world_cam, *r.local_map, I, 1.6, none));
  w->wait_idle();
  s = w->status();
  ASSERT_TRUE(w->localized()) << s.last_message;
  EXPECT_EQ(s.attempts, 2);
  ASSERT_EQ(s.log.size(), 2u);
  EXPECT_FALSE(s.log[1].pending_confirmation);
  EXPECT_DOUBLE_EQ(s.moved_at_localization_m, 1.6);
  const Eigen::Isometry3d d = known_T_prior_world().inverse() * w->T_prior_world();
  EXPECT_LT(d.translation().norm(), 0.03);
  EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 0.3 * kDeg);
}

TEST(RelocalizationWorker, GivenTheLocalMapInItsSegmentFrameThenOnlyPointsNearTheCameraAreSent) {
  const Rendered& r = rendered();
  RelocalizationWorkerConfig config;
  config.first_attempt_m = 0.0;
  config.local_radius_m = 2.5;  // the lab query's camera sees its points from 1-4 m
  config.max_attempts_logged = 4;
  auto w = start_worker(r, config);
  w->wait_idle();
  // The local map handed over in a segment frame placed at T_world_segment (the map's points moved
  // into it): the points sent are the voxels within the radius of the camera in the world frame.
  Eigen::Isometry3d T_world_segment = Eigen::Isometry3d::Identity();
  T_world_segment.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_world_segment.translation() = Eigen::Vector3d(4.0, -3.0, 0.5);
  auto segment_map = VoxelMap::create({0.05, 400'000});
  ASSERT_TRUE(segment_map.ok());
  std::vector<CloudPoint> moved;
  r.local_map->for_each([&](const Voxel& v) {
    const Eigen::Vector3d p = T_world_segment.inverse() * Eigen::Vector3d(v.x_m, v.y_m, v.z_m);
    CloudPoint c;
    c.x_m = static_cast<float>(p.x());
    c.y_m = static_cast<float>(p.y());
    c.z_m = static_cast<float>(p.z());
    moved.push_back(c);
  });
  segment_map->insert(moved.data(), static_cast<int>(moved.size()));
  ASSERT_TRUE(w->offer(*r.features, r.T_world_cam, segment_map.value(), T_world_segment, 1.0, {}));
  w->wait_idle();
  const int sent = w->status().log.at(0).local_points;
  int expected = 0;
  segment_map->for_each([&](const Voxel& v) {
    const Eigen::Vector3d p_world = T_world_segment * Eigen::Vector3d(v.x_m, v.y_m, v.z_m);
    expected += (p_world - r.T_world_cam.translation()).norm() <= 2.5 ? 1 : 0;
  });
  EXPECT_GT(expected, 100);
  EXPECT_NEAR(sent, expected, 2);  // float rounding at the radius
  EXPECT_LT(sent, segment_map->size() / 2);
}

TEST(RelocalizationWorker, GivenAnInvalidConfigThenStartFails) {
  const Rendered& r = rendered();
  RelocalizationWorkerConfig config;
  config.max_local_points = 0;
  auto prior = PriorMap::open(r.prior_dir);
  ASSERT_TRUE(prior.ok());
  auto w = RelocalizationWorker::start(std::move(prior.value()), config, r.K, kMaxFeatures);
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("max_local_points"), std::string::npos);

  RelocalizationWorkerConfig no_agreement;
  no_agreement.confirmation.agree_m = 0.0;
  auto prior2 = PriorMap::open(r.prior_dir);
  ASSERT_TRUE(prior2.ok());
  auto w2 = RelocalizationWorker::start(std::move(prior2.value()), no_agreement, r.K, kMaxFeatures);
  ASSERT_FALSE(w2.ok());
  EXPECT_NE(w2.status().message().find("agree_m"), std::string::npos);

  RelocalizationWorkerConfig negative_separation;
  negative_separation.confirmation.min_separation_m = -1.0;
  auto prior3 = PriorMap::open(r.prior_dir);
  ASSERT_TRUE(prior3.ok());
  auto w3 = RelocalizationWorker::start(std::move(prior3.value()), negative_separation, r.K, kMaxFeatures);
  ASSERT_FALSE(w3.ok());
  EXPECT_NE(w3.status().message().find("min_separation_m"), std::string::npos);
}

}  // namespace
}  // namespace hwr::recon
