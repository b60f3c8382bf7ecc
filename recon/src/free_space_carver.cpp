// Free-space carving of the prior map (issue #6 item 3); the method is in free_space_carver.hpp.

#include "hwr/recon/free_space_carver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <mutex>
#include <string>

#include <embree3/rtcore.h>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace hwr::recon {
namespace {

// Embree wants flush-to-zero and denormals-are-zero while it traverses; set them for one call
// (x86: MXCSR FTZ | DAZ; aarch64: FPCR.FZ, bit 24, which flushes both inputs and results).
class ScopedFlushDenormals {
 public:
#if defined(__SSE__)
  ScopedFlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | 0x8040u); }
  ~ScopedFlushDenormals() { _mm_setcsr(saved_); }

 private:
  unsigned saved_;
#elif defined(__aarch64__)
  ScopedFlushDenormals() {
    asm volatile("mrs %0, fpcr" : "=r"(saved_));
    const uint64_t fz = saved_ | (uint64_t{1} << 24);
    asm volatile("msr fpcr, %0" : : "r"(fz));
  }
  ~ScopedFlushDenormals() { asm volatile("msr fpcr, %0" : : "r"(saved_)); }

 private:
  uint64_t saved_ = 0;
#else
  ScopedFlushDenormals() {}  // no control register known: Embree runs with the default mode
#endif
};

bool is_rigid(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return false;
  const Eigen::Matrix3d R = T.linear();
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
         R.determinant() > 0.0;
}

bool positive_finite(float x) { return std::isfinite(x) && x > 0.0f; }

// Inverse depth of a pixel, or 0 when the pixel is off the image or invalid.
inline float inverse_depth(const cv::Mat& depth_m, int u, int v) {
  if (u < 0 || v < 0 || u >= depth_m.cols || v >= depth_m.rows) return 0.0f;
  const float z = depth_m.ptr<float>(v)[u];
  return (std::isfinite(z) && z > 0.0f) ? 1.0f / z : 0.0f;
}

// Cluster of a measured normal (prior frame): dominant axis a, sign -> 2a + (n_a < 0).
inline int normal_cluster(const Eigen::Vector3f& n) {
  int a = 0;
  n.cwiseAbs().maxCoeff(&a);
  return 2 * a + (n[a] < 0.0f ? 1 : 0);
}

// The 1-sigma of a ray's endpoint against the prior (header: margin and band): the range noise
// sigma_z = k z^2 along the ray (|d| its length per unit z) and the pose's uncertainty at this range,
// in quadrature.
inline float endpoint_sigma_m(const FreeSpaceCarverConfig& c, float z, float d_norm) {
  const float range_m = z * d_norm;
  const float sigma_range_m = c.depth_noise_k * z * z * d_norm;
  const float sigma_pose_m = c.pose_sigma_m + c.pose_sigma_rad * range_m;
  return std::sqrt(sigma_range_m * sigma_range_m + sigma_pose_m * sigma_pose_m);
}

}  // namespace

struct FreeSpaceCarver::Impl {
  static constexpr int kBiasBins = 200;

  // What a pass of cast() measures: the pose check's near / far rays and residuals, the votes, or
  // the point-to-plane normal equations (header).
  enum class Pass : uint8_t { kCheck, kVote, kAlign };

  // The ray being cast, handed to the filter through Embree's context (the RTCIntersectContext must
  // be the first member: Embree passes its address back).
  struct RayContext {
    RTCIntersectContext embree;
    Impl* self = nullptr;
    Eigen::Vector3f o, d, q, n;  // origin, direction (d_cam.z = 1), measured endpoint, unit normal to camera
    float d_norm = 0;            // |d|
    float margin_m = 0;          // free beyond this height above the measured plane
    float occupied_band_m = 0;   // occupied within ± this
    uint32_t stamp = 0;
    Pass pass = Pass::kVote;
    int64_t free_votes = 0, occupied_votes = 0;
    // Voting pass: which normal clusters passed the check (their rays vote).
    std::array<bool, kNormalClusters> cluster_votes{};
    std::array<float, kNormalClusters> cluster_margin_floor_m{};  // check on planes: the residuals' spread
    // Check pass, per normal cluster: near / far rays and the histogram of s over
    // [-bias_window_m, bias_window_m] (kBiasBins bins). The current ray's cluster and what it met.
    float bias_window_m = 0;
    int cluster = 0;
    bool ray_near = false, ray_hit = false;
    // Check pass on measured planes: one residual per ray, the mean s of its pairs within ±margin_m of
    // the plane, else (none that close) the near pair's s nearest the plane.
    bool per_ray = false;
    float nearest_s = 0, band_sum_s = 0;
    int band_n = 0;
    // ... and each near ray's endpoint and residual for the trend test (Impl::check_rays; rays beyond
    // its capacity enter the histogram only).
    CheckRay* ray_log = nullptr;
    int ray_log_capacity = 0, ray_log_n = 0;
    std::array<int, kNormalClusters> near_rays{}, far_rays{};
    std::array<int64_t, kNormalClusters> surface_pairs{};
    std::array<double, kNormalClusters> margin_sum_m{};  // of those pairs' free margins
    std::array<std::array<uint32_t, kBiasBins>, kNormalClusters> bias_hist{};
    // Align pass: this ray's Tukey c and its weighted sums over the prior points within it.
    float align_c_m = 0;
    float align_w = 0, align_ws = 0;
    Eigen::Vector3f align_wp = Eigen::Vector3f::Zero();
    int align_n = 0;
  };

  FreeSpaceCarverConfig config;
  int max_points = 0;
  int n = 0;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<CheckRay> check_rays;  // the check on planes' near rays (max_check_rays, sized at create())
  std::vector<float> spheres;        // x y z radius per point, +1 element of padding (Embree's SSE loads)
  std::vector<uint32_t> stamps;
  std::vector<uint16_t> free_hits, occupied_hits;
  uint32_t ray_id = 0;
  // Embree may report errors from its worker threads (BVH build): guarded.
  std::mutex error_mutex;
  std::string error;

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  static void on_error(void* user, RTCError code, const char* message) {
    auto* self = static_cast<Impl*>(user);
    const std::lock_guard<std::mutex> lock(self->error_mutex);
    if (self->error.empty()) self->error = "Embree error " + std::to_string(code) + ": " + message;
  }

