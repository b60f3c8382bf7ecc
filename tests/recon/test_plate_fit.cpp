// Welding-plate reconstruction error (issue #4 item 5). Oracles: synthetic plates whose box faces
// are sampled from the known geometry (a fillet pair: a base plate with a web standing beside its
// edge, the bench under the base, clutter), raw and averaged into 1 cm voxels by recon::VoxelMap;
// closed-form corner and dimension errors; hand-written ground-truth files and cloud bytes. Weights:
// a point of weight k against k copies of it; 2 mm voxel means with their counts against the raw
// points.

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "hwr/recon/plate_fit.hpp"
#include "hwr/recon/voxel_map.hpp"
#include "plate_truth.hpp"

namespace hwr::recon {
namespace {

namespace fs = std::filesystem;

using hwr::testing::make_plate;

Eigen::Isometry3d pose(const Eigen::Vector3d& t, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

CloudPoint to_point(const Eigen::Vector3d& p) {
  CloudPoint c;
  c.x_m = static_cast<float>(p.x());
  c.y_m = static_cast<float>(p.y());
  c.z_m = static_cast<float>(p.z());
  c.r = c.g = c.b = 128;
  return c;
}

// Uniform random samples (one per spacing² of area) on the face of the plate's box whose normal is
// sign * plate axis `axis`, with isotropic Gaussian noise, or with depth_dir (unit, not zero) noise
// along it only (a depth camera's, along its viewing ray).
void sample_face(const PlateTruth& p, int axis, int sign, double spacing_m, double noise_m, std::mt19937* rng,
                 std::vector<CloudPoint>* out, const Eigen::Vector3d& depth_dir = Eigen::Vector3d::Zero()) {
  const int b = (axis + 1) % 3, c = (axis + 2) % 3;
  const double area = p.size_m[b] * p.size_m[c];
  const int n = static_cast<int>(area / (spacing_m * spacing_m));
  std::uniform_real_distribution<double> ub(-0.5 * p.size_m[b], 0.5 * p.size_m[b]);
  std::uniform_real_distribution<double> uc(-0.5 * p.size_m[c], 0.5 * p.size_m[c]);
  std::normal_distribution<double> noise(0.0, noise_m);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d local;
    local[axis] = sign * 0.5 * p.size_m[axis];
    local[b] = ub(*rng);
    local[c] = uc(*rng);
    const Eigen::Vector3d w = depth_dir.isZero()
                                  ? Eigen::Vector3d(p.T_world_plate * local +
                                                    Eigen::Vector3d(noise(*rng), noise(*rng), noise(*rng)))
                                  : Eigen::Vector3d(p.T_world_plate * local + noise(*rng) * depth_dir);
    out->push_back(to_point(w));
  }
}

// A fillet pair as hwr-sim lays it out (scene_spec): a 600 x 300 x 10 mm base plate on a bench and a
// 600 x 200 x 10 mm web standing beside its +y edge on the base's top level; a third plate far away
// that the cloud never sees.
struct Scene {
  WeldGroundTruth gt;
  std::vector<CloudPoint> points;
};

// depth_dir: see sample_face. with_web false: the base plate alone on its bench (and the far plate).
Scene fillet_scene(double yaw_rad, const Eigen::Vector3d& base_centre, double spacing_m, double noise_m,
                   uint32_t seed, const Eigen::Vector3d& depth_dir = Eigen::Vector3d::Zero(),
                   bool with_web = true) {
  Scene s;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Isometry3d T_world_base = pose(base_centre, R);
  const PlateTruth base = make_plate("pair/base", {0.6, 0.3, 0.01}, T_world_base);
  Eigen::Matrix3d R_base_web;  // web x = base x, web y = base z (up), web z = x cross y = -base y
  R_base_web.col(0) = Eigen::Vector3d::UnitX();
  R_base_web.col(1) = Eigen::Vector3d::UnitZ();
  R_base_web.col(2) = -Eigen::Vector3d::UnitY();
  const PlateTruth web = make_plate("pair/web", {0.6, 0.2, 0.01},
                                    T_world_base * pose(Eigen::Vector3d(0, 0.155, 0.105), R_base_web));
  const PlateTruth far =
      make_plate("far/base", {0.5, 0.25, 0.008},
                 pose(base_centre + Eigen::Vector3d(5, 5, 0), Eigen::Matrix3d::Identity()));
  s.gt.scenario = "test";
  s.gt.plates = {base, web, far};
  SeamTruth seam;
  seam.name = "pair";
  seam.plates = {"pair/base", "pair/web"};
  s.gt.seams = {seam};
  if (!with_web) {
    s.gt.plates = {base, far};
    s.gt.seams.clear();
  }

  std::mt19937 rng(seed);
  // Base: top and the four sides (its bottom lies on the bench). Web: both faces, top, both ends.
  sample_face(base, 2, +1, spacing_m, noise_m, &rng, &s.points, depth_dir);
  for (int sign : {-1, 1}) {
    sample_face(base, 0, sign, spacing_m, noise_m, &rng, &s.points, depth_dir);
    sample_face(base, 1, sign, spacing_m, noise_m, &rng, &s.points, depth_dir);
    if (!with_web) continue;
    sample_face(web, 2, sign, spacing_m, noise_m, &rng, &s.points, depth_dir);
    sample_face(web, 0, sign, spacing_m, noise_m, &rng, &s.points, depth_dir);
  }
  if (with_web) sample_face(web, 1, +1, spacing_m, noise_m, &rng, &s.points, depth_dir);
  // The bench top under the base (hidden where the base covers it), sparser.
  std::uniform_real_distribution<double> bx(-0.6, 0.6), by(-0.5, 0.5);
  std::normal_distribution<double> noise(0.0, noise_m);
  for (int i = 0; i < 40000; ++i) {
    const Eigen::Vector3d local(bx(rng), by(rng), -0.005);
    if (std::fabs(local.x()) <= 0.3 && std::fabs(local.y()) <= 0.15) continue;
    s.points.push_back(to_point(
        depth_dir.isZero()
            ? Eigen::Vector3d(T_world_base * local + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)))
            : Eigen::Vector3d(T_world_base * local + noise(rng) * depth_dir)));
  }
  // Clutter in the air around the pair.
  std::uniform_real_distribution<double> cx(-0.7, 0.7), cy(-0.6, 0.6), cz(-0.1, 0.4);
  for (int i = 0; i < 3000; ++i)
    s.points.push_back(to_point(T_world_base * Eigen::Vector3d(cx(rng), cy(rng), cz(rng))));
  return s;
}

