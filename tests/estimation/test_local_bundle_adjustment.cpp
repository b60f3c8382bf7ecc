// Sliding-window bundle adjustment over the tracker's stores: a synthetic map with exact
// observations is perturbed and recovered; the gauge (oldest window pose) and the older fixed
// keyframes stay put; gross outlier observations are dropped from the keyframes.

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "hwr/core/se3.hpp"
#include "hwr/estimation/keyframe_store.hpp"
#include "hwr/estimation/local_bundle_adjustment.hpp"
#include "hwr/estimation/map_point_store.hpp"

namespace hwr::estimation {
namespace {

hal::PinholeIntrinsics vga() {
  hal::PinholeIntrinsics K;
  K.width = 640;
  K.height = 480;
  K.fx = K.fy = 525;
  K.cx = 319.5;
  K.cy = 239.5;
  return K;
}

struct World {
  std::vector<Eigen::Isometry3d> T_world_cam;  // true
  std::vector<Eigen::Vector3d> p_world;        // true
};

// Cameras along x looking at a wall of points at z ≈ 4 m.
World make_world(int cameras, int points, uint32_t seed) {
  World w;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < cameras; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.25 * i, 0.02 * std::sin(i), 0.0);
    T.linear() = Eigen::AngleAxisd(0.03 * i, Eigen::Vector3d::UnitY()).toRotationMatrix();
    w.T_world_cam.push_back(T);
  }
  for (int j = 0; j < points; ++j) {
    w.p_world.emplace_back(0.25 * cameras / 2.0 + 3.0 * u(rng), 1.8 * u(rng), 4.0 + 0.8 * u(rng));
  }
  return w;
}

struct Stores {
  Stores() : keyframes(config()), points(20000) {}
  static KeyframeStoreConfig config() {
    KeyframeStoreConfig c;
    c.capacity = 32;
    c.image_slots = 1;
    c.feature_capacity = 1000;
    return c;
  }
  KeyframeStore keyframes;
  MapPointStore points;
  std::vector<MapPointHandle> handles;
};

// Keyframes observe every point that projects into the image; depth on every other observation.
void fill(const World& w, const hal::PinholeIntrinsics& K, Stores* s) {
  uint8_t desc[kOrbDescriptorBytes] = {};
  for (const Eigen::Vector3d& p : w.p_world) s->handles.push_back(s->points.create(p, desc, 0, 0));
  for (size_t i = 0; i < w.T_world_cam.size(); ++i) {
    Keyframe* kf = s->keyframes.insert(static_cast<int64_t>(i), w.T_world_cam[i]);
    ASSERT_NE(kf, nullptr);
    const Eigen::Isometry3d T_cam_world = w.T_world_cam[i].inverse();
    for (size_t j = 0; j < w.p_world.size(); ++j) {
      const Eigen::Vector3d pc = T_cam_world * w.p_world[j];
      const double u = K.fx * pc.x() / pc.z() + K.cx, v = K.fy * pc.y() / pc.z() + K.cy;
      if (pc.z() < 0.1 || u < 0 || v < 0 || u > K.width - 1 || v > K.height - 1) continue;
      Feature f;
      f.u_px = static_cast<float>(u);
      f.v_px = static_cast<float>(v);
      f.depth_m = (j % 2 == 0) ? static_cast<float>(pc.z()) : 0.f;
      f.p_cam_m = pc;
      const int idx = kf->features.push_back(f, desc);
      if (idx < 0) break;
      kf->points[static_cast<size_t>(idx)] = s->handles[j];
      ++s->points.get(s->handles[j])->observations;
    }
  }
}