  static void bump(uint16_t* c) {
    if (*c != std::numeric_limits<uint16_t>::max()) ++*c;
  }

  // Every sphere the ray meets in [tnear, tfar] arrives here; it is classified against the measured
  // plane (header: free / occupied / ignored) and rejected so that traversal goes on.
  static void filter(const RTCFilterFunctionNArguments* args) {
    auto* rc = reinterpret_cast<RayContext*>(args->context);
    Impl* self = rc->self;
    for (unsigned k = 0; k < args->N; ++k) {
      if (args->valid[k] == 0) continue;
      args->valid[k] = 0;
      const unsigned prim = RTCHitN_primID(args->hit, args->N, k);
      if (self->stamps[prim] == rc->stamp) continue;  // the sphere's exit hit of the same ray
      self->stamps[prim] = rc->stamp;
      const Eigen::Map<const Eigen::Vector3f> p(&self->spheres[4 * static_cast<size_t>(prim)]);
      const Eigen::Vector3f q_to_p = p - rc->q;
      const float s = rc->n.dot(q_to_p);  // height above the measured plane, towards the camera
      if (rc->pass == Pass::kAlign) {
        // Tukey biweight of the point's height (header: point-to-plane normal equations).
        if (!(std::abs(s) < rc->align_c_m)) continue;
        // ... times a biweight kernel of its distance to the ray, so that points entering or
        // leaving the ray's sphere of reach as the pose moves change the mean continuously.
        const float lateral2 = (p - rc->o).cross(rc->d).squaredNorm() / (rc->d_norm * rc->d_norm);
        const float l = 1.0f - lateral2 / (self->config.point_radius_m * self->config.point_radius_m);
        if (!(l > 0.0f)) continue;
        const float x = s / rc->align_c_m;
        const float w = (1.0f - x * x) * (1.0f - x * x) * l * l;
        rc->align_w += w;
        rc->align_ws += w * s;
        rc->align_wp += w * p;
        ++rc->align_n;
        continue;
      }
      if (rc->pass == Pass::kCheck) {
        rc->ray_hit = true;
        if (rc->per_ray) {
          if (std::abs(s) < rc->bias_window_m) {
            if (!rc->ray_near || std::abs(s) < std::abs(rc->nearest_s)) rc->nearest_s = s;
            rc->ray_near = true;
            if (std::abs(s) < rc->margin_m) {
              rc->band_sum_s += s;
              ++rc->band_n;
            }
          }
          continue;
        }
        if (std::abs(s) < rc->bias_window_m) {
          const int bin = static_cast<int>((s + rc->bias_window_m) / (2.0f * rc->bias_window_m) * kBiasBins);
          const size_t k_cl = static_cast<size_t>(rc->cluster);
          ++rc->bias_hist[k_cl][static_cast<size_t>(std::clamp(bin, 0, kBiasBins - 1))];
          ++rc->surface_pairs[k_cl];
          rc->margin_sum_m[k_cl] += rc->margin_m;
          rc->ray_near = true;
        }
        continue;
      }
      if (s > rc->margin_m) {
        // Range before the endpoint along the ray: -(q_to_p . d) / |d|.
        if (-q_to_p.dot(rc->d) / rc->d_norm > rc->margin_m) {
          bump(&self->free_hits[prim]);
          ++rc->free_votes;
        }
      } else if (std::abs(s) <= rc->occupied_band_m) {
        bump(&self->occupied_hits[prim]);
        ++rc->occupied_votes;
      }
    }
  }

  // The local plane at pixel (u, v) for measure(): a least-squares fit of the inverse depth
  // w = a dx + b dy + w0 over the samples every `step` pixels within ±r (dx, dy normalised image
  // offsets), n / c = (a, b, w0 - a xb - b yb) as in the header. Fails when fewer than 3/4 of the
  // samples are valid. *count: the samples used; *max_dev, *rms: of their residuals.
  bool fit_plane(const cv::Mat& depth_m, int u, int v, int r, int step, float fx, float fy, float xb,
                 float yb, Eigen::Vector3f* n_over_c, int* count, float* max_dev, float* rms) const {
    Eigen::Matrix3f A = Eigen::Matrix3f::Zero();
    Eigen::Vector3f b = Eigen::Vector3f::Zero();
    int valid = 0, total = 0;
    for (int dv = -r; dv <= r; dv += step) {
      for (int du = -r; du <= r; du += step) {
        ++total;
        const float w = inverse_depth(depth_m, u + du, v + dv);
        if (w == 0.0f) continue;
        const Eigen::Vector3f x(static_cast<float>(du) / fx, static_cast<float>(dv) / fy, 1.0f);
        A.noalias() += x * x.transpose();
        b += w * x;
        ++valid;
      }
    }
    if (4 * valid < 3 * total || valid < 4) return false;
    const Eigen::Vector3f abw = A.ldlt().solve(b);  // a, b, w0
    if (!abw.allFinite() || !(abw.z() > 0.0f)) return false;
    float sum2 = 0.0f, worst = 0.0f;
    for (int dv = -r; dv <= r; dv += step) {
      for (int du = -r; du <= r; du += step) {
        const float w = inverse_depth(depth_m, u + du, v + dv);
        if (w == 0.0f) continue;
        const float dev =
            w - (abw.x() * static_cast<float>(du) / fx + abw.y() * static_cast<float>(dv) / fy + abw.z());
        sum2 += dev * dev;
        worst = std::max(worst, std::abs(dev));
      }
    }
    *n_over_c = Eigen::Vector3f(abw.x(), abw.y(), abw.z() - xb * abw.x() - yb * abw.y());
    *count = valid;
    *max_dev = worst;
    *rms = std::sqrt(sum2 / static_cast<float>(valid));
    return true;
  }