std::vector<CloudPoint> voxel_means(const std::vector<CloudPoint>& pts, double voxel_m) {
  auto map = VoxelMap::create({voxel_m, 1 << 20});
  EXPECT_TRUE(map.ok());
  map->insert(pts.data(), static_cast<int>(pts.size()));
  EXPECT_EQ(map->counters().refused_full, 0u);
  std::vector<CloudPoint> out;
  map->for_each([&](const Voxel& v) {
    CloudPoint c;
    c.x_m = v.x_m, c.y_m = v.y_m, c.z_m = v.z_m;
    out.push_back(c);
  });
  return out;
}

AeReport fit_all(const Scene& s, const std::vector<CloudPoint>& pts, const PlateFitConfig& config,
                 std::vector<PlateFit>* fits_out = nullptr) {
  std::vector<PlateFit> fits;
  for (size_t i = 0; i < s.gt.plates.size(); ++i) {
    auto f = fit_plate(pts.data(), pts.size(), plate_roi_from_truth(s.gt, i), config);
    EXPECT_TRUE(f.ok()) << f.status().message();
    fits.push_back(f.ok() ? *f : PlateFit{});
  }
  auto rep = compute_ae(fits, s.gt);
  EXPECT_TRUE(rep.ok());
  if (fits_out != nullptr) *fits_out = fits;
  return *rep;
}

// The base plate within base_mm (dimensions and corners), the web within web_mm, the far plate not seen.
void expect_within(const AeReport& rep, double base_dim_mm, double base_corner_mm, double web_mm,
                   const std::string& what) {
  ASSERT_EQ(rep.plates_total, 3) << what;
  EXPECT_EQ(rep.plates_seen, 2) << what;
  for (int i = 0; i < 2; ++i) {
    const PlateAe& a = rep.plates[static_cast<size_t>(i)];
    ASSERT_TRUE(a.seen) << what << " " << a.name << ": " << a.reason;
    const double dim_mm = i == 0 ? base_dim_mm : web_mm;
    const double corner_mm = i == 0 ? base_corner_mm : web_mm;
    EXPECT_LE(a.length_error_mm, dim_mm) << what << " " << a.name << " L " << a.length_m;
    EXPECT_LE(a.width_error_mm, dim_mm) << what << " " << a.name << " W " << a.width_m;
    for (double c : a.corner_error_mm) EXPECT_LE(c, corner_mm) << what << " " << a.name;
  }
  EXPECT_FALSE(rep.plates[2].seen);
  EXPECT_NE(rep.plates[2].reason.find("points in the ROI"), std::string::npos) << rep.plates[2].reason;
}

// ---------------------------------------------------------------------------------------------

TEST(PlateFit, GivenDenseRawPointsWithNoiseWebBenchAndClutterThenDimensionsWithin2mmAndCornersWithin3mm) {
  // All the box faces but the base's bottom are sampled as densely as the faces that matter: the
  // side faces at the edges are the pessimistic case (a camera sees them obliquely, sparser).
  for (double yaw : {0.0294, 0.9}) {
    const Scene s = fillet_scene(yaw, Eigen::Vector3d(1.2034, -0.7071, 0.505), 0.002, 0.001, 7);
    std::vector<PlateFit> fits;
    const AeReport rep = fit_all(s, s.points, PlateFitConfig{}, &fits);
    // The web (a thin plate seen from one side, its foot over the bench) within 3 mm.
    expect_within(rep, 2.0, 3.0, 3.0, "raw, yaw " + std::to_string(yaw));
    // The base's visible face is its top (+z); the web's normal is horizontal (perpendicular to the base's).
    EXPECT_EQ(fits[0].face_sign, 1);
    EXPECT_GT(fits[0].normal_world.z(), 0.999);
    EXPECT_LT(std::fabs(fits[1].normal_world.z()), 0.01);
    EXPECT_NEAR(fits[0].plane_rms_m, 0.001, 0.0005);
    EXPECT_GT(fits[0].inliers, 40000);
    EXPECT_EQ(fits[0].edges_from_band_mean, 0);
  }
}

TEST(PlateFit, GivenVoxelMeansAt1cmThenTheVoxelModelKeepsTheBaseWithin3mm) {
  // Grid-aligned edges (yaw 0 and the simulator's 0.0294 rad) are the hard case: every voxel along an
  // edge is cut at the same fraction, so the outermost voxel mean sits up to half a voxel inside.
  // Top faces at several heights within a voxel layer (the side faces share the top's voxels or not).
  // The web, one voxel thick, coplanar with the base's side face at its foot and with end faces as
  // dense as its face, is only held to 8 mm.
  int cases = 0;
  for (double yaw : {0.0, 0.0294, 0.5}) {
    // Top at a layer boundary (z 0.510) and 6.3 mm into a layer (z 0.0627).
    for (const Eigen::Vector3d& c :
         {Eigen::Vector3d(1.2034, -0.7071, 0.505), Eigen::Vector3d(-3.0022, 0.0049, 0.0577)}) {
      const Scene s = fillet_scene(yaw, c, 0.0015, 0.001, 11);
      const std::vector<CloudPoint> vox = voxel_means(s.points, 0.01);
      PlateFitConfig config;
      config.sampling = CloudSampling::kVoxelMeans;
      config.voxel_m = 0.01;
      expect_within(fit_all(s, vox, config), 3.0, 3.0, 8.0,
                    "voxel 1 cm, yaw " + std::to_string(yaw) + " centre " + std::to_string(c.x()));
      ++cases;
    }
  }
  EXPECT_EQ(cases, 6);
}

