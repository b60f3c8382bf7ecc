// Weld-joint ground truth: plate corners against the closed-form geometry of scene_spec.hpp, and
// against the rendered surfaces (ray casts onto every face next to every corner), seams on both
// plates.

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "hwr/sim/renderer.hpp"
#include "sim_test_util.hpp"

namespace hwr::sim {
namespace {

using testing::pose;

WeldJointSpec fillet(const std::string& name, const Eigen::Isometry3d& T) {
  WeldJointSpec j;
  j.name = name;
  j.type = WeldJointSpec::Type::kFillet;
  j.length_m = 0.5;
  j.base_width_m = 0.25;
  j.web_width_m = 0.15;
  j.thickness_m = 0.012;
  j.T_scene_joint = T;
  return j;
}

WeldJointSpec butt(const std::string& name, const Eigen::Isometry3d& T) {
  WeldJointSpec j;
  j.name = name;
  j.type = WeldJointSpec::Type::kButt;
  j.length_m = 0.4;
  j.base_width_m = 0.2;
  j.thickness_m = 0.008;
  j.gap_m = 0.003;
  j.T_scene_joint = T;
  return j;
}

// Joints hanging in the air, far apart, so that every plate face is in the open.
SceneSpec joints_scene() {
  SceneSpec s;
  s.name = "joints";
  s.has_room = false;
  s.joints.push_back(fillet("tee_a", pose({0.0, 0.0, 1.0}, Eigen::Vector3d::Zero())));
  s.joints.push_back(fillet("tee_b", pose({3.0, -2.0, 1.5}, {0.3, -0.5, 1.1})));
  s.joints.push_back(butt("butt_a", pose({-3.0, 2.0, 1.2}, Eigen::Vector3d::Zero())));
  s.joints.push_back(butt("butt_b", pose({-3.0, -3.0, 1.4}, {-0.7, 0.2, 2.5})));
  return s;
}

const PlateTruth* find_plate(const SceneGroundTruth& truth, const std::string& name) {
  for (const PlateTruth& p : truth.plates) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

// Closed-form corners in the joint frame, written out from the comment in scene_spec.hpp.
TEST(SceneTruth, FilletPlatesMatchSpecGeometry) {
  const WeldJointSpec j = fillet("tee", Eigen::Isometry3d::Identity());
  SceneSpec s;
  s.joints.push_back(j);
  const SceneGroundTruth truth = scene_ground_truth(s);
  ASSERT_EQ(truth.plates.size(), 2u);
  ASSERT_EQ(truth.seams.size(), 1u);
  const PlateTruth* base = find_plate(truth, "tee/base");
  const PlateTruth* web = find_plate(truth, "tee/web");
  ASSERT_TRUE(base && web);
  EXPECT_TRUE(base->size_m.isApprox(Eigen::Vector3d(0.5, 0.25, 0.012)));
  EXPECT_TRUE(web->size_m.isApprox(Eigen::Vector3d(0.5, 0.15, 0.012)));
  // Base: x in [0, L], y in [-bw, 0], z in [-t, 0].
  Eigen::AlignedBox3d base_box(Eigen::Vector3d(0, -0.25, -0.012), Eigen::Vector3d(0.5, 0, 0));
  // Web: x in [0, L], y in [0, t], z in [0, ww].
  Eigen::AlignedBox3d web_box(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.5, 0.012, 0.15));
  for (int i = 0; i < 8; ++i) {
    EXPECT_TRUE(base_box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i))
                    .isApprox(base->corners_scene[((i & 1) << 2) | (i & 2) | ((i & 4) >> 2)], 1e-12))
        << "base corner " << i;
  }
  // The web's frame is rotated (width runs up), so compare corner sets: each web corner is a
  // corner of the web box, and all 8 are distinct.
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d& c = web->corners_scene[i];
    double nearest = 1.0;
    for (int k = 0; k < 8; ++k) {
      nearest =
          std::min(nearest, (web_box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)) - c).norm());
    }
    EXPECT_LT(nearest, 1e-12) << "web corner " << i;
    for (int k = 0; k < i; ++k) EXPECT_GT((c - web->corners_scene[k]).norm(), 1e-6);
  }
  // Corner numbering: bit 2 -> +x, bit 1 -> +y, bit 0 -> +z of the plate frame.
  for (const PlateTruth* p : {base, web}) {
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d local = p->T_scene_plate.inverse() * p->corners_scene[i];
      EXPECT_NEAR(local.x(), ((i & 4) ? 0.5 : -0.5) * p->size_m.x(), 1e-12);
      EXPECT_NEAR(local.y(), ((i & 2) ? 0.5 : -0.5) * p->size_m.y(), 1e-12);
      EXPECT_NEAR(local.z(), ((i & 1) ? 0.5 : -0.5) * p->size_m.z(), 1e-12);
    }
  }
  // The web stands with its +z (thickness) face on the seam side, y = 0.
  EXPECT_NEAR((web->T_scene_plate * Eigen::Vector3d(0, 0, 0.006)).y(), 0.0, 1e-12);
  const SeamTruth& seam = truth.seams[0];
  EXPECT_EQ(seam.name, "tee");
  EXPECT_EQ(seam.type, WeldJointSpec::Type::kFillet);
  EXPECT_TRUE(seam.start_scene.isZero(1e-12));
  EXPECT_TRUE(seam.end_scene.isApprox(Eigen::Vector3d(0.5, 0, 0)));
  EXPECT_EQ(seam.plate_a, "tee/base");
  EXPECT_EQ(seam.plate_b, "tee/web");
}