  // One ray's point-to-plane residual (header): the Tukey-weighted mean of the prior points near the
  // measured plane, its Jacobian for T_prior_cam * exp(xi) and its weight, added to *system.
  static void add_residual(const RayContext& rc, const Eigen::Matrix3f& R, const Eigen::Vector3f& o,
                           const MeasuredPlane& mp, PointToPlaneSystem* system) {
    const float sigma_normal_m = mp.sigma_m;
    const float r = rc.align_ws / rc.align_w;
    const Eigen::Vector3f p_mean = rc.align_wp / rc.align_w;
    const Eigen::Vector3d p_cam = (R.transpose() * (p_mean - o)).cast<double>();
    const Eigen::Vector3d n_cam = mp.n_cam.cast<double>();  // towards the camera, as rc.n
    Eigen::Matrix<double, 6, 1> J;
    J.head<3>() = n_cam.cross(p_cam);
    J.tail<3>() = -n_cam;
    const double sigma2 = static_cast<double>(sigma_normal_m) * sigma_normal_m;
    const double w = static_cast<double>(rc.align_w) / rc.align_n / sigma2;
    system->H.noalias() += w * J * J.transpose();
    system->g += (w * r) * J;
    system->cost += w * r * r;
    system->weight += w;
    ++system->residuals;
    const float r_sigmas = std::abs(r) / sigma_normal_m;
    const int bin = std::min(PointToPlaneSystem::kResidualBins - 1,
                             static_cast<int>(r_sigmas / PointToPlaneSystem::kResidualBinSigmas));
    ++system->abs_residual_hist[static_cast<size_t>(bin)];
  }

  // After a check ray: its near / far count, and on measured planes its one residual.
  static void finish_check_ray(RayContext* rc, int cluster) {
    const size_t k = static_cast<size_t>(cluster);
    if (rc->ray_near) {
      ++rc->near_rays[k];
      if (rc->per_ray) {
        const float r = rc->band_n > 0 ? rc->band_sum_s / static_cast<float>(rc->band_n) : rc->nearest_s;
        if (rc->ray_log_n < rc->ray_log_capacity) rc->ray_log[rc->ray_log_n++] = {rc->q, r, cluster};
        const int bin = static_cast<int>((r + rc->bias_window_m) / (2.0f * rc->bias_window_m) * kBiasBins);
        ++rc->bias_hist[k][static_cast<size_t>(std::clamp(bin, 0, kBiasBins - 1))];
        ++rc->surface_pairs[k];
        rc->margin_sum_m[k] += rc->margin_m;
      }
    } else if (rc->ray_hit) {
      ++rc->far_rays[k];
    }
  }

  // The q-quantile of the check pass's histogram of s in cluster k (bin centre).
  static float quantile(const RayContext& rc, int k, double q, float window_m) {
    const auto& hist = rc.bias_hist[static_cast<size_t>(k)];
    const double target = q * static_cast<double>(rc.surface_pairs[static_cast<size_t>(k)]);
    int64_t below = 0;
    int bin = 0;
    while (bin < kBiasBins - 1 && static_cast<double>(below + hist[static_cast<size_t>(bin)]) <= target) {
      below += hist[static_cast<size_t>(bin)];
      ++bin;
    }
    return (2.0f * (static_cast<float>(bin) + 0.5f) / kBiasBins - 1.0f) * window_m;
  }

  // The trend test on measured planes (header): least squares of the near rays' residuals r of
  // cluster k over their endpoints' two coordinates across the cluster's axis, r = a + g·(x − x̄),
  // rays further than 2 IQRs from the median left out (changed geometry). trend_m = |g| times the
  // rays' RMS distance from their centroid, its standard error from the fit's residuals. Returns
  // false (no trend measured) with fewer than 8 rays or a degenerate spread.
  static bool residual_trend(const RayContext& rc, int k, float median_m, float iqr_m, float* trend_m,
                             float* trend_se_m) {
    const int axis = k / 2;  // +x -x +y -y +z -z
    const int a0 = (axis + 1) % 3, a1 = (axis + 2) % 3;
    const float keep_m = 2.0f * std::max(iqr_m, 2.0f * rc.bias_window_m / kBiasBins);
    Eigen::Vector4d sums = Eigen::Vector4d::Zero();  // n, Σu, Σv, Σr
    Eigen::Matrix3d uvr2 = Eigen::Matrix3d::Zero();  // Σ [u v r][u v r]ᵀ
    for (int i = 0; i < rc.ray_log_n; ++i) {
      const CheckRay& cr = rc.ray_log[i];
      if (cr.cluster != k || std::abs(cr.r_m - median_m) > keep_m) continue;
      const Eigen::Vector3d x(cr.q_prior[a0], cr.q_prior[a1], cr.r_m);
      sums[0] += 1.0;
      sums.segment<3>(1) += x;
      uvr2 += x * x.transpose();
    }
    const double n = sums[0];
    if (n < 8) return false;
    const Eigen::Vector3d mean = sums.segment<3>(1) / n;
    const Eigen::Matrix3d C = uvr2 - n * mean * mean.transpose();  // centred scatter
    const Eigen::Matrix2d S = C.topLeftCorner<2, 2>();
    const Eigen::Vector2d b = C.topRightCorner<2, 1>();
    if (!(S.determinant() > 1e-12 * S.trace() * S.trace()) || !(S.trace() > 0)) return false;
    const Eigen::Matrix2d S_inv = S.inverse();
    const Eigen::Vector2d g = S_inv * b;
    const double rss = std::max(0.0, C(2, 2) - b.dot(g));
    const double sigma2 = rss / (n - 3.0);
    const double radius = std::sqrt(S.trace() / n);
    const double g_norm = g.norm();
    const Eigen::Vector2d dir = g_norm > 0 ? Eigen::Vector2d(g / g_norm) : Eigen::Vector2d(1, 0);
    *trend_m = static_cast<float>(g_norm * radius);
    *trend_se_m = static_cast<float>(radius * std::sqrt(sigma2 * dir.dot(S_inv * dir)));
    return true;
  }