TEST(PlateFit, GivenVoxelMeansTreatedAsRawPointsThenTheEdgesAreBiasedByTheSampling) {
  // The same 1 cm voxel means fitted with the raw-point model: every voxel counts as a full cell, so
  // the edges come out up to half a voxel too far out; the voxel model corrects it (previous test).
  const Scene s = fillet_scene(0.0, Eigen::Vector3d(1.2034, -0.7071, 0.505), 0.0015, 0.001, 11);
  const std::vector<CloudPoint> vox = voxel_means(s.points, 0.01);
  PlateFitConfig voxel;
  voxel.sampling = CloudSampling::kVoxelMeans;
  voxel.voxel_m = 0.01;
  std::vector<PlateFit> raw_fits, voxel_fits;
  fit_all(s, vox, PlateFitConfig{}, &raw_fits);
  fit_all(s, vox, voxel, &voxel_fits);
  ASSERT_TRUE(raw_fits[0].seen && voxel_fits[0].seen);
  const double raw_err = std::fabs(raw_fits[0].length_m - 0.6) + std::fabs(raw_fits[0].width_m - 0.3);
  const double voxel_err = std::fabs(voxel_fits[0].length_m - 0.6) + std::fabs(voxel_fits[0].width_m - 0.3);
  EXPECT_GT(raw_err, 0.003) << "voxel model: " << voxel_err;
  EXPECT_GT(raw_err, 2 * voxel_err);
}

TEST(PlateFit, GivenAPlateFitThenCornersFollowTheDocumentedOrderAndFrame) {
  const Scene s = fillet_scene(0.3, Eigen::Vector3d(0.5, 0.5, 0.505), 0.0025, 0.0005, 3);
  auto f = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), PlateFitConfig{});
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE(f->seen) << f->reason;
  // Counter-clockwise about the outward normal, from (-L/2, -W/2): corners 0, 4, 6, 2 of the top face.
  const PlateTruth& t = s.gt.plates[0];
  const int expected[4] = {1, 5, 7, 3};
  for (int k = 0; k < 4; ++k) {
    EXPECT_LT(
        (f->corners_world[static_cast<size_t>(k)] - t.corners_world[static_cast<size_t>(expected[k])]).norm(),
        0.003)
        << "corner " << k;
  }
  EXPECT_LT((f->face_centre_world - t.T_world_plate * Eigen::Vector3d(0, 0, 0.005)).norm(), 0.002);
  for (int k = 0; k < 4; ++k) EXPECT_GE(f->edge_samples[static_cast<size_t>(k)], 5);
}

TEST(PlateFit, GivenTooFewPointsOrABadConfigThenNotSeenOrInvalidArgument) {
  const Scene s = fillet_scene(0.0, Eigen::Vector3d(0, 0, 0.505), 0.0025, 0.001, 5);
  // Only 20 points of the base.
  std::vector<CloudPoint> few(s.points.begin(), s.points.begin() + 20);
  auto f = fit_plate(few.data(), few.size(), plate_roi_from_truth(s.gt, 0), PlateFitConfig{});
  ASSERT_TRUE(f.ok());
  EXPECT_FALSE(f->seen);
  EXPECT_LE(f->roi_points, 20);
  EXPECT_NE(f->reason.find(" points in the ROI (min 50)"), std::string::npos) << f->reason;
  // The whole base top but nothing near its -x edge: that edge is not observed.
  std::vector<CloudPoint> half;
  const Eigen::Isometry3d T_plate_world = s.gt.plates[0].T_world_plate.inverse();
  for (const CloudPoint& p : s.points) {
    const Eigen::Vector3d q = T_plate_world * Eigen::Vector3d(p.x_m, p.y_m, p.z_m);
    if (q.x() > 0.0) half.push_back(p);
  }
  f = fit_plate(half.data(), half.size(), plate_roi_from_truth(s.gt, 0), PlateFitConfig{});
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE(f->seen) << f->reason;  // seen, as the half plate that the cloud holds
  EXPECT_NEAR(f->length_m, 0.3, 0.003);
  EXPECT_NEAR(f->width_m, 0.3, 0.003);

  PlateFitConfig bad;
  bad.sampling = CloudSampling::kVoxelMeans;  // voxel_m left 0
  auto e = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), bad);
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(e.status().message().find("voxel_m"), std::string::npos);
  PlateRoi roi = plate_roi_from_truth(s.gt, 0);
  roi.size_m.y() = 0;
  e = fit_plate(s.points.data(), s.points.size(), roi, PlateFitConfig{});
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.status().code(), core::ErrorCode::kInvalidArgument);
}

TEST(ComputeAe, GivenKnownOffsetsThenErrorsAreTheirClosedForm) {
  WeldGroundTruth gt;
  gt.plates = {make_plate("a", {0.6, 0.3, 0.01}, pose({1, 2, 0.005}, Eigen::Matrix3d::Identity())),
               make_plate("b", {0.5, 0.2, 0.01}, pose({4, 2, 0.005}, Eigen::Matrix3d::Identity()))};
  PlateFit f;
  f.seen = true;
  f.face_sign = 1;
  f.length_m = 0.603;  // 3 mm long
  f.width_m = 0.299;   // 1 mm short
  // Top-face corners (bit 0 set) moved by (1, 2, 2) mm: 3 mm each.
  const Eigen::Vector3d d(0.001, 0.002, 0.002);
  const int top[4] = {1, 5, 7, 3};
  for (int k = 0; k < 4; ++k)
    f.corners_world[static_cast<size_t>(k)] = gt.plates[0].corners_world[static_cast<size_t>(top[k])] + d;
  PlateFit unseen;
  unseen.reason = "0 points in the ROI (min 50)";
  auto rep = compute_ae({f, unseen}, gt);
  ASSERT_TRUE(rep.ok());
  EXPECT_EQ(rep->plates_total, 2);
  EXPECT_EQ(rep->plates_seen, 1);
  EXPECT_NEAR(rep->plates[0].length_error_mm, 3.0, 1e-9);
  EXPECT_NEAR(rep->plates[0].width_error_mm, 1.0, 1e-9);
  for (double c : rep->plates[0].corner_error_mm) EXPECT_NEAR(c, 3.0, 1e-9);
  EXPECT_NEAR(rep->ae_mm, 2.0, 1e-9);
  EXPECT_NEAR(rep->ae_corner_mm, 3.0, 1e-9);
  EXPECT_FALSE(rep->plates[1].seen);
  EXPECT_TRUE(std::isnan(rep->plates[1].length_error_mm));
  // Fitted on the bottom face: matched against the bottom corners, 10 mm below.
  f.face_sign = -1;
  rep = compute_ae({f, unseen}, gt);
  ASSERT_TRUE(rep.ok());
  EXPECT_NEAR(rep->plates[0].corner_error_mm[0], 1e3 * (d + Eigen::Vector3d(0, 0, 0.01)).norm(), 1e-9);
  // Nothing seen: NaN, not 0.
  rep = compute_ae({unseen, unseen}, gt);
  ASSERT_TRUE(rep.ok());
  EXPECT_TRUE(std::isnan(rep->ae_mm));
  EXPECT_TRUE(std::isnan(rep->ae_corner_mm));
  EXPECT_FALSE(compute_ae({f}, gt).ok());
}

