// The welding regions' reconstruction error (recon/region_ae.hpp) and the simulator-truth detections
// (recon/truth_weld_regions.hpp). Oracles: a plate pair sampled from known geometry and fitted in
// the truth's frame (fit_plate with the truth's ROI) against the same points carried into a drifted
// map frame and a segment frame, measured through a region: the dimensions must agree exactly and
// the local placement must remove the drift from the corners; closed-form box extents, visibility
// and interpolated poses.

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/recon/region_ae.hpp"
#include "hwr/recon/truth_weld_regions.hpp"
#include "plate_truth.hpp"

namespace hwr::recon {
namespace {

Eigen::Isometry3d pose(const Eigen::Vector3d& t, double yaw, double pitch = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  T.translation() = t;
  return T;
}

using hwr::testing::make_plate;

// Two butt plates side by side on a bench, a third plate far away (no region holds it), and dense
// samples (1.5 mm, 0.5 mm noise) of the pair's top faces and the bench around them.
struct World {
  WeldGroundTruth gt;
  std::vector<CloudPoint> points_world;
};

World butt_world() {
  World w;
  const Eigen::Isometry3d T_world_joint = pose(Eigen::Vector3d(2.0, 1.0, 0.85), 0.4);
  w.gt.plates = {
      make_plate("j/left", {0.5, 0.25, 0.01}, T_world_joint * pose(Eigen::Vector3d(0, 0.1265, -0.005), 0)),
      make_plate("j/right", {0.5, 0.25, 0.01}, T_world_joint * pose(Eigen::Vector3d(0, -0.1265, -0.005), 0)),
      make_plate("far/base", {0.4, 0.2, 0.01}, pose(Eigen::Vector3d(9, 9, 0.005), 0))};
  SeamTruth seam;
  seam.name = "j";
  seam.type = SeamType::kButt;
  seam.plates = {"j/left", "j/right"};
  SeamTruth far;
  far.name = "far";
  far.plates = {"far/base", "far/base"};
  w.gt.seams = {seam, far};
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.0005);
  for (double x = -0.35; x <= 0.35; x += 0.0015)
    for (double y = -0.35; y <= 0.35; y += 0.0015) {
      // Top faces at z = 0 of the joint frame; the bench 1 cm lower elsewhere (and in the gap).
      const bool on_plate = std::fabs(x) <= 0.25 && std::fabs(y) >= 0.0015 && std::fabs(y) <= 0.2515;
      const Eigen::Vector3d p = T_world_joint * Eigen::Vector3d(x, y, on_plate ? 0.0 : -0.01) +
                                Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      CloudPoint c;
      c.x_m = static_cast<float>(p.x()), c.y_m = static_cast<float>(p.y()), c.z_m = static_cast<float>(p.z());
      w.points_world.push_back(c);
    }
  return w;
}

TEST(RegionAe, GivenADriftedMapThenEachPlateIsMeasuredInTheRoiItsDetectionPlacedWithTheTruthsDimensions) {
  const World w = butt_world();
  const auto boxes = truth_joint_boxes(w.gt, 0.05);
  ASSERT_EQ(boxes.size(), 2u);
  // The camera that detects the joint (true pose), and the map's drift at that place.
  const int64_t t_ns = 5'000'000'000;
  const Eigen::Isometry3d T_world_cam_true = pose(Eigen::Vector3d(1.0, 0.2, 1.5), 0.6, 0.5);
  const Eigen::Isometry3d T_map_world = pose(Eigen::Vector3d(0.03, -0.02, 0.01), 0.01);  // 3.6 cm, 0.6 deg
  const Eigen::Isometry3d T_map_segment = pose(Eigen::Vector3d(1.5, 0.5, 1.2), -0.3);
  const Eigen::Isometry3d T_segment_map = T_map_segment.inverse();

  StoredWeldRegion region;
  region.region.id = 4;
  region.region.source = WeldRegionSource::kSimTruth;
  set_weld_region_label(&region.region, boxes[0].joint);
  region.region.t_ns = t_ns;
  region.region.T_cam_region = T_world_cam_true.inverse() * boxes[0].T_world_box;
  region.region.half_size_m = boxes[0].half_size_m;
  // The map placed the detection with its estimated camera pose, T_map_world * T_world_cam_true.
  region.T_segment_region = T_segment_map * T_map_world * boxes[0].T_world_box;
  region.fine_points = static_cast<int64_t>(w.points_world.size());
  region.viewpoint_segment = T_segment_map * T_map_world * T_world_cam_true.translation();
  const std::vector<StoredWeldRegion> regions = {region};
  std::vector<CloudPoint> points_segment;
  std::vector<uint32_t> counts;
  for (const CloudPoint& p : w.points_world) {
    const Eigen::Vector3d q = T_segment_map * T_map_world * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
    CloudPoint c = p;
    c.x_m = static_cast<float>(q.x()), c.y_m = static_cast<float>(q.y()), c.z_m = static_cast<float>(q.z());
    points_segment.push_back(c);
    counts.push_back(1);
  }
  const std::vector<core::StampedPose> truth = {{t_ns - 20'000'000, T_world_cam_true},
                                                {t_ns + 20'000'000, T_world_cam_true}};
  RegionAeConfig config;
  config.use_viewpoints = false;  // noise-free rays: the viewpoint changes nothing to compare
  auto rep = compute_region_ae({{&regions, &points_segment, &counts, T_map_segment}}, w.gt, truth, config);
  ASSERT_TRUE(rep.ok()) << rep.status().message();
  EXPECT_EQ(rep->regions, 1);
  EXPECT_EQ(rep->plates_in_regions, 2);
  EXPECT_EQ(rep->fine_points, static_cast<int64_t>(w.points_world.size()));
  // The far plate: no region holds it.
  EXPECT_FALSE(rep->ae.plates[2].seen);
  EXPECT_EQ(rep->plates[2].region_id, -1);
  EXPECT_EQ(rep->plates[2].fit.reason, "no welding region holds it");
  // Oracle: the same points fitted in the truth's own frame with the truth's ROIs.
  for (size_t i = 0; i < 2; ++i) {
    auto direct =
        fit_plate(w.points_world.data(), w.points_world.size(), plate_roi_from_truth(w.gt, i), config.fit);
    ASSERT_TRUE(direct.ok() && direct->seen);
    const PlateAe& a = rep->ae.plates[i];
    ASSERT_TRUE(a.seen) << a.reason;
    EXPECT_EQ(rep->plates[i].region_id, 4);
    EXPECT_EQ(rep->plates[i].region_label, "j");
    EXPECT_NEAR(a.length_m, direct->length_m, 2e-5);  // float32 points moved through two frames
    EXPECT_NEAR(a.width_m, direct->width_m, 2e-5);
    EXPECT_LT(std::fabs(a.length_m - 0.5), 0.002);
    // The drift is 3.6 cm; corners measured against the locally placed truth see none of it.
    EXPECT_LT(a.mean_corner_error_mm, 2.0);
  }
  // The same map placed through the drift, but the truth pose of the detection missing: nothing held.
  auto no_truth = compute_region_ae({{&regions, &points_segment, &counts, T_map_segment}}, w.gt,
                                    {{t_ns + 1'000'000'000, T_world_cam_true}}, config);
  ASSERT_TRUE(no_truth.ok());
  EXPECT_EQ(no_truth->plates_in_regions, 0);
  EXPECT_EQ(no_truth->ae.plates_seen, 0);
  // Bad views.
  const std::vector<uint32_t> short_counts(3, 1);
  EXPECT_EQ(
      compute_region_ae({{&regions, &points_segment, &short_counts, T_map_segment}}, w.gt, truth, config)
          .status()
          .code(),
      core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(compute_region_ae({{nullptr, &points_segment, &counts, T_map_segment}}, w.gt, truth, config)
                .status()
                .code(),
            core::ErrorCode::kInvalidArgument);
}

TEST(TruthWeldRegions, GivenAJointThenItsBoxHoldsBothPlatesAndItIsDetectedOnlyInViewAndInRange) {
  const World w = butt_world();
  const auto boxes = truth_joint_boxes(w.gt, 0.05);
  ASSERT_EQ(boxes.size(), 2u);
  EXPECT_EQ(boxes[0].joint, "j");
  // Every corner of both plates inside the box, 5 cm from its faces at the plates' extremes.
  const Eigen::Isometry3d T_box_world = boxes[0].T_world_box.inverse();
  double slack = 1e9;
  for (size_t i = 0; i < 2; ++i)
    for (const Eigen::Vector3d& c : w.gt.plates[i].corners_world) {
      const Eigen::Vector3d q = (T_box_world * c).cwiseAbs();
      slack = std::min(slack, (boxes[0].half_size_m - q).minCoeff());
      EXPECT_TRUE((q.array() <= boxes[0].half_size_m.array() + 1e-12).all());
    }
  EXPECT_NEAR(slack, 0.05, 1e-9);
  // Box extents: 0.5 + 0.1 along the seam, 2 x 0.25 + 0.003 + 0.1 across, 0.01 + 0.1 thick.
  EXPECT_NEAR(2 * boxes[0].half_size_m.x(), 0.6, 1e-9);
  EXPECT_NEAR(2 * boxes[0].half_size_m.y(), 0.603, 1e-9);
  EXPECT_NEAR(2 * boxes[0].half_size_m.z(), 0.11, 1e-9);

  hal::PinholeIntrinsics K;
  K.width = 640, K.height = 480, K.fx = K.fy = 525, K.cx = 319.5, K.cy = 239.5;
  // A camera 2 m from the joint looking at it (z towards the joint centre).
  const Eigen::Vector3d c = boxes[0].T_world_box.translation();
  const Eigen::Vector3d eye = c + Eigen::Vector3d(0, -1.6, 1.2);
  Eigen::Matrix3d R;
  R.col(2) = (c - eye).normalized();
  R.col(0) = R.col(2).cross(Eigen::Vector3d::UnitZ()).normalized();
  R.col(1) = R.col(2).cross(R.col(0));
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  T_world_cam.linear() = R;
  T_world_cam.translation() = eye;
  std::vector<WeldRegion> seen;
  truth_detections(boxes, T_world_cam, K, 0.3, 4.0, 12, 77, &seen);
  ASSERT_EQ(seen.size(), 1u);  // the far plate is 10 m away and behind
  EXPECT_EQ(weld_region_label(seen[0]), "j");
  EXPECT_EQ(seen[0].source, WeldRegionSource::kSimTruth);
  EXPECT_EQ(seen[0].keyframe_id, 12);
  EXPECT_EQ(seen[0].t_ns, 77);
  EXPECT_TRUE((T_world_cam * seen[0].T_cam_region).isApprox(boxes[0].T_world_box, 1e-12));
  EXPECT_NEAR(seen[0].T_cam_region.translation().z(), 2.0, 1e-9);
  truth_detections(boxes, T_world_cam, K, 0.3, 1.9, 12, 77, &seen);  // out of range
  EXPECT_TRUE(seen.empty());
  Eigen::Isometry3d turned = T_world_cam;
  turned.linear() = R * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitY()).toRotationMatrix();  // 40 deg aside
  truth_detections(boxes, turned, K, 0.3, 4.0, 12, 77, &seen);
  EXPECT_TRUE(seen.empty());
}

TEST(TruthWeldRegions, GivenATrajectoryThenPosesAreInterpolatedOnlyInsideItAndAcrossSmallGaps) {
  const std::vector<core::StampedPose> traj = {{100, pose(Eigen::Vector3d(0, 0, 0), 0.0)},
                                               {200, pose(Eigen::Vector3d(1, 0, 0), 0.2)},
                                               {1000, pose(Eigen::Vector3d(2, 0, 0), 0.2)}};
  Eigen::Isometry3d T;
  ASSERT_TRUE(truth_pose_at(traj, 150, 500, &T));
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(0.5, 0, 0), 1e-12));
  EXPECT_NEAR(Eigen::AngleAxisd(T.linear()).angle(), 0.1, 1e-12);
  ASSERT_TRUE(truth_pose_at(traj, 200, 10, &T));  // an exact sample needs no neighbour
  EXPECT_TRUE(T.isApprox(traj[1].T_world_body, 1e-15));
  EXPECT_FALSE(truth_pose_at(traj, 600, 500, &T));  // the samples around it are 800 ns apart
  EXPECT_TRUE(truth_pose_at(traj, 600, 800, &T));
  EXPECT_FALSE(truth_pose_at(traj, 50, 500, &T));
  EXPECT_FALSE(truth_pose_at(traj, 1001, 500, &T));
  EXPECT_FALSE(truth_pose_at({}, 100, 500, &T));
}

}  // namespace
}  // namespace hwr::recon