  // Casts every stride_px-th pixel's ray (header). kCheck measures only the pose check's near / far
  // rays and near-surface residuals; kVote casts only the rays of the clusters in
  // rc_out->cluster_votes.
  void cast(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K, const Eigen::Isometry3d& T_prior_cam,
            int stride_px, Pass pass, RayContext* rc_out, FreeSpaceObserveStats* stats_out) {
    const bool vote = pass == Pass::kVote;
    const Eigen::Matrix3f R = T_prior_cam.linear().cast<float>();
    const Eigen::Vector3f o = T_prior_cam.translation().cast<float>();
    const FreeSpaceCarverConfig& c = config;
    const int h = c.normal_window_px;
    const float fx = static_cast<float>(K.fx), fy = static_cast<float>(K.fy);
    const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
    // 1/z has noise sigma_z / z² = depth_noise_k at every depth; its second difference sqrt(6) times that.
    const float planarity_abs = c.planarity_sigmas * std::sqrt(6.0f) * c.depth_noise_k;

    RayContext& rc = *rc_out;
    rtcInitIntersectContext(&rc.embree);
    rc.self = this;
    rc.o = o;
    rc.pass = pass;
    rc.bias_window_m = config.bias_window_m;
    FreeSpaceObserveStats& stats = *stats_out;
    for (int v = 0; v < depth_m.rows; v += stride_px) {
      const float* row = depth_m.ptr<float>(v);
      for (int u = 0; u < depth_m.cols; u += stride_px) {
        ++stats.pixels;
        const float z = row[u];
        if (!std::isfinite(z) || z <= 0.0f) {
          ++stats.invalid;
          continue;
        }
        if (z < c.min_depth_m || z > c.max_depth_m) {
          ++stats.out_of_range;
          continue;
        }
        // Local plane from the inverse depths of the 4 neighbours at ±h (header).
        const float w = 1.0f / z;
        const float wl = inverse_depth(depth_m, u - h, v), wr = inverse_depth(depth_m, u + h, v);
        const float wu = inverse_depth(depth_m, u, v - h), wd = inverse_depth(depth_m, u, v + h);
        const float tol = planarity_abs + c.planarity_rel * w;
        if (wl == 0.0f || wr == 0.0f || wu == 0.0f || wd == 0.0f || std::abs(wl + wr - 2.0f * w) > tol ||
            std::abs(wu + wd - 2.0f * w) > tol) {
          ++stats.not_planar;
          continue;
        }
        const float xb = (static_cast<float>(u) - cx) / fx, yb = (static_cast<float>(v) - cy) / fy;
        const float gx = (wr - wl) * fx / (2.0f * static_cast<float>(h));
        const float gy = (wd - wu) * fy / (2.0f * static_cast<float>(h));
        const Eigen::Vector3f n_over_c(gx, gy, w - xb * gx - yb * gy);  // plane n.X = c, pointing away
        const Eigen::Vector3f d_cam(xb, yb, 1.0f);
        const float d_norm = d_cam.norm();
        const float cos_inc = n_over_c.dot(d_cam) / (n_over_c.norm() * d_norm);
        if (!(cos_inc >= c.min_cos_incidence)) {
          ++stats.grazing;
          continue;
        }
        const float sigma_m = endpoint_sigma_m(c, z, d_norm);
        float margin = c.margin_min_m + c.k_sigma * sigma_m;
        rc.n = -(R * n_over_c).normalized();
        const int cluster = normal_cluster(rc.n);
        // Voting on a cluster whose prior is thick (check on measured planes): free only beyond its spread.
        if (vote) margin = std::max(margin, rc.cluster_margin_floor_m[static_cast<size_t>(cluster)]);
        if (vote && !rc.cluster_votes[static_cast<size_t>(cluster)]) {
          ++stats.unverified;
          continue;
        }
        rc.cluster = cluster;
        rc.ray_near = rc.ray_hit = false;
        rc.d = R * d_cam;
        rc.q = o + z * rc.d;
        rc.d_norm = d_norm;
        rc.margin_m = margin;
        rc.occupied_band_m = c.margin_min_m + c.k_sigma_occupied * sigma_m;
        ++stats.rays;
        if (n == 0) continue;
        // Past the endpoint only points on the measured plane matter (occupied): at incidence cos_inc
        // the ray stays within margin + radius of the plane for that range divided by cos_inc. Check
        // rays go on to check_reach_behind_m: a prior surface behind the measured one is "far".
        const float behind_m = vote ? margin : std::max(margin, c.check_reach_behind_m);
        cast_ray(&rc, z + (behind_m + c.point_radius_m) / (d_norm * cos_inc));
        if (pass == Pass::kCheck) finish_check_ray(&rc, cluster);
      }
    }
  }

  // The local planes of every stride-th pixel from (offset, offset) (header: point-to-plane normal
  // equations) into out[0, capacity); returns how many.
  int measure(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K, const PlaneSamplingParams& p,
              MeasuredPlane* out, int capacity) const {
    const FreeSpaceCarverConfig& c = config;
    const float fx = static_cast<float>(K.fx), fy = static_cast<float>(K.fy);
    const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
    const float max_depth_m = p.max_depth_m > 0.0f ? p.max_depth_m : c.max_depth_m;
    int n_out = 0;
    for (int v = p.offset_px; v < depth_m.rows && n_out < capacity; v += p.stride_px) {
      for (int u = p.offset_px; u < depth_m.cols && n_out < capacity; u += p.stride_px) {
        const float z_raw = depth_m.ptr<float>(v)[u];
        if (!std::isfinite(z_raw) || z_raw <= 0.0f || z_raw > 1.2f * max_depth_m) continue;
        const float xb = (static_cast<float>(u) - cx) / fx, yb = (static_cast<float>(v) - cy) / fy;
        Eigen::Vector3f n_over_c;
        int count = 0;
        float max_dev = 0.0f, rms = 0.0f;
        if (!fit_plane(depth_m, u, v, p.plane_radius_px, p.plane_step_px, fx, fy, xb, yb, &n_over_c, &count,
                       &max_dev, &rms)) {
          continue;
        }
        const Eigen::Vector3f d_cam(xb, yb, 1.0f);
        const float w0 = n_over_c.dot(d_cam);
        // The fit's residuals against the noise of 1/z, sigma_z / z² = k + m0 w² (header): a window
        // across a crease (floor meeting wall) or a depth edge fails one of the two tests.
        const float sigma_w = c.depth_noise_k + p.depth_noise_m0 * w0 * w0;
        if (!(max_dev <= p.max_dev_sigmas * sigma_w + c.planarity_rel * 0.1f * w0) ||
            !(rms <= p.max_rms_sigmas * sigma_w)) {
          continue;
        }
        const float z = 1.0f / w0;
        if (!(z >= c.min_depth_m && z <= max_depth_m)) continue;
        const float d_norm = d_cam.norm();
        const float cos_inc = n_over_c.dot(d_cam) / (n_over_c.norm() * d_norm);
        if (!(cos_inc >= c.min_cos_incidence)) continue;
        // Noise along the normal: the prior's own, and the range noise of the fit's endpoint.
        const float s_range_m = (p.depth_noise_m0 + c.depth_noise_k * z * z) * d_norm * cos_inc /
                                std::sqrt(static_cast<float>(count));
        const float sigma_m = std::sqrt(c.margin_min_m * c.margin_min_m + s_range_m * s_range_m);
        // Zero noise (margin_min_m, depth_noise_k and m0 all 0): no weight can be given, skip.
        if (!(sigma_m > 0.0f)) continue;
        MeasuredPlane& mp = out[n_out++];
        mp.d_cam = d_cam;
        mp.z_m = z;
        mp.n_cam = -n_over_c.normalized();
        mp.cos_inc = cos_inc;
        mp.sigma_m = sigma_m;
      }
    }
    return n_out;
  }