// ---------------------------------------------------------------------------------------------
// Weights (fine 2 mm voxel means with their counts). Oracle: a point of weight k is k copies of it.

// Each point repeated times[i] times in place (point 0 times[0] times, then point 1, ...): the layout
// whose RANSAC draws the weighted fit reproduces (header, "Weights").
std::vector<CloudPoint> repeat_points(const std::vector<CloudPoint>& pts, const std::vector<int>& times) {
  std::vector<CloudPoint> out;
  for (size_t i = 0; i < pts.size(); ++i) out.insert(out.end(), static_cast<size_t>(times[i]), pts[i]);
  return out;
}

std::vector<int> random_multiplicities(size_t n, int max_k, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> k(1, max_k);
  std::vector<int> out(n);
  for (int& x : out) x = k(rng);
  return out;
}

// The same fit up to floating-point summation order: counts equal, metres and the normal within tol.
void expect_same_fit(const PlateFit& a, const PlateFit& b, double tol, const std::string& what) {
  ASSERT_EQ(a.seen, b.seen) << what << ": " << a.reason << " / " << b.reason;
  EXPECT_EQ(a.reason, b.reason) << what;
  EXPECT_EQ(a.roi_points, b.roi_points) << what;
  EXPECT_EQ(a.inliers, b.inliers) << what;
  if (!a.seen) return;
  EXPECT_NEAR(a.plane_rms_m, b.plane_rms_m, tol * std::max(1.0, b.plane_rms_m)) << what;
  EXPECT_LT((a.normal_world - b.normal_world).norm(), tol) << what;
  EXPECT_LT((a.face_centre_world - b.face_centre_world).norm(),
            tol * std::max(1.0, b.face_centre_world.norm()))
      << what;
  EXPECT_EQ(a.face_sign, b.face_sign) << what;
  EXPECT_NEAR(a.length_m, b.length_m, tol * b.length_m) << what;
  EXPECT_NEAR(a.width_m, b.width_m, tol * b.width_m) << what;
  for (size_t k = 0; k < 4; ++k)
    EXPECT_LT((a.corners_world[k] - b.corners_world[k]).norm(),
              tol * std::max(1.0, b.corners_world[k].norm()))
        << what << " corner " << k;
  EXPECT_EQ(a.edge_samples, b.edge_samples) << what;
  EXPECT_EQ(a.edges_from_band_mean, b.edges_from_band_mean) << what;
  EXPECT_EQ(a.at_roi_limit, b.at_roi_limit) << what;
  EXPECT_EQ(a.iterations, b.iterations) << what;
}

// Bit for bit.
void expect_identical_fit(const PlateFit& a, const PlateFit& b, const std::string& what) {
  EXPECT_EQ(a.seen, b.seen) << what;
  EXPECT_EQ(a.reason, b.reason) << what;
  EXPECT_EQ(a.roi_points, b.roi_points) << what;
  EXPECT_EQ(a.inliers, b.inliers) << what;
  EXPECT_EQ(a.plane_rms_m, b.plane_rms_m) << what;
  EXPECT_EQ(a.normal_world, b.normal_world) << what;
  EXPECT_EQ(a.face_centre_world, b.face_centre_world) << what;
  EXPECT_EQ(a.face_sign, b.face_sign) << what;
  EXPECT_EQ(a.length_m, b.length_m) << what;
  EXPECT_EQ(a.width_m, b.width_m) << what;
  // (Not seen: the corners are not set.)
  for (size_t k = 0; k < 4 && a.seen; ++k)
    EXPECT_EQ(a.corners_world[k], b.corners_world[k]) << what << " corner " << k;
  EXPECT_EQ(a.edge_samples, b.edge_samples) << what;
  EXPECT_EQ(a.edges_from_band_mean, b.edges_from_band_mean) << what;
  EXPECT_EQ(a.at_roi_limit, b.at_roi_limit) << what;
  EXPECT_EQ(a.iterations, b.iterations) << what;
}

PlateFit fit_or_fail(const std::vector<CloudPoint>& pts, const PlateRoi& roi, const PlateFitConfig& config,
                     const std::vector<float>* weights = nullptr) {
  auto f = fit_plate(pts.data(), pts.size(), roi, config, weights != nullptr ? weights->data() : nullptr);
  EXPECT_TRUE(f.ok()) << f.status().message();
  return f.ok() ? *f : PlateFit{};
}

// A plate of thickness T lying on a bench, rendered from a camera: rays through a grid of
// directions (spacing_rad apart), each hitting the first of the plate's box (its top and sides) and
// the bench plane, the hit moved along the ray by Gaussian noise of sigma(range) = 1 mm + 1.5 mm/m^2
// range^2 (a depth camera's). The exact geometry of what the camera sees: the side faces turned
// towards it, none of those turned away, and the bench's part in the plate's shadow missing.
Scene plate_rendered_from(const Eigen::Vector3d& camera, const Eigen::Vector3d& size, double spacing_rad,
                          uint32_t seed) {
  Scene s;
  const double bench_z = 0.85;
  const PlateTruth base = make_plate(
      "one/base", size, pose(Eigen::Vector3d(0, 0, bench_z + 0.5 * size.z()), Eigen::Matrix3d::Identity()));
  s.gt.scenario = "test";
  s.gt.plates = {base};
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Eigen::Vector3d lo = base.T_world_plate.translation() - 0.5 * size,
                        hi = base.T_world_plate.translation() + 0.5 * size;
  const Eigen::Vector3d centre = base.T_world_plate.translation();
  const Eigen::Vector3d fwd = (centre - camera).normalized();
  const Eigen::Vector3d right = fwd.cross(Eigen::Vector3d::UnitZ()).normalized(), up = right.cross(fwd);
  const double span = std::atan2(0.5 * size.x() + 0.1, (centre - camera).norm());
  for (double a = -span; a <= span; a += spacing_rad)
    for (double b = -0.7 * span; b <= 0.7 * span; b += spacing_rad) {
      const Eigen::Vector3d u = (fwd + std::tan(a) * right + std::tan(b) * up).normalized();
      // Slab test against the plate's box, then the bench plane.
      double t0 = 0, t1 = 1e9;
      for (int k = 0; k < 3; ++k) {
        const double ta = (lo[k] - camera[k]) / u[k], tb = (hi[k] - camera[k]) / u[k];
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
      }
      double t = t0 <= t1 ? t0 : (bench_z - camera.z()) / u.z();
      if (!(t > 0)) continue;
      const Eigen::Vector3d hit = camera + t * u;
      if (std::fabs(hit.x() - centre.x()) > 0.5 * size.x() + 0.08 ||
          std::fabs(hit.y() - centre.y()) > 0.5 * size.y() + 0.08)
        continue;
      const double sigma = 0.001 + 0.0015 * t * t;
      s.points.push_back(to_point(hit + sigma * noise(rng) * u));
    }
  return s;
}

