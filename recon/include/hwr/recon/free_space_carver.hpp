#pragma once
// Prior-map update by free-space carving (issue #6 item 3): after relocalization, the current
// depth images are cast as rays against the prior map's points with Embree, and a prior point that
// the current rays pass through, well in front of the surface they measured, is in observed free
// space (a moved plate, removed clutter) and is deleted. New geometry is not this class's job: the
// current keyframe clouds are merged into the map as usual (VoxelMap::insert).
//
// Geometry (docs/prior_map_update.md has the figures):
//  - Every prior point is an Embree sphere of radius point_radius_m: the width of a ray, i.e. how
//    close a ray must pass a point to say anything about it.
//  - The ray of pixel (u, v) is d_cam = K^-1 [u v 1]^T = ((u - cx) / fx, (v - cy) / fy, 1) from the
//    camera centre; with d_cam.z = 1 the ray parameter t is the z-depth, so the measured endpoint is
//    q_m = o + z_m d.
//  - The measured surface's normal at q_m comes from the depth image itself: a plane's inverse depth
//    is affine in the normalised image coordinates (x̄, ȳ) = ((u - cx) / fx, (v - cy) / fy): for the
//    plane n·X = c, X = z (x̄, ȳ, 1), 1/z = (n_x x̄ + n_y ȳ + n_z) / c. Central differences of 1/z over
//    ±normal_window_px give n ∝ (∂w/∂x̄, ∂w/∂ȳ, w − x̄ ∂w/∂x̄ − ȳ ∂w/∂ȳ), w = 1/z. A pixel whose
//    neighbourhood is not planar (second difference of 1/z beyond the noise: a depth edge, a flying
//    pixel) or whose ray meets the surface at incidence beyond acos(min_cos_incidence) casts nothing.
//  - A prior point p met by the ray is classified by its signed distance to the measured local
//    plane, s = n̂·(p − q_m) (n̂ towards the camera), against the free margin and the occupied band
//        margin = margin_min_m + k_sigma · σ,  band = margin_min_m + k_sigma_occupied · σ,
//        σ² = (depth_noise_k z² |d|)² + (pose_sigma_m + pose_sigma_rad · r)²
//    (stereo depth noise grows with z², |d| turns it into range r along the ray; the pose term is
//    T_prior_cam's uncertainty at that range; margin_min_m is the prior map's own noise):
//        free      s > margin and the point is more than margin before q_m along the ray,
//        occupied  |s| <= band (the current surface confirms it),
//        no vote   band < |s| <= margin (a 1 cm plate seen from 2 m: too close to the noise to say),
//        ignored   s < −margin (behind the measured surface: occluded, never evidence of absence).
//    The plane, not the range along the ray, is what makes grazing rays safe: a ray meeting the floor
//    at 10° passes within point_radius_m of floor points up to point_radius_m / sin(10°) ≈ 6 radii
//    before its endpoint, but those points lie on the measured plane (s ≈ 0) and vote occupied.
//  - Point i is deleted when free_i >= min_free_hits and free_i > free_ratio · occupied_i: one
//    noisy ray cannot delete a point, and a point the current run also sees is kept.
//  - Pose check: votes average out depth noise but not an error of T_prior_cam, which offsets every
//    ray of a frame alike (1 cm of error erodes 18 % of the lab test's floor). Before voting, a
//    sparse pass (every bias_check_subsample-th sampled pixel) casts check rays that reach
//    check_reach_behind_m behind the measured surface and groups them by the measured normal's
//    dominant axis and sign in the prior frame (6 clusters: ±x, ±y, ±z), so that an aligned surface
//    cannot vouch for a misaligned one (a vertical error leaves a wall's s unchanged). Per ray:
//        near   it meets a prior point with |s| < bias_window_m (every such pair enters the
//               cluster's histogram of s),
//        far    it meets prior points, none within the window (the prior surface is beyond the
//               window in front of or behind the measured one: a large pose error, or a scene that
//               changed by more than the window),
//        empty  it meets nothing (the prior has no geometry there: neither check nor vote).
//    A cluster with >= min_cluster_rays near + far rays is checked: it fails when its near
//    fraction is below min_near_fraction, its median s exceeds max_surface_bias_m (a translation
//    along its normal) or its interquartile range exceeds max_iqr_to_margin times its mean margin (a
//    rotation: s grows across the image). The check fails closed:
//        any checked cluster fails                         -> the frame casts no votes (misaligned),
//        the passed clusters hold < min_bias_pairs pairs   -> no votes (too few pairs to tell),
//        otherwise only the rays of passed clusters vote; rays of clusters too small to be checked
//        cast nothing (unverified_rays).
//    Quartiles resist changed geometry inside the window as long as it is the minority; changes
//    beyond the window count against the near fraction (a largely changed view keeps the prior).
//  - Pose check on measured planes (observe() with check planes, from measure_planes() of the same
//    image; PriorMapUpdater passes its pose refinement's): the check rays are the planes' pixels,
//    with their least-squares endpoint and normal, and each near ray enters the cluster's histogram
//    once, with the mean s of its pairs within ±margin of the plane (else its pair nearest the plane).
//    Same clusters and tests, except the rotation test (trend_check_on_planes): instead of the
//    residuals' interquartile range, their tilt across the cluster. A least-squares fit of the near
//    rays' residuals over their endpoints' two coordinates across the cluster's axis (rays beyond 2
//    IQRs of the median left out), r = a + g·(x − x̄); trend = |g| × the rays' RMS distance from their
//    centroid must be within max_surface_bias_m plus median_sigmas standard errors, and the IQR within
//    max_iqr_to_margin_trend margins. A rotation tilts the residuals; a prior that saw the surface from
//    afar only spreads them. Why: on the simulated lab revisit the sparse pass failed most
//    aligned frames (with poses at the simulator's truth too) on the interquartile range: its ±2 px
//    normals tilt by tens of degrees at 2-3 m, and a grazing ray adds tens of pairs to the histogram,
//    a frontal one one or two (docs/prior_map_update.md has the numbers).