  // Casts the ray rc->d from rc->o to tfar with a fresh ray stamp; the intersection filter sees every
  // sphere it crosses (classified per rc->pass, header). One BVH traversal, no allocation.
  void cast_ray(RayContext* rc, float tfar) {
    if (++ray_id == 0) {  // wrapped after 2^32 rays: old stamps could collide
      std::fill_n(stamps.begin(), n, 0u);
      ray_id = 1;
    }
    rc->stamp = ray_id;
    RTCRayHit rh;
    rh.ray.org_x = rc->o.x();
    rh.ray.org_y = rc->o.y();
    rh.ray.org_z = rc->o.z();
    rh.ray.dir_x = rc->d.x();
    rh.ray.dir_y = rc->d.y();
    rh.ray.dir_z = rc->d.z();
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = tfar;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &rc->embree, &rh);
  }

  // Casts the measured planes from T_prior_cam and adds their point-to-plane residuals to *system.
  void cast_planes(const MeasuredPlane* planes, int n_planes, const Eigen::Isometry3d& T_prior_cam,
                   const PointToPlaneParams& params, PointToPlaneSystem* system) {
    const Eigen::Matrix3f R = T_prior_cam.linear().cast<float>();
    const Eigen::Vector3f o = T_prior_cam.translation().cast<float>();
    RayContext rc;
    rtcInitIntersectContext(&rc.embree);
    rc.self = this;
    rc.o = o;
    rc.pass = Pass::kAlign;
    for (int i = 0; i < n_planes; ++i) {
      const MeasuredPlane& mp = planes[i];
      ++system->rays_cast;
      rc.d = R * mp.d_cam;
      rc.q = o + mp.z_m * rc.d;
      rc.n = R * mp.n_cam;
      rc.d_norm = mp.d_cam.norm();
      rc.align_c_m = params.window_m;
      if (params.tukey_c_sigmas > 0.0f)
        rc.align_c_m = std::min(params.window_m, params.tukey_c_sigmas * mp.sigma_m);
      rc.align_w = rc.align_ws = 0.0f;
      rc.align_wp.setZero();
      rc.align_n = 0;
      cast_ray(&rc, mp.z_m + (rc.align_c_m + config.point_radius_m) / (rc.d_norm * mp.cos_inc));
      if (rc.align_n > 0 && rc.align_w > 0.0f) add_residual(rc, R, o, mp, system);
    }
  }

  // The pose check's pass on measured planes (header: observe with check planes): each plane's ray,
  // endpoint and normal instead of a sparse pixel's ±normal_window_px differences.
  void cast_check_planes(const MeasuredPlane* planes, int n_planes, const Eigen::Isometry3d& T_prior_cam,
                         RayContext* rc_out) {
    const FreeSpaceCarverConfig& c = config;
    const Eigen::Matrix3f R = T_prior_cam.linear().cast<float>();
    const Eigen::Vector3f o = T_prior_cam.translation().cast<float>();
    RayContext& rc = *rc_out;
    rtcInitIntersectContext(&rc.embree);
    rc.self = this;
    rc.o = o;
    rc.pass = Pass::kCheck;
    rc.per_ray = true;
    rc.bias_window_m = c.bias_window_m;
    rc.ray_log = check_rays.data();
    rc.ray_log_capacity = static_cast<int>(check_rays.size());
    rc.ray_log_n = 0;
    for (int i = 0; i < n_planes; ++i) {
      const MeasuredPlane& mp = planes[i];
      const float z = mp.z_m;
      if (!(z >= c.min_depth_m && z <= c.max_depth_m) || !(mp.cos_inc >= c.min_cos_incidence)) continue;
      const float d_norm = mp.d_cam.norm();
      rc.margin_m = c.margin_min_m + c.k_sigma * endpoint_sigma_m(c, z, d_norm);
      rc.n = R * mp.n_cam;
      const int cluster = normal_cluster(rc.n);
      rc.cluster = cluster;
      rc.ray_near = rc.ray_hit = false;
      rc.band_sum_s = 0.0f;
      rc.band_n = 0;
      rc.d = R * mp.d_cam;
      rc.q = o + z * rc.d;
      rc.d_norm = d_norm;
      const float behind_m = std::max(rc.margin_m, c.check_reach_behind_m);
      cast_ray(&rc, z + (behind_m + c.point_radius_m) / (d_norm * mp.cos_inc));
      finish_check_ray(&rc, cluster);
    }
  }

  core::Status embree_status(const char* what) {
    const std::lock_guard<std::mutex> lock(error_mutex);
    if (error.empty()) return core::Status::Ok();
    core::Status st = core::Internal(std::string(what) + ": " + error);
    error.clear();
    return st;
  }
};