TEST(PlateFit,
     GivenNoiseAlongTheViewingRaysThenTheViewpointRemovesTheOpenSideSelectionsPullTowardsTheCamera) {
  // A 10 mm plate 1.45 m in front of the camera, 0.6 m below it, centred on it: at both ends the rays
  // lean inwards, so the points kept above the face (moved towards the camera) shorten the plate.
  // With the viewpoint they are placed where their rays meet the face (the support edges are left
  // to the band mean here: this is the slide alone).
  const Eigen::Vector3d camera(0.0, -1.3, 1.5);
  double sum_without = 0, sum_with = 0;
  for (uint32_t seed : {41u, 42u, 43u}) {
    const Scene s = plate_rendered_from(camera, Eigen::Vector3d(0.6, 0.3, 0.01), 0.0012, seed);
    PlateFitConfig c;
    c.support_edges = false;
    auto without = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), c);
    c.has_viewpoint = true;
    c.viewpoint_world = camera;
    auto with = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), c);
    ASSERT_TRUE(without.ok() && with.ok());
    ASSERT_TRUE(without->seen && with->seen) << without->reason << " / " << with->reason;
    const double dl0 = (without->length_m - 0.6) * 1e3, dl1 = (with->length_m - 0.6) * 1e3;
    std::printf("seed %u: length error without viewpoint %+.3f mm, with %+.3f mm\n", seed, dl0, dl1);
    EXPECT_LT(dl0, -0.5);            // shortened towards the camera
    EXPECT_LT(std::fabs(dl1), 0.7);  // the ray-plane intersection undoes it (one view: ~0.3 mm scatter)
    sum_without += std::fabs(dl0);
    sum_with += std::fabs(dl1);
  }
  EXPECT_LT(sum_with, 0.5 * sum_without);
  EXPECT_LT(sum_with / 3, 0.35);
  // A non-finite viewpoint is refused.
  const Scene s = plate_rendered_from(camera, Eigen::Vector3d(0.6, 0.3, 0.01), 0.004, 1);
  PlateFitConfig bad;
  bad.has_viewpoint = true;
  bad.viewpoint_world = Eigen::Vector3d(NAN, 0, 0);
  EXPECT_EQ(fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), bad).status().code(),
            core::ErrorCode::kInvalidArgument);
}

TEST(PlateFit, GivenAThinPlateOnItsSupportSeenAtAGrazingAngleThenTheRayModelPlacesItsEdges) {
  // A 10 mm floor plate 2.6 m from a camera 1.5 m above the floor (the sim lab's floor joints): the
  // noise along the rays (11 mm at that range) is as large as the plate is thick, and the band mean
  // merges the plate with the floor. The rays' model of face, sides and support places each edge.
  const Eigen::Vector3d camera(-0.3, -2.2, 1.5 + 0.85);
  for (uint32_t seed : {51u, 52u, 53u, 54u}) {
    const Scene s = plate_rendered_from(camera, Eigen::Vector3d(0.8, 0.3, 0.01), 0.0004, seed);
    PlateFitConfig c;
    c.has_viewpoint = true;
    c.viewpoint_world = camera;
    c.support_edges = false;
    auto band = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), c);
    c.support_edges = true;
    auto rays = fit_plate(s.points.data(), s.points.size(), plate_roi_from_truth(s.gt, 0), c);
    ASSERT_TRUE(band.ok() && rays.ok());
    ASSERT_TRUE(rays->seen) << rays->reason;
    const double dl = (rays->length_m - 0.8) * 1e3, dw = (rays->width_m - 0.3) * 1e3;
    const double band_err =
        band->seen ? std::fabs(band->length_m - 0.8) * 1e3 + std::fabs(band->width_m - 0.3) * 1e3 : INFINITY;
    std::printf(
        "seed %u: band mean |dL| + |dW| %.2f mm; ray model dL %+.2f mm dW %+.2f mm, %d edges on the "
        "support\n",
        seed, band_err, dl, dw, rays->edges_on_support);
    EXPECT_EQ(rays->edges_on_support, 4);
    // One view at 2.6 m: each edge is placed to about a millimetre (the lab's many views do better).
    EXPECT_LT(std::fabs(dl), 1.5);
    EXPECT_LT(std::fabs(dw), 2.5);
    EXPECT_LT(std::fabs(dl) + std::fabs(dw), 0.5 * band_err);
  }
}

TEST(PlateFitWeights, GivenIntegerWeightsThenTheFitIsTheFitOfThePointsRepeatedThatOften) {
  // The whole fillet scene (web, bench, clutter, 1 mm noise), weights 1..5: every statistic and
  // RANSAC's draws are those of the duplicated cloud, so only the summation order differs (k w x
  // against x + ... + x): 1e-9 relative.
  for (double yaw : {0.0294, 0.9}) {
    const Scene s = fillet_scene(yaw, Eigen::Vector3d(1.2034, -0.7071, 0.505), 0.003, 0.001, 13);
    const std::vector<int> k = random_multiplicities(s.points.size(), 5, 99);
    const std::vector<float> weights(k.begin(), k.end());
    const std::vector<CloudPoint> repeated = repeat_points(s.points, k);
    for (size_t i = 0; i < s.gt.plates.size(); ++i) {
      const PlateRoi roi = plate_roi_from_truth(s.gt, i);
      const PlateFit weighted = fit_or_fail(s.points, roi, PlateFitConfig{}, &weights);
      const PlateFit copies = fit_or_fail(repeated, roi, PlateFitConfig{});
      const std::string what = "yaw " + std::to_string(yaw) + " " + s.gt.plates[i].name;
      expect_same_fit(weighted, copies, 1e-9, what);
      EXPECT_EQ(weighted.seen, i < 2) << what << ": " << weighted.reason;
    }
  }
}