TEST(LocalBundleAdjustment, GivenAPerturbedWindowWhenAdjustedThenPosesAndPointsReturnToTheTruth) {
  const hal::PinholeIntrinsics K = vga();
  const World w = make_world(12, 400, 3);
  Stores s;
  fill(w, K, &s);
  // Perturb the newest 8 keyframes except the window's oldest (it fixes the gauge), and the points.
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int id = 5; id < 12; ++id) {
    core::Vector6d xi;
    for (int k = 0; k < 6; ++k) xi[k] = (k < 3 ? 0.02 : 0.01) * n(rng);
    s.keyframes.get(id)->T_world_cam = s.keyframes.get(id)->T_world_cam * core::se3_exp(xi);
  }
  for (const MapPointHandle& h : s.handles)
    s.points.get(h)->p_world_m += 0.03 * Eigen::Vector3d(n(rng), n(rng), n(rng));

  LocalBaConfig cfg;
  cfg.window_keyframes = 8;
  cfg.fixed_keyframes = 4;
  cfg.options.max_iterations = 30;
  LocalBundleAdjustment ba(cfg, s.points.capacity());
  auto report = ba.run(&s.keyframes, &s.points, K);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->cameras, 12);       // 8 in the window + the 4 older ones that see its points
  EXPECT_EQ(report->fixed_cameras, 5);  // the 4 older ones + the window's oldest
  EXPECT_EQ(report->observations_removed, 0);
  EXPECT_LT(report->summary.final_cost, 1e-6 * report->summary.initial_cost);
  for (int id = 0; id < 12; ++id) {
    const Eigen::Isometry3d d =
        w.T_world_cam[static_cast<size_t>(id)].inverse() * s.keyframes.get(id)->T_world_cam;
    EXPECT_LT(d.translation().norm(), 1e-5) << "keyframe " << id;
    EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 1e-6) << "keyframe " << id;
  }
  // Points seen by the window are back at the truth (points only the fixed keyframes see are not in it).
  int checked = 0;
  for (size_t j = 0; j < w.p_world.size(); ++j) {
    const MapPoint* p = s.points.get(s.handles[j]);
    if ((p->p_world_m - w.p_world[j]).norm() < 1e-4) ++checked;
  }
  EXPECT_GT(checked, 300);
}

TEST(LocalBundleAdjustment, GivenGrossOutlierObservationsWhenAdjustedThenTheyAreDroppedFromTheKeyframes) {
  const hal::PinholeIntrinsics K = vga();
  const World w = make_world(8, 300, 7);
  Stores s;
  fill(w, K, &s);
  // Move 10 observations of the newest keyframe by 40 px.
  Keyframe* kf = s.keyframes.get(7);
  int moved = 0;
  for (int f = 0; f < kf->features.size() && moved < 10; f += 7, ++moved)
    kf->features.feature(f).u_px += 40.f;
  LocalBaConfig cfg;
  cfg.window_keyframes = 8;
  LocalBundleAdjustment ba(cfg, s.points.capacity());
  auto report = ba.run(&s.keyframes, &s.points, K);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->observations_removed, 10);
  int invalid = 0;
  for (int f = 0; f < kf->features.size(); f += 7)
    invalid += kf->points[static_cast<size_t>(f)].valid() ? 0 : 1;
  EXPECT_EQ(invalid, 10);
  // The outliers did not pull the poses (Huber): still at the truth to well under a millimetre.
  for (int id = 0; id < 8; ++id) {
    const Eigen::Isometry3d d =
        w.T_world_cam[static_cast<size_t>(id)].inverse() * s.keyframes.get(id)->T_world_cam;
    EXPECT_LT(d.translation().norm(), 5e-4) << "keyframe " << id;
  }
}

TEST(LocalBundleAdjustment, GivenOneKeyframeThenNothingToAdjust) {
  Stores s;
  s.keyframes.insert(0, Eigen::Isometry3d::Identity());
  LocalBundleAdjustment ba(LocalBaConfig{}, s.points.capacity());
  auto report = ba.run(&s.keyframes, &s.points, vga());
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->cameras, 0);
}

}  // namespace
}  // namespace hwr::estimation