FreeSpaceCarver::FreeSpaceCarver(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FreeSpaceCarver::FreeSpaceCarver(FreeSpaceCarver&&) noexcept = default;
FreeSpaceCarver& FreeSpaceCarver::operator=(FreeSpaceCarver&&) noexcept = default;
FreeSpaceCarver::~FreeSpaceCarver() = default;

core::Expected<FreeSpaceCarver> FreeSpaceCarver::create(const FreeSpaceCarverConfig& c, int max_points) {
  if (!positive_finite(c.point_radius_m) || !positive_finite(c.min_depth_m) ||
      !positive_finite(c.max_depth_m) || c.min_depth_m >= c.max_depth_m) {
    return core::InvalidArgument(
        "free-space carver: point_radius_m, min_depth_m and max_depth_m must be positive and finite with "
        "min_depth_m < max_depth_m (got " +
        std::to_string(c.point_radius_m) + ", " + std::to_string(c.min_depth_m) + ", " +
        std::to_string(c.max_depth_m) + ")");
  }
  if (!(std::isfinite(c.depth_noise_k) && c.depth_noise_k >= 0) ||
      !(std::isfinite(c.k_sigma) && c.k_sigma >= 0) ||
      !(std::isfinite(c.margin_min_m) && c.margin_min_m >= 0) ||
      !(std::isfinite(c.pose_sigma_m) && c.pose_sigma_m >= 0) ||
      !(std::isfinite(c.pose_sigma_rad) && c.pose_sigma_rad >= 0) ||
      !(std::isfinite(c.k_sigma_occupied) && c.k_sigma_occupied >= 0 && c.k_sigma_occupied <= c.k_sigma) ||
      !(std::isfinite(c.planarity_sigmas) && c.planarity_sigmas >= 0) ||
      !(std::isfinite(c.planarity_rel) && c.planarity_rel >= 0) ||
      !(std::isfinite(c.free_ratio) && c.free_ratio >= 0) ||
      !(std::isfinite(c.spread_margin_iqrs) && c.spread_margin_iqrs >= 0)) {
    return core::InvalidArgument(
        "free-space carver: depth_noise_k, k_sigma, margin_min_m, pose_sigma_m, pose_sigma_rad, "
        "planarity_sigmas, planarity_rel, free_ratio and spread_margin_iqrs must be finite and >= 0, and "
        "0 <= k_sigma_occupied <= k_sigma");
  }
  if (!(std::isfinite(c.max_iqr_to_margin_trend) && c.max_iqr_to_margin_trend > 0)) {
    return core::InvalidArgument("free-space carver: max_iqr_to_margin_trend must be positive (got " +
                                 std::to_string(c.max_iqr_to_margin_trend) + ")");
  }
  if (c.max_check_rays < 0) {
    return core::InvalidArgument("free-space carver: max_check_rays must be >= 0 (got " +
                                 std::to_string(c.max_check_rays) + ")");
  }
  if (!(c.min_cos_incidence > 0.0f && c.min_cos_incidence <= 1.0f)) {
    return core::InvalidArgument("free-space carver: min_cos_incidence must be in (0, 1] (got " +
                                 std::to_string(c.min_cos_incidence) + ")");
  }
  if (!(std::isfinite(c.max_surface_bias_m) && c.max_surface_bias_m > 0) || !(c.median_sigmas >= 0.0f) ||
      !(std::isfinite(c.bias_window_m) && c.bias_window_m > c.max_surface_bias_m) ||
      !(std::isfinite(c.max_iqr_to_margin) && c.max_iqr_to_margin > 0) ||
      !(std::isfinite(c.check_reach_behind_m) && c.check_reach_behind_m >= c.bias_window_m) ||
      !(c.min_near_fraction >= 0.0f && c.min_near_fraction <= 1.0f) || c.bias_check_subsample < 0 ||
      c.min_bias_pairs < 1 || c.min_cluster_rays < 1) {
    return core::InvalidArgument(
        "free-space carver: pose check needs max_surface_bias_m > 0, bias_window_m > max_surface_bias_m, "
        "check_reach_behind_m >= bias_window_m, max_iqr_to_margin > 0, min_near_fraction in [0, 1], "
        "bias_check_subsample >= 0, min_bias_pairs >= 1 and min_cluster_rays >= 1");
  }
  if (c.embree_threads < 1) {
    return core::InvalidArgument("free-space carver: embree_threads must be >= 1 (got " +
                                 std::to_string(c.embree_threads) + ")");
  }
  if (c.normal_window_px < 1 || c.min_free_hits < 1) {
    return core::InvalidArgument("free-space carver: normal_window_px and min_free_hits must be >= 1 (got " +
                                 std::to_string(c.normal_window_px) + ", " + std::to_string(c.min_free_hits) +
                                 ")");
  }
  if (max_points < 0) {
    return core::InvalidArgument("free-space carver: max_points must be >= 0 (got " +
                                 std::to_string(max_points) + ")");
  }
  auto impl = std::make_unique<Impl>();
  impl->config = c;
  impl->max_points = max_points;
  // Without a thread count Embree starts a worker per core (its config string: "threads=N").
  const std::string device_config = "threads=" + std::to_string(c.embree_threads);
  impl->device = rtcNewDevice(device_config.c_str());
  if (!impl->device) {
    return core::Unavailable("free-space carver: cannot create the Embree device (error " +
                             std::to_string(rtcGetDeviceError(nullptr)) + ")");
  }
  rtcSetDeviceErrorFunction(impl->device, &Impl::on_error, impl.get());
  const size_t cap = static_cast<size_t>(max_points);
  impl->spheres.assign(4 * (cap + 1), 0.0f);
  impl->stamps.assign(cap, 0);
  impl->check_rays.resize(static_cast<size_t>(c.max_check_rays));
  impl->free_hits.assign(cap, 0);
  impl->occupied_hits.assign(cap, 0);
  return FreeSpaceCarver(std::move(impl));
}

core::Status FreeSpaceCarver::set_prior(const CloudPoint* points_prior, int n) {
  Impl& m = *impl_;
  if (n < 0 || (n > 0 && points_prior == nullptr)) {
    return core::InvalidArgument(
        "free-space carver: set_prior needs n >= 0 points and a non-null array (n = " + std::to_string(n) +
        ")");
  }
  if (n > m.max_points) {
    return core::OutOfRange("free-space carver: prior has " + std::to_string(n) + " points, capacity is " +
                            std::to_string(m.max_points) + " (raise max_points at create())");
  }
  for (int i = 0; i < n; ++i) {
    const CloudPoint& p = points_prior[i];
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m)) {
      return core::InvalidArgument("free-space carver: prior point " + std::to_string(i) + " is not finite");
    }
  }
  if (m.scene) {
    rtcReleaseScene(m.scene);
    m.scene = nullptr;
  }
  m.n = 0;
  for (int i = 0; i < n; ++i) {
    float* s = &m.spheres[4 * static_cast<size_t>(i)];
    s[0] = points_prior[i].x_m;
    s[1] = points_prior[i].y_m;
    s[2] = points_prior[i].z_m;
    s[3] = m.config.point_radius_m;
  }
  std::fill_n(m.stamps.begin(), n, 0u);
  std::fill_n(m.free_hits.begin(), n, uint16_t{0});
  std::fill_n(m.occupied_hits.begin(), n, uint16_t{0});
  m.ray_id = 0;

  m.scene = rtcNewScene(m.device);
  if (n > 0) {
    RTCGeometry geom = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, m.spheres.data(), 0,
                               4 * sizeof(float), static_cast<size_t>(n));
    rtcSetGeometryIntersectFilterFunction(geom, &Impl::filter);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(m.scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(m.scene);
  HWR_RETURN_IF_ERROR(m.embree_status("free-space carver: building the prior's BVH"));
  m.n = n;
  return core::Status::Ok();
}