TEST(PlateFitWeights, GivenNonIntegerWeightsThenTheFitIsTheFitOfTheSameMassInEqualCopies) {
  // Weights k / 2 against k copies of weight 1/2: the non-integer path (RANSAC draws a real position
  // in the cumulative weight) with the same oracle; halves keep every cumulative weight exact.
  const Scene s = fillet_scene(0.3, Eigen::Vector3d(0.5, 0.5, 0.505), 0.003, 0.001, 17);
  const std::vector<int> k = random_multiplicities(s.points.size(), 6, 5);
  std::vector<float> halves(k.size());
  for (size_t i = 0; i < k.size(); ++i) halves[i] = 0.5f * static_cast<float>(k[i]);
  const std::vector<CloudPoint> repeated = repeat_points(s.points, k);
  const std::vector<float> half_each(repeated.size(), 0.5f);
  for (size_t i = 0; i < 2; ++i) {
    const PlateRoi roi = plate_roi_from_truth(s.gt, i);
    const PlateFit weighted = fit_or_fail(s.points, roi, PlateFitConfig{}, &halves);
    const PlateFit copies = fit_or_fail(repeated, roi, PlateFitConfig{}, &half_each);
    ASSERT_TRUE(weighted.seen) << weighted.reason;
    expect_same_fit(weighted, copies, 1e-9, s.gt.plates[i].name);
  }
}

TEST(PlateFitWeights, GivenAllWeightsOneThenTheFitIsBitIdenticalToNoWeights) {
  for (double yaw : {0.0294, 0.9}) {
    const Scene s = fillet_scene(yaw, Eigen::Vector3d(1.2034, -0.7071, 0.505), 0.003, 0.001, 7);
    const std::vector<float> ones(s.points.size(), 1.0f);
    // Raw points, and 1 cm voxel means fitted as raw points (another distribution of the edges).
    const std::vector<CloudPoint> vox = voxel_means(s.points, 0.01);
    const std::vector<float> vox_ones(vox.size(), 1.0f);
    for (size_t i = 0; i < s.gt.plates.size(); ++i) {
      const PlateRoi roi = plate_roi_from_truth(s.gt, i);
      const std::string what = "yaw " + std::to_string(yaw) + " " + s.gt.plates[i].name;
      expect_identical_fit(fit_or_fail(s.points, roi, PlateFitConfig{}, &ones),
                           fit_or_fail(s.points, roi, PlateFitConfig{}), what);
      expect_identical_fit(fit_or_fail(vox, roi, PlateFitConfig{}, &vox_ones),
                           fit_or_fail(vox, roi, PlateFitConfig{}), what + " voxel means");
    }
  }
}

TEST(PlateFitWeights, GivenFine2mmVoxelMeansWithTheirCountsThenTheFitReproducesTheRawPoints) {
  // A depth camera's noise: 3 mm along the viewing ray, the ray slanted to the plate, so the noise also
  // moves points across the edges. At 2 mm a voxel mean is about a raw point, but the voxels along an
  // edge hold fewer points than those inside: weighted by their counts the means give the raw fit
  // (within 0.3 mm); unweighted, the edges move. The base plate alone on its bench (sides, bench,
  // clutter): at a web's foot the boundary voxels also merge the web's face into the top's, which
  // the counts do not undo (the edge there moves by up to a millimetre either way).
  const Eigen::Vector3d view = Eigen::Vector3d(0.45, -0.3, -1.0).normalized();
  double weighted_sum = 0, unweighted_sum = 0;
  const std::vector<uint32_t> seeds = {21, 22, 23};
  for (uint32_t seed : seeds) {
    const Scene s =
        fillet_scene(0.0294, Eigen::Vector3d(1.2034, -0.7071, 0.505), 0.0015, 0.003, seed, view, false);
    auto map = VoxelMap::create({0.002, 1 << 22});
    ASSERT_TRUE(map.ok());
    map->insert(s.points.data(), static_cast<int>(s.points.size()));
    ASSERT_EQ(map->counters().refused_full, 0u);
    std::vector<CloudPoint> vox;
    std::vector<float> counts;
    map->for_each([&](const Voxel& v) {
      CloudPoint c;
      c.x_m = v.x_m, c.y_m = v.y_m, c.z_m = v.z_m;
      vox.push_back(c);
      counts.push_back(static_cast<float>(v.count));
    });
    ASSERT_LT(vox.size(), s.points.size());
    const PlateRoi roi = plate_roi_from_truth(s.gt, 0);
    const PlateFit raw = fit_or_fail(s.points, roi, PlateFitConfig{});
    const PlateFit weighted = fit_or_fail(vox, roi, PlateFitConfig{}, &counts);
    const PlateFit unweighted = fit_or_fail(vox, roi, PlateFitConfig{});
    ASSERT_TRUE(raw.seen && weighted.seen && unweighted.seen)
        << raw.reason << weighted.reason << unweighted.reason;
    const double L = s.gt.plates[0].size_m.x(), W = s.gt.plates[0].size_m.y();
    std::printf(
        "  seed %u, L and W errors (mm): raw points %+.3f %+.3f | 2 mm voxel means weighted %+.3f %+.3f | "
        "unweighted %+.3f %+.3f\n",
        seed, 1e3 * (raw.length_m - L), 1e3 * (raw.width_m - W), 1e3 * (weighted.length_m - L),
        1e3 * (weighted.width_m - W), 1e3 * (unweighted.length_m - L), 1e3 * (unweighted.width_m - W));
    const std::string what = "seed " + std::to_string(seed);
    EXPECT_NEAR(weighted.length_m, raw.length_m, 0.0003) << what;
    EXPECT_NEAR(weighted.width_m, raw.width_m, 0.0003) << what;
    // The counts restore the raw points' statistics (up to the voxels across the ROI's boundary).
    EXPECT_NEAR(weighted.roi_points, raw.roi_points, 0.01 * raw.roi_points) << what;
    EXPECT_NEAR(weighted.inliers, raw.inliers, 0.01 * raw.inliers) << what;
    EXPECT_NEAR(weighted.plane_rms_m, raw.plane_rms_m, 0.0001) << what;
    EXPECT_LT(unweighted.inliers, 0.95 * raw.inliers) << what;
    weighted_sum +=
        std::max(std::fabs(weighted.length_m - raw.length_m), std::fabs(weighted.width_m - raw.width_m));
    unweighted_sum +=
        std::max(std::fabs(unweighted.length_m - raw.length_m), std::fabs(unweighted.width_m - raw.width_m));
  }
  // Mean over the seeds of the larger dimension's deviation from the raw fit.
  const double weighted_dev = weighted_sum / static_cast<double>(seeds.size());
  const double unweighted_dev = unweighted_sum / static_cast<double>(seeds.size());
  std::printf("  mean deviation from the raw fit (mm): weighted %.3f, unweighted %.3f\n", 1e3 * weighted_dev,
              1e3 * unweighted_dev);
  EXPECT_GT(unweighted_dev, 0.0003) << "the weights should matter";
  EXPECT_GT(unweighted_dev, 2.5 * weighted_dev);
}