// Point-to-plane normal equations for pose refinement (prior_pose_refiner.hpp, issue #6 item 3):
//  - measure_planes() fits the local plane of every sampled pixel by least squares of 1/z over
//    ±plane_radius_px (7 x 7 samples; fewer than 3/4 valid, or residuals beyond the noise of 1/z: a
//    window across a crease or an edge, and the pixel is skipped). The ±2 px differences of the carving pass
//    tilt normals by tens of degrees at 2-3 m (measured: the lab's floor pixels then fall into wall
//    clusters); such normals invent constraints (a floor seen with them seems to fix the lateral
//    translation, which then random-walks over the iterations). The fit's depth at the pixel is the
//    endpoint q_m: it averages the range noise of ~49 pixels.
//  - accumulate_point_to_plane() casts those rays into the same spheres from T_prior_cam. Per ray
//    the prior points within ±c of the measured plane give r = n̂·(p̄ − q_m), p̄ their mean weighted
//    by Tukey's biweight of their height s (c = min(window_m, c_σ σ_ray)) times a biweight of their
//    distance to the ray over point_radius_m (so that points entering or leaving the ray's reach as
//    the pose moves change p̄ continuously); the prior surface's thickness (2 cm voxel means, several
//    mm) averages out along the ray. For the right perturbation T_prior_cam · exp(ξ), ξ = (ω, v) in
//    the camera frame, the measured point and normal stay put in the camera and the prior moves by
//    exp(−ξ): r(ξ) = r + [(n_c × p_c)ᵀ, −n_cᵀ] ξ (p_c = T_prior_cam⁻¹ p̄). Each ray adds w JᵀJ and
//    w J r, w = (mean weight) / σ_ray², σ_ray² = margin_min_m² + ((m0 + depth_noise_k z²) |d| cos θ)² / N
//    (the prior's own noise, and the range noise of the fitted endpoint along the normal). The
//    camera-frame ξ makes the systems of several carvers (segments, each in its own frame) add up.

// Embree: one RTC_GEOMETRY_TYPE_SPHERE_POINT geometry over a buffer sized at create(); every hit
// along a ray is classified in an intersection filter callback that then rejects it, so one BVH
// traversal per ray visits every sphere the ray crosses in [0, tfar] (rtcOccluded1 / re-cast loops
// would restart the traversal at every hit). A sphere may be reported twice by one ray (entry and
// exit); a per-point ray stamp counts it once. observe() allocates nothing; set_prior() rebuilds the
// BVH (Embree allocates there).

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/keyframe_cloud.hpp"