namespace {

// The checks observe() and measure_planes() share.
core::Status check_frame(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                         const Eigen::Isometry3d& T_prior_cam, int stride_px, bool has_scene) {
  if (!K.valid()) return core::InvalidArgument("free-space carver: invalid intrinsics");
  if (depth_m.type() != CV_32FC1 || depth_m.cols != K.width || depth_m.rows != K.height) {
    return core::InvalidArgument("free-space carver: depth must be CV_32FC1 of " + std::to_string(K.width) +
                                 "x" + std::to_string(K.height) + " (got type " +
                                 std::to_string(depth_m.type()) + ", " + std::to_string(depth_m.cols) + "x" +
                                 std::to_string(depth_m.rows) + ")");
  }
  if (stride_px < 1) {
    return core::InvalidArgument("free-space carver: stride_px must be >= 1 (got " +
                                 std::to_string(stride_px) + ")");
  }
  if (!is_rigid(T_prior_cam)) {
    return core::InvalidArgument(
        "free-space carver: T_prior_cam is not a finite rigid transform (rotation must be orthonormal)");
  }
  if (!has_scene) {
    return core::InvalidArgument("free-space carver: a frame cast before set_prior()");
  }
  return core::Status::Ok();
}

}  // namespace

float PointToPlaneSystem::median_abs_residual_sigmas() const {
  if (residuals <= 0) return 0.0f;
  const double target = 0.5 * residuals;
  int64_t below = 0;
  int bin = 0;
  while (bin < kResidualBins - 1 &&
         static_cast<double>(below + abs_residual_hist[static_cast<size_t>(bin)]) <= target) {
    below += abs_residual_hist[static_cast<size_t>(bin)];
    ++bin;
  }
  return (static_cast<float>(bin) + 0.5f) * kResidualBinSigmas;
}

core::Expected<int> FreeSpaceCarver::measure_planes(const cv::Mat& depth_m, const hal::PinholeIntrinsics& K,
                                                    const PlaneSamplingParams& params, MeasuredPlane* out,
                                                    int capacity) const {
  HWR_RETURN_IF_ERROR(check_frame(depth_m, K, Eigen::Isometry3d::Identity(), params.stride_px, true));
  if (params.offset_px < 0 || params.plane_radius_px < 1 || params.plane_step_px < 1 || capacity < 0 ||
      (capacity > 0 && out == nullptr)) {
    return core::InvalidArgument(
        "free-space carver: measure_planes needs offset_px >= 0, plane_radius_px and plane_step_px >= 1 and "
        "an output array of capacity >= 0 (got offset " +
        std::to_string(params.offset_px) + ", radius " + std::to_string(params.plane_radius_px) + ", step " +
        std::to_string(params.plane_step_px) + ", capacity " + std::to_string(capacity) + ")");
  }
  return impl_->measure(depth_m, K, params, out, capacity);
}

core::Status FreeSpaceCarver::accumulate_point_to_plane(const MeasuredPlane* planes, int n_planes,
                                                        const Eigen::Isometry3d& T_prior_cam,
                                                        const PointToPlaneParams& params,
                                                        PointToPlaneSystem* system) {
  Impl& m = *impl_;
  if (n_planes < 0 || (n_planes > 0 && planes == nullptr) || system == nullptr ||
      !(std::isfinite(params.window_m) && params.window_m > 0.0f) || !std::isfinite(params.tukey_c_sigmas)) {
    return core::InvalidArgument(
        "free-space carver: point-to-plane needs planes (n >= 0), a system, a positive finite window_m and a "
        "finite tukey_c_sigmas (got n " +
        std::to_string(n_planes) + ", window " + std::to_string(params.window_m) + " m)");
  }
  if (!is_rigid(T_prior_cam)) {
    return core::InvalidArgument(
        "free-space carver: T_prior_cam is not a finite rigid transform (rotation must be orthonormal)");
  }
  if (m.scene == nullptr) return core::InvalidArgument("free-space carver: a frame cast before set_prior()");
  if (m.n == 0) return core::Status::Ok();
  ScopedFlushDenormals ftz;
  m.cast_planes(planes, n_planes, T_prior_cam, params, system);
  return m.embree_status("free-space carver: casting point-to-plane rays");
}

core::Expected<FreeSpaceObserveStats> FreeSpaceCarver::observe(const cv::Mat& depth_m,
                                                               const hal::PinholeIntrinsics& K,
                                                               const Eigen::Isometry3d& T_prior_cam,
                                                               int stride_px) {
  return observe(depth_m, K, T_prior_cam, stride_px, nullptr, 0);
}