TEST(PlateFitWeights, GivenAWeightThatIsNotFinitePositiveOrWeightsWithVoxelMeansThenInvalidArgument) {
  const Scene s = fillet_scene(0.0, Eigen::Vector3d(0, 0, 0.505), 0.01, 0.001, 5);
  const PlateRoi roi = plate_roi_from_truth(s.gt, 0);
  struct Case {
    size_t index;
    float value;
    std::string shown;
  };
  const std::vector<Case> cases = {{7, std::nanf(""), "nan"},
                                   {3, 0.0f, "0"},
                                   {12, -2.0f, "-2"},
                                   {s.points.size() - 1, std::numeric_limits<float>::infinity(), "inf"}};
  for (const Case& c : cases) {
    std::vector<float> w(s.points.size(), 2.0f);
    w[c.index] = c.value;
    auto f = fit_plate(s.points.data(), s.points.size(), roi, PlateFitConfig{}, w.data());
    ASSERT_FALSE(f.ok()) << c.shown;
    EXPECT_EQ(f.status().code(), core::ErrorCode::kInvalidArgument);
    EXPECT_NE(f.status().message().find("weight " + std::to_string(c.index) + " is " + c.shown),
              std::string::npos)
        << f.status().message();
  }
  const std::vector<float> ones(s.points.size(), 1.0f);
  PlateFitConfig voxel;
  voxel.sampling = CloudSampling::kVoxelMeans;
  voxel.voxel_m = 0.01;
  auto f = fit_plate(s.points.data(), s.points.size(), roi, voxel, ones.data());
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(f.status().message().find("weights are for kRawPoints"), std::string::npos)
      << f.status().message();
}

// ---------------------------------------------------------------------------------------------
// Ground-truth file

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// The layout hwr-sim writes (hal/sim/src/run_writer.cpp weld_yaml).
std::string weld_yaml(const WeldGroundTruth& gt) {
  std::string y = "# test\nframe: world\nscenario: \"" + gt.scenario + "\"\nplates:\n";
  for (const PlateTruth& p : gt.plates) {
    y += "  - name: \"" + p.name + "\"\n";
    y += "    size_m: [" + num(p.size_m.x()) + ", " + num(p.size_m.y()) + ", " + num(p.size_m.z()) + "]\n";
    y += "    T_world_plate: [";
    const Eigen::Matrix4d M = p.T_world_plate.matrix();
    for (int i = 0; i < 16; ++i) y += (i ? ", " : "") + num(M(i / 4, i % 4));
    y += "]\n    corners_world: [";
    for (int i = 0; i < 24; ++i)
      y += (i ? ", " : "") + num(p.corners_world[static_cast<size_t>(i / 3)][i % 3]);
    y += "]\n";
  }
  y += "seams:\n";
  for (const SeamTruth& s : gt.seams) {
    y +=
        "  - name: \"" + s.name + "\"\n    type: " + (s.type == SeamType::kFillet ? "fillet" : "butt") + "\n";
    y += "    start_world: [" + num(s.start_world.x()) + ", " + num(s.start_world.y()) + ", " +
         num(s.start_world.z()) + "]\n";
    y += "    end_world: [" + num(s.end_world.x()) + ", " + num(s.end_world.y()) + ", " +
         num(s.end_world.z()) + "]\n";
    y += "    plates: [\"" + s.plates[0] + "\", \"" + s.plates[1] + "\"]\n";
  }
  return y;
}

WeldGroundTruth two_seams() {
  Scene s = fillet_scene(0.4, Eigen::Vector3d(1, 2, 3), 0.01, 0.0, 1);
  s.gt.seams[0].start_world = Eigen::Vector3d(1, 2, 3);
  s.gt.seams[0].end_world = Eigen::Vector3d(1.5, 2, 3);
  SeamTruth b;
  b.name = "other";
  b.type = SeamType::kButt;
  b.plates = {"far/base", "pair/base"};
  s.gt.seams.push_back(b);
  return s.gt;
}

core::Status parse_error(const std::string& text) {
  auto r = parse_weld_groundtruth(text, "weld.yaml");
  return r.ok() ? core::Status::Ok() : r.status();
}

void replace(std::string* s, const std::string& from, const std::string& to) {
  const size_t at = s->find(from);
  ASSERT_NE(at, std::string::npos) << from;
  s->replace(at, from.size(), to);
}