TEST(SceneTruth, ButtPlatesMatchSpecGeometry) {
  const WeldJointSpec j = butt("bj", Eigen::Isometry3d::Identity());
  SceneSpec s;
  s.joints.push_back(j);
  const SceneGroundTruth truth = scene_ground_truth(s);
  ASSERT_EQ(truth.plates.size(), 2u);
  const PlateTruth* left = find_plate(truth, "bj/left");
  const PlateTruth* right = find_plate(truth, "bj/right");
  ASSERT_TRUE(left && right);
  const double g = 0.003, w = 0.2, t = 0.008, L = 0.4;
  const Eigen::AlignedBox3d left_box(Eigen::Vector3d(0, g / 2, -t), Eigen::Vector3d(L, g / 2 + w, 0));
  const Eigen::AlignedBox3d right_box(Eigen::Vector3d(0, -g / 2 - w, -t), Eigen::Vector3d(L, -g / 2, 0));
  for (int i = 0; i < 8; ++i) {
    const auto corner = static_cast<Eigen::AlignedBox3d::CornerType>(i);
    const int k = ((i & 1) << 2) | (i & 2) | ((i & 4) >> 2);  // Eigen: bit 0 = x; ours: bit 2 = x
    EXPECT_TRUE(left_box.corner(corner).isApprox(left->corners_scene[k], 1e-12)) << i;
    EXPECT_TRUE(right_box.corner(corner).isApprox(right->corners_scene[k], 1e-12)) << i;
  }
  EXPECT_EQ(truth.seams[0].plate_a, "bj/left");
  EXPECT_EQ(truth.seams[0].plate_b, "bj/right");
  EXPECT_TRUE(truth.seams[0].end_scene.isApprox(Eigen::Vector3d(L, 0, 0)));
}

// First crossing of a ray with a plate's surface: the entry, or the exit when the ray starts inside
// (the mesh is surfaces, not solids); +inf on a miss.
double ray_plate(const PlateTruth& plate, const Eigen::Vector3d& o_scene, const Eigen::Vector3d& d_scene) {
  return testing::ray_box_slab(plate.size_m, plate.T_scene_plate, o_scene, d_scene, /*exit_if_inside=*/true);
}

// For each corner and each of the three faces meeting there: aim a ray along the inward face
// normal at a point of the face 1 mm in from the corner, from 5 cm and from 1 mm away. The ray
// cast must agree with the analytic first hit over all truth plates (a butt plate's inner face is
// hidden behind the other plate from 5 cm, visible from 1 mm inside the gap), and every face must
// be hit directly from at least one of the two stand-offs. That pins each face plane through its
// corner and each face's extent to the corner.
TEST(SceneTruth, EveryPlateCornerLiesOnTheRenderedSurface) {
  const SceneSpec spec = joints_scene();
  auto created = Renderer::create(spec);
  ASSERT_TRUE(created.ok()) << created.status().to_string();
  const Renderer& renderer = **created;
  const SceneGroundTruth truth = scene_ground_truth(spec);
  ASSERT_EQ(truth.plates.size(), 8u);
  constexpr double kInset = 0.001;
  int faces_seen = 0, probes = 0;
  for (const PlateTruth& plate : truth.plates) {
    const Eigen::Matrix3d R = plate.T_scene_plate.linear();
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d sign((i & 4) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 1) ? 1.0 : -1.0);
      for (int axis = 0; axis < 3; ++axis) {
        // Move in from the corner along the two in-face edges.
        Eigen::Vector3d inset = Eigen::Vector3d::Zero();
        for (int k = 0; k < 3; ++k) {
          if (k != axis) inset[k] = -sign[k] * kInset;
        }
        const Eigen::Vector3d on_face = plate.corners_scene[i] + R * inset;
        const Eigen::Vector3d outward = R.col(axis) * sign[axis];
        bool seen = false;
        for (const double standoff : {0.05, 0.001}) {
          const Eigen::Vector3d origin = on_face + standoff * outward;
          double expected = std::numeric_limits<double>::infinity();
          for (const PlateTruth& other : truth.plates)
            expected = std::min(expected, ray_plate(other, origin, -outward));
          ASSERT_TRUE(std::isfinite(expected));
          EXPECT_NEAR(renderer.cast_ray(origin, -outward), expected, 1e-4)
              << plate.name << " corner " << i << " face axis " << axis << " standoff " << standoff;
          seen = seen || std::abs(expected - standoff) < 1e-9;
          ++probes;
        }
        EXPECT_TRUE(seen) << plate.name << " corner " << i << " face axis " << axis << " is hidden";
        faces_seen += seen;
      }
    }
  }
  EXPECT_EQ(faces_seen, 8 * 8 * 3);
  EXPECT_EQ(probes, 2 * 8 * 8 * 3);
}