core::Expected<FreeSpaceObserveStats> FreeSpaceCarver::observe(
    const cv::Mat& depth_m, const hal::PinholeIntrinsics& K, const Eigen::Isometry3d& T_prior_cam,
    int stride_px, const MeasuredPlane* check_planes, int n_check_planes) {
  Impl& m = *impl_;
  const FreeSpaceCarverConfig& c = m.config;
  HWR_RETURN_IF_ERROR(check_frame(depth_m, K, T_prior_cam, stride_px, m.scene != nullptr));
  if (n_check_planes < 0 || (n_check_planes > 0 && check_planes == nullptr)) {
    return core::InvalidArgument("free-space carver: check planes must be a non-null array of n >= 0 (got " +
                                 std::to_string(n_check_planes) + ")");
  }

  ScopedFlushDenormals ftz;
  FreeSpaceObserveStats stats;
  Impl::RayContext rc;
  rc.cluster_votes.fill(true);
  if (m.n > 0 && c.bias_check_subsample > 0) {
    // Pose check first (header): a sparse pass that only measures near / far rays and residuals.
    Impl::RayContext check;
    FreeSpaceObserveStats ignored;
    if (check_planes != nullptr) {
      m.cast_check_planes(check_planes, n_check_planes, T_prior_cam, &check);
    } else {
      m.cast(depth_m, K, T_prior_cam, stride_px * c.bias_check_subsample, Impl::Pass::kCheck, &check,
             &ignored);
    }
    bool any_failed = false;
    for (int k = 0; k < kNormalClusters; ++k) {
      const size_t kk = static_cast<size_t>(k);
      SurfaceClusterCheck& cl = stats.clusters[kk];
      rc.cluster_votes[kk] = false;  // until it passes
      cl.near_rays = check.near_rays[kk];
      cl.far_rays = check.far_rays[kk];
      cl.pairs = check.surface_pairs[kk];
      if (cl.pairs > 0) {
        // Quartiles of s from the histogram (bin centres): robust to changed geometry in the window.
        cl.median_m = Impl::quantile(check, k, 0.5, c.bias_window_m);
        cl.iqr_m =
            Impl::quantile(check, k, 0.75, c.bias_window_m) - Impl::quantile(check, k, 0.25, c.bias_window_m);
        cl.margin_m = static_cast<float>(check.margin_sum_m[kk] / static_cast<double>(cl.pairs));
      }
      const int checkable = cl.near_rays + cl.far_rays;
      cl.checked = checkable >= c.min_cluster_rays;
      if (!cl.checked) continue;  // unverified: its rays cast nothing
      // The median's own noise: its standard error is ~1.2533 sigma / sqrt(n) with sigma ~ IQR / 1.349
      // (normal residuals), so a median within median_sigmas of it is no evidence of a bias.
      const float median_se_m =
          0.929f * cl.iqr_m / std::sqrt(static_cast<float>(std::max<int64_t>(cl.pairs, 1)));
      const float max_bias_m = std::max(c.max_surface_bias_m, c.median_sigmas * median_se_m);
      // A rotation: the residuals' spread (the sparse pass), or on measured planes with the trend
      // test their tilt across the cluster (header), which a thick prior does not have.
      bool rotation_ok = cl.iqr_m <= c.max_iqr_to_margin * cl.margin_m;
      if (check_planes != nullptr && c.trend_check_on_planes) {
        float se_m = 0;
        cl.trend_measured = Impl::residual_trend(check, k, cl.median_m, cl.iqr_m, &cl.trend_m, &se_m);
        cl.trend_limit_m = c.max_surface_bias_m + c.median_sigmas * se_m;
        rotation_ok = cl.trend_measured && cl.trend_m <= cl.trend_limit_m &&
                      cl.iqr_m <= c.max_iqr_to_margin_trend * cl.margin_m;
      }
      cl.passed = static_cast<float>(cl.near_rays) >= c.min_near_fraction * static_cast<float>(checkable) &&
                  std::abs(cl.median_m) <= max_bias_m && rotation_ok;
      any_failed = any_failed || !cl.passed;
      if (cl.passed) stats.surface_pairs += cl.pairs;
      rc.cluster_votes[kk] = cl.passed;
      if (check_planes != nullptr) rc.cluster_margin_floor_m[kk] = c.spread_margin_iqrs * cl.iqr_m;
    }
    stats.pose_check = any_failed                               ? PoseCheck::kMisaligned
                       : stats.surface_pairs < c.min_bias_pairs ? PoseCheck::kTooFewPairs
                                                                : PoseCheck::kAligned;
    stats.misaligned = stats.pose_check != PoseCheck::kAligned;
  }
  if (!stats.misaligned) m.cast(depth_m, K, T_prior_cam, stride_px, Impl::Pass::kVote, &rc, &stats);
  stats.free_votes = rc.free_votes;
  stats.occupied_votes = rc.occupied_votes;
  HWR_RETURN_IF_ERROR(m.embree_status("free-space carver: casting rays"));
  return stats;
}

int FreeSpaceCarver::prior_size() const { return impl_->n; }
int FreeSpaceCarver::capacity() const { return impl_->max_points; }
const FreeSpaceCarverConfig& FreeSpaceCarver::config() const { return impl_->config; }
uint16_t FreeSpaceCarver::free_hits(int i) const { return impl_->free_hits[static_cast<size_t>(i)]; }
uint16_t FreeSpaceCarver::occupied_hits(int i) const { return impl_->occupied_hits[static_cast<size_t>(i)]; }

bool FreeSpaceCarver::deleted(int i) const {
  const float f = impl_->free_hits[static_cast<size_t>(i)];
  const float occ = impl_->occupied_hits[static_cast<size_t>(i)];
  return f >= static_cast<float>(impl_->config.min_free_hits) && f > impl_->config.free_ratio * occ;
}

int FreeSpaceCarver::deleted_count() const {
  int count = 0;
  for (int i = 0; i < impl_->n; ++i) count += deleted(i) ? 1 : 0;
  return count;
}

core::Expected<int> FreeSpaceCarver::apply(std::vector<CloudPoint>* points_prior) const {
  if (points_prior == nullptr || points_prior->size() != static_cast<size_t>(impl_->n)) {
    return core::InvalidArgument("free-space carver: apply() needs the " + std::to_string(impl_->n) +
                                 " points given to set_prior() (got " +
                                 (points_prior ? std::to_string(points_prior->size()) : std::string("null")) +
                                 ")");
  }
  size_t kept = 0;
  for (int i = 0; i < impl_->n; ++i) {
    if (!deleted(i)) (*points_prior)[kept++] = (*points_prior)[static_cast<size_t>(i)];
  }
  const int removed = impl_->n - static_cast<int>(kept);
  points_prior->resize(kept);
  return removed;
}

}  // namespace hwr::recon