TEST(WeldGroundTruth, GivenTheSimulatorsLayoutThenPlatesAndSeamsAreRead) {
  const WeldGroundTruth want = two_seams();
  auto gt = parse_weld_groundtruth(weld_yaml(want), "weld.yaml");
  ASSERT_TRUE(gt.ok()) << gt.status().message();
  EXPECT_EQ(gt->scenario, "test");
  ASSERT_EQ(gt->plates.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(gt->plates[i].name, want.plates[i].name);
    EXPECT_EQ(gt->plates[i].size_m, want.plates[i].size_m);
    EXPECT_LT((gt->plates[i].T_world_plate.matrix() - want.plates[i].T_world_plate.matrix()).norm(), 1e-15);
    for (size_t c = 0; c < 8; ++c) EXPECT_EQ(gt->plates[i].corners_world[c], want.plates[i].corners_world[c]);
  }
  ASSERT_EQ(gt->seams.size(), 2u);
  EXPECT_EQ(gt->seams[0].name, "pair");
  EXPECT_EQ(gt->seams[0].type, SeamType::kFillet);
  EXPECT_EQ(gt->seams[0].plates[0], "pair/base");
  EXPECT_EQ(gt->seams[0].plates[1], "pair/web");
  EXPECT_EQ(gt->seams[0].end_world, Eigen::Vector3d(1.5, 2, 3));
  EXPECT_EQ(gt->seams[1].type, SeamType::kButt);
  EXPECT_EQ(gt->seams[1].plates[0], "far/base");
}

TEST(WeldGroundTruth, GivenMalformedFilesThenParseErrorsNameFileLineAndKey) {
  const std::string good = weld_yaml(two_seams());
  struct Case {
    std::string from, to, expect;
  };
  const std::vector<Case> cases = {
      {"    size_m: [0.59999999999999998, 0.29999999999999999, 0.01]\n", "",
       "weld.yaml:5: key 'plates[0].size_m': required but missing"},
      {"size_m: [0.59999999999999998", "size_m: [-0.59999999999999998",
       "key 'plates[0].size_m': length, width"},
      {"size_m: [0.59999999999999998, 0.29999999999999999, 0.01]", "size_m: [0.6, 0.3]",
       "key 'plates[0].size_m': expected 3 numbers"},
      {"frame: world", "frame: scene", "weld.yaml:2: key 'frame': expected 'world'"},
      {"type: butt", "type: lap", "key 'seams[1].type': expected fillet or butt, got 'lap'"},
      {"[\"far/base\", \"pair/base\"]", "[\"far/base\", \"nope\"]",
       "key 'seams[1].plates': 'nope' is not a plate of this file"},
      {"[\"far/base\", \"pair/base\"]", "[\"far/base\"]",
       "key 'seams[1].plates': expected 2 plate names, got 1"},
      {"[\"far/base\", \"pair/base\"]", "far/base", "key 'seams[1].plates': expected a list of plate names"},
      {"  - name: \"other\"\n", "  - name: \"other\"\n    colour: red\n", "unknown key 'seams[1].colour'"},
      {"  - name: \"pair/web\"", "  - name: \"pair/base\"",
       "key 'plates[1].name': duplicate plate name 'pair/base'"},
      {"T_world_plate: [", "T_world_plate: [2, ", "key 'plates[0].T_world_plate'"},
      {"plates:\n  - name: \"pair/base\"", "plates:\n  - name: [", "YAML syntax error"},
  };
  for (const Case& c : cases) {
    std::string text = good;
    replace(&text, c.from, c.to);
    const core::Status st = parse_error(text);
    ASSERT_FALSE(st.ok()) << c.expect;
    EXPECT_EQ(st.code(), core::ErrorCode::kParseError) << st.message();
    EXPECT_NE(st.message().find(c.expect), std::string::npos) << "got: " << st.message();
  }
  // A corner that disagrees with the pose and size by 2 mm.
  WeldGroundTruth gt = two_seams();
  gt.plates[1].corners_world[3].z() += 0.002;
  const core::Status st = parse_error(weld_yaml(gt));
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("key 'plates[1].corners_world': corner 3 is 2.0"), std::string::npos)
      << st.message();

  auto missing = read_weld_groundtruth("/nonexistent/weld_groundtruth.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), core::ErrorCode::kNotFound);
}

// ---------------------------------------------------------------------------------------------
// Cloud file

class CloudFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("hwr_cloud_file_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(CloudFile, GivenPointsThenTheBytesAreLittleEndianRecordsAndReadBackExactly) {
  std::vector<CloudPoint> pts(3);
  pts[0].x_m = 1.0f, pts[0].y_m = -2.0f, pts[0].z_m = 0.1f, pts[0].r = 1, pts[0].g = 2, pts[0].b = 3,
  pts[0].flags = 4;
  pts[1].x_m = 7.0305f, pts[1].y_m = 2.8079f, pts[1].z_m = -0.34f, pts[1].r = 255;
  pts[2].x_m = -1e-30f;
  ASSERT_TRUE(write_cloud_file(path("c.bin"), pts.data(), pts.size()).ok());
  std::ifstream in(path("c.bin"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.size(), 48u);
  // 1.0f = 0x3F800000, -2.0f = 0xC0000000, little-endian.
  const unsigned char head[12] = {0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0, 0xCD, 0xCC, 0xCC, 0x3D};
  for (int i = 0; i < 12; ++i)
    EXPECT_EQ(static_cast<unsigned char>(bytes[static_cast<size_t>(i)]), head[i]) << i;
  EXPECT_EQ(bytes[12], 1);
  EXPECT_EQ(bytes[15], 4);
  auto back = read_cloud_file(path("c.bin"));
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(std::memcmp(&(*back)[i], &pts[i], sizeof(CloudPoint)), 0) << i;
  }
}

TEST_F(CloudFile, GivenATruncatedOrNonFiniteOrMissingFileThenCorruptDataOrNotFound) {
  std::vector<CloudPoint> pts(2);
  ASSERT_TRUE(write_cloud_file(path("c.bin"), pts.data(), pts.size()).ok());
  fs::resize_file(path("c.bin"), 31);
  auto r = read_cloud_file(path("c.bin"));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(r.status().message().find("31 bytes is not a whole number of 16-byte point records"),
            std::string::npos)
      << r.status().message();

  pts[1].y_m = std::nanf("");
  ASSERT_TRUE(write_cloud_file(path("n.bin"), pts.data(), pts.size()).ok());
  r = read_cloud_file(path("n.bin"));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kCorruptData);
  EXPECT_NE(r.status().message().find("point 1 has a non-finite coordinate"), std::string::npos);

  r = read_cloud_file(path("absent.bin"));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), core::ErrorCode::kNotFound);

  ASSERT_TRUE(write_cloud_file(path("empty.bin"), nullptr, 0).ok());
  r = read_cloud_file(path("empty.bin"));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->empty());
}

}  // namespace
}  // namespace hwr::recon