namespace hwr::recon {

struct FreeSpaceCarverConfig {
  float point_radius_m = 0.005f;  // a quarter of the 2 cm map voxel
  float min_depth_m = 0.2f;       // pixels outside [min, max] cast nothing
  float max_depth_m = 4.0f;       // sigma_z(4 m) = 16 mm: beyond, a 1 cm plate is below the noise
  float depth_noise_k = 0.001f;   // sigma_z = k z² (1/m), ZED-like stereo
  float k_sigma = 2.0f;           // free beyond this many depth sigmas (the vote absorbs the 2.3 % tail)
  float k_sigma_occupied = 1.0f;  // occupied within this many (<= k_sigma); between the two: no vote
  float margin_min_m = 0.003f;    // the prior map's own noise (its voxel means)
  // Uncertainty of T_prior_cam (the relocalization refined locally against the prior, e.g. NDT of
  // the keyframe cloud): sigma_pose(r) = pose_sigma_m + pose_sigma_rad r at range r. The pose check
  // below rejects frames with larger errors; these cover what passes under its thresholds.
  float pose_sigma_m = 0.001f;
  float pose_sigma_rad = 0.0005f;  // 0.03°
  int normal_window_px = 2;        // central differences over ±this many pixels
  float planarity_sigmas = 4.0f;   // second difference of 1/z allowed, in its noise sigmas
  float planarity_rel = 0.01f;     // ... plus this fraction of 1/z (curved surfaces, zero noise)
  float min_cos_incidence = 0.1f;  // rays meeting the surface beyond ~84° from its normal cast nothing
  int min_free_hits = 2;
  float free_ratio = 1.0f;
  // Pose check (header): clusters of check rays by the measured normal; see the header comment.
  // bias_check_subsample = 0 turns the check off (every ray votes).
  float max_surface_bias_m = 0.002f;
  // ... or this many standard errors of the cluster's median (0.929 IQR / sqrt(pairs)), whichever is
  // larger: with noisy depth and few pairs the median alone wanders by more than 2 mm.
  float median_sigmas = 3.0f;
  float bias_window_m = 0.05f;        // near: |s| below this
  float check_reach_behind_m = 0.3f;  // check rays end this far behind the surface (>= bias_window_m)
  float max_iqr_to_margin = 0.6f;  // ... or whose interquartile range of s exceeds this times the mean margin
  float min_near_fraction = 0.8f;  // near / (near + far) rays of a checked cluster
  // Check on measured planes: a voting ray's free margin is at least this many times its cluster's
  // interquartile range of residuals (the prior's own thickness there; 0: off). A surface the prior
  // saw from afar is centimetres thick, and its points in front of the measured surface by more than
  // the current noise's margin were carved: on the short lab revisit (no moved plate in view) the
  // static loss went from 0.13 % to 0.99 %; with 2 IQRs (~2.7 sigma of a normal spread) 0.41 %.
  float spread_margin_iqrs = 0.0f;
  // Check on measured planes: the rotation test is on the residuals' trend across the cluster (a
  // least-squares tilt, header) instead of their interquartile range: a rotation tilts the residuals,
  // a prior surface seen from afar (centimetres thick) spreads them without a tilt. A cluster passes
  // when the tilt times the rays' RMS distance from their centroid is within max_surface_bias_m plus
  // median_sigmas of its standard error. On the lab revisit the IQR test failed every view of segment
  // 8 at the moved plate (IQR 23-25 mm against margins of 23-24 mm; docs/prior_map_update.md).
  bool trend_check_on_planes = true;
  // ... and the spread still allowed with it, in mean margins: a prior whose residuals spread further
  // holds more than one surface there (the short lab revisit's segment 0: IQR 1.6-1.9 margins on a
  // floor cluster; carved with 2 IQRs of spread margin it lost 2.0 % of its points against 0.55 %).
  float max_iqr_to_margin_trend = 1.3f;
  int max_check_rays = 16384;  // near rays kept for the trend test (sized at create(); beyond: not fitted)
  int min_cluster_rays = 30;   // near + far check rays for a cluster to be checked
  int bias_check_subsample = 4;
  int min_bias_pairs = 200;  // near pairs (rays, on measured planes) over the passed clusters, else rejected
  // Embree worker threads (BVH builds in set_prior; rays are cast on the caller's thread). 1: the
  // AGX control loop shares the cores.
  int embree_threads = 1;
};

// A near check ray on a measured plane: its endpoint (prior frame), residual and normal cluster.
struct CheckRay {
  Eigen::Vector3f q_prior = Eigen::Vector3f::Zero();
  float r_m = 0;
  int cluster = 0;
};

// Outcome of a frame's pose check.
enum class PoseCheck : uint8_t {
  kOff,          // bias_check_subsample = 0 or an empty prior: every ray votes
  kAligned,      // every checked cluster passed: the rays of passed clusters vote
  kMisaligned,   // a checked cluster failed: no votes
  kTooFewPairs,  // fewer than min_bias_pairs near pairs in passed clusters: no votes
};

// Measured normals in the prior frame, by dominant axis and sign: +x, -x, +y, -y, +z, -z.
inline constexpr int kNormalClusters = 6;

struct SurfaceClusterCheck {
  int near_rays = 0;   // check rays with a prior point within ±bias_window_m of the measured plane
  int far_rays = 0;    // check rays meeting prior points, none within the window
  int64_t pairs = 0;   // point-ray pairs with |s| < bias_window_m (on measured planes: near rays)
  float median_m = 0;  // of s over the pairs (on measured planes: the rays' residuals; 0.5 mm bins)
  float iqr_m = 0;     // interquartile range
  float margin_m = 0;  // mean free margin of the pairs
  // Trend test (check on measured planes, trend_check_on_planes): the residuals' tilt across the
  // cluster in metres (|g| times the rays' RMS radius) and its limit; not measured with < 8 rays.
  bool trend_measured = false;
  float trend_m = 0, trend_limit_m = 0;
  bool checked = false;  // near + far >= min_cluster_rays
  bool passed = false;   // checked, near fraction, median and IQR within limits: its rays vote
};

struct FreeSpaceObserveStats {
  // Counters of the voting pass (all 0 when the frame is rejected).
  int pixels = 0;          // pixels visited (every stride-th in u and v)
  int invalid = 0;         // depth 0 / NaN / inf
  int out_of_range = 0;    // outside [min_depth_m, max_depth_m]
  int not_planar = 0;      // neighbourhood invalid, off the image, or not planar (edges)
  int grazing = 0;         // incidence beyond acos(min_cos_incidence)
  int unverified = 0;      // rays of clusters the check did not pass (too few check rays): not cast
  int rays = 0;            // rays cast
  int64_t free_votes = 0;  // point-ray pairs classified free
  int64_t occupied_votes = 0;
  // The pose check (header).
  PoseCheck pose_check = PoseCheck::kOff;
  bool misaligned = false;    // kMisaligned or kTooFewPairs: nothing voted
  int64_t surface_pairs = 0;  // near pairs of the passed clusters
  std::array<SurfaceClusterCheck, kNormalClusters> clusters{};
};

// Which pixels measure_planes() samples, and how it fits their local plane (header).
struct PlaneSamplingParams {
  int stride_px = 8;        // every stride_px-th pixel in u and v ...
  int offset_px = 4;        // ... from this pixel (the pose check's rays start at 0)
  int plane_radius_px = 6;  // local plane: least squares over ±this ...
  int plane_step_px = 2;    // ... every this many pixels (7 x 7 samples)
  // Planes farther than this are not measured; <= 0: the carver's max_depth_m. (Pose refinement
  // gains from surfaces too noisy to carve: the fit averages their range noise.)
  float max_depth_m = 0;
  // Depth noise sigma_z = depth_noise_m0 + depth_noise_k z² (k from the carver's config), so 1/z has
  // sigma_w = k + m0 / z². A plane is kept when no sample's 1/z departs from the fit by more than
  // max_dev_sigmas sigma_w (+ 0.1 planarity_rel of 1/z: curvature) and their RMS is at most
  // max_rms_sigmas sigma_w.
  float depth_noise_m0 = 0;
  float max_dev_sigmas = 4.5f;
  float max_rms_sigmas = 1.5f;
};

// A pixel's ray and its measured local plane, in the camera frame (measure_planes()).
struct MeasuredPlane {
  Eigen::Vector3f d_cam = Eigen::Vector3f::Zero();  // K^-1 [u v 1]^T (z = 1)
  float z_m = 0;                                    // the plane's depth at the pixel: q_m = z_m d_cam
  Eigen::Vector3f n_cam = Eigen::Vector3f::Zero();  // unit normal, towards the camera
  float cos_inc = 0;                                // incidence cosine of the ray
  float sigma_m = 0;                                // σ_ray of the residual along the normal
};

// How accumulate_point_to_plane() pairs prior points with a ray (header).
struct PointToPlaneParams {
  float window_m = 0.06f;    // prior points with |s| below this enter the ray's mean
  float tukey_c_sigmas = 0;  // Tukey c in σ_ray (capped by window_m); <= 0: window_m alone
};

// Normal equations of one Gauss-Newton step, ξ = (ω rad, v m) in the camera frame (header). Fixed
// size: accumulating allocates nothing. clear() before a step; several carvers add into one.
struct PointToPlaneSystem {
  static constexpr int kResidualBins = 256;
  static constexpr float kResidualBinSigmas = 0.05f;  // |r| / σ_ray histogram: 0 .. 12.8 σ
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  double cost = 0;                                          // Σ w r²
  double weight = 0;                                        // Σ w
  int rays_cast = 0;                                        // planar pixels cast
  int residuals = 0;                                        // ... of which met prior points within the window
  std::array<uint32_t, kResidualBins> abs_residual_hist{};  // |r| / σ_ray (the last bin holds the tail)
  void clear() { *this = PointToPlaneSystem(); }
  // Median of |r| / σ_ray over the residuals (bin centre); 0 when there are none.
  float median_abs_residual_sigmas() const;
};

class FreeSpaceCarver {
 public:
  // Errors (kInvalidArgument): non-positive or non-finite config values, min_depth_m >= max_depth_m,
  // max_points < 0, free_ratio < 0, check_reach_behind_m < bias_window_m, min_near_fraction outside
  // [0, 1], embree_threads < 1; (kUnavailable): Embree cannot create its device.
  static core::Expected<FreeSpaceCarver> create(const FreeSpaceCarverConfig& config, int max_points);
  FreeSpaceCarver(FreeSpaceCarver&&) noexcept;
  FreeSpaceCarver& operator=(FreeSpaceCarver&&) noexcept;
  ~FreeSpaceCarver();