TEST(SceneTruth, SeamEndpointsLieOnBothPlates) {
  const SceneSpec spec = joints_scene();
  auto created = Renderer::create(spec);
  ASSERT_TRUE(created.ok()) << created.status().to_string();
  const Renderer& renderer = **created;
  const SceneGroundTruth truth = scene_ground_truth(spec);
  ASSERT_EQ(truth.seams.size(), spec.joints.size());
  for (size_t s = 0; s < truth.seams.size(); ++s) {
    const SeamTruth& seam = truth.seams[s];
    const WeldJointSpec& joint = spec.joints[s];
    EXPECT_NEAR((seam.end_scene - seam.start_scene).norm(), joint.length_m, 1e-12);
    const PlateTruth* a = find_plate(truth, seam.plate_a);
    const PlateTruth* b = find_plate(truth, seam.plate_b);
    ASSERT_TRUE(a && b) << seam.name;
    const double expected_gap = seam.type == WeldJointSpec::Type::kButt ? 0.5 * joint.gap_m : 0.0;
    for (const Eigen::Vector3d& p : {seam.start_scene, seam.end_scene}) {
      for (const PlateTruth* plate : {a, b}) {
        // In the plate frame: on the +z face plane, inside the face up to the butt half-gap.
        const Eigen::Vector3d local = plate->T_scene_plate.inverse() * p;
        const Eigen::Vector3d half = 0.5 * plate->size_m;
        EXPECT_NEAR(local.z(), half.z(), 1e-12) << seam.name << " " << plate->name;
        EXPECT_LE(std::abs(local.x()), half.x() + 1e-12) << seam.name << " " << plate->name;
        EXPECT_NEAR(std::abs(local.y()) - half.y(), expected_gap, 1e-12) << seam.name << " " << plate->name;
      }
    }
    // Rendered: 1 mm into the seam, a ray down the joint's -z onto the base side hits the top
    // face at the seam's height; in a butt joint the ray down the gap centre passes through.
    const Eigen::Matrix3d R = joint.T_scene_joint.linear();
    const Eigen::Vector3d up = R.col(2);
    const Eigen::Vector3d along = (seam.end_scene - seam.start_scene).normalized();
    const Eigen::Vector3d on_a = seam.start_scene + 0.001 * along - R.col(1) * (expected_gap + 0.001);
    EXPECT_NEAR(renderer.cast_ray(on_a + 0.05 * up, -up), 0.05, 1e-4) << seam.name;
    if (seam.type == WeldJointSpec::Type::kButt) {
      const Eigen::Vector3d on_b = seam.start_scene + 0.001 * along + R.col(1) * (expected_gap + 0.001);
      EXPECT_NEAR(renderer.cast_ray(on_b + 0.05 * up, -up), 0.05, 1e-4) << seam.name;
      const Eigen::Vector3d in_gap = seam.start_scene + 0.01 * along;
      EXPECT_GT(renderer.cast_ray(in_gap + 0.05 * up, -up), 0.05 + joint.thickness_m) << seam.name;
    } else {
      // The web's seam-side face stands at the seam: a ray along -y_joint from the base side hits it.
      const Eigen::Vector3d beside = seam.start_scene + 0.001 * along + 0.002 * up - 0.05 * R.col(1);
      EXPECT_NEAR(renderer.cast_ray(beside, R.col(1)), 0.05, 1e-4) << seam.name;
    }
  }
}

TEST(SceneTruth, EmptySceneHasNoTruth) {
  const SceneGroundTruth truth = scene_ground_truth(SceneSpec{});
  EXPECT_TRUE(truth.plates.empty());
  EXPECT_TRUE(truth.seams.empty());
}

}  // namespace
}  // namespace hwr::sim