  // Copies the prior points (in the prior map's frame), zeroes the counters and builds the BVH.
  // n == 0 is a valid empty prior. Errors: (kOutOfRange) n > max_points; (kInvalidArgument)
  // points_prior null with n > 0, n < 0, a non-finite point (its index is named).
  core::Status set_prior(const CloudPoint* points_prior, int n);

  // Casts every stride_px-th valid pixel of depth_m (CV_32FC1, metres, K's size; 0/NaN/inf
  // invalid) from T_prior_cam and updates the counters. Errors (kInvalidArgument): wrong type or
  // size, invalid intrinsics, stride_px < 1, T_prior_cam not a finite rigid transform.
  core::Expected<FreeSpaceObserveStats> observe(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                                                const Eigen::Isometry3d& T_prior_cam, int stride_px);
  // The same, with the pose check on measured planes (measure_planes() of the same image) instead of
  // the sparse pass's ±normal_window_px differences (header). check_planes null: the sparse pass.
  core::Expected<FreeSpaceObserveStats> observe(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                                                const Eigen::Isometry3d& T_prior_cam, int stride_px,
                                                const MeasuredPlane* check_planes, int n_check_planes);

  // The local planes of depth_m at the pixels params samples, for accumulate_point_to_plane (header;
  // the carver's config gives the depth range, noise, planarity and incidence limits). Writes at most
  // capacity planes to out and returns how many. Allocates nothing. Errors (kInvalidArgument): as
  // observe() for the image and intrinsics, stride_px < 1, offset_px < 0, plane_radius_px or
  // plane_step_px < 1, out null with capacity > 0.
  core::Expected<int> measure_planes(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                                     const PlaneSamplingParams& params, MeasuredPlane* out,
                                     int capacity) const;

  // Adds the point-to-plane residuals of planes[0, n_planes) cast from T_prior_cam (prior = this
  // carver's frame) to *system (header). Counters and votes are untouched; allocates nothing.
  // Errors (kInvalidArgument): planes null with n_planes > 0, system null, window_m not positive,
  // T_prior_cam not rigid, no set_prior() yet.
  core::Status accumulate_point_to_plane(const MeasuredPlane* planes, int n_planes,
                                         const Eigen::Isometry3d& T_prior_cam,
                                         const PointToPlaneParams& params, PointToPlaneSystem* system);

  int prior_size() const;
  int capacity() const;
  const FreeSpaceCarverConfig& config() const;
  uint16_t free_hits(int i) const;      // saturating
  uint16_t occupied_hits(int i) const;  // saturating
  bool deleted(int i) const;
  int deleted_count() const;

  // Removes the deleted points from points_prior (stable order) and returns how many went.
  // points_prior must be the array given to set_prior() (same size: kInvalidArgument otherwise).
  // The carver keeps its counters; call set_prior() with the result to carve further.
  core::Expected<int> apply(std::vector<CloudPoint>* points_prior) const;

 private:
  struct Impl;
  explicit FreeSpaceCarver(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::recon
