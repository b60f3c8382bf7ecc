// Embree renderer: one static triangle mesh (RTC_BUILD_QUALITY_HIGH), primary rays traced in
// coherent packets over 4x4 / 4x2 / 2x2 pixel tiles, textured Lambertian shading; optionally a
// shadow ray per hit towards the directional light and ambient-occlusion rays over the hit's
// hemisphere, traced in packets of the same width (RenderOptions::shadows, ambient_occlusion_rays).
//
// Ray of pixel (u, v): d_cam = K^-1 [u v 1]^T = ((u - cx) / fx, (v - cy) / fy, 1). Because
// d_cam.z = 1, the hit parameter t along d is directly the z-depth of the hit in the camera frame.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <embree3/rtcore.h>
#include <opencv2/core.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "hwr/sim/renderer.hpp"
#include "hwr/sim/random.hpp"
#include "scene_mesh.hpp"
#include "texture.hpp"

namespace hwr::sim {
namespace {

// What the shader needs of a triangle, one cache line each.
struct alignas(64) TriShade {
  float n[3];  // unit geometric normal (scene frame)
  // Texture coordinates (level-0 texels) of a scene point p: u = pu . [p 1], v = pv . [p 1]. The
  // rows project onto the plane of the two axes other than the normal's dominant one, scaled by
  // the material's texel density, offset per object so equal materials look different.
  float pu[4];
  float pv[4];
  float texels_per_m2;  // squared texel density (mip selection)
  uint8_t material;
  uint8_t cylinder;  // pipe side: smooth normal from the object's axis
  uint32_t object;
};

struct CylinderAxis {
  float p[3];  // point on the axis
  float a[3];  // unit axis direction
};

// Embree wants flush-to-zero and denormals-are-zero; set them for the duration of a call only.
class ScopedFlushDenormals {
 public:
#if defined(__SSE2__)
  ScopedFlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | 0x8040u); }
  ~ScopedFlushDenormals() { _mm_setcsr(saved_); }

 private:
  unsigned saved_;
#endif
};

// Per-render constants of the shader.
struct ShadeContext {
  const TriShade* tris;
  const CylinderAxis* cylinders;
  const detail::Texture* textures;
  float org[3];
  float light[3];  // unit vector towards the light
  float ambient, diffuse;
  bool shadows;                                  // RenderOptions::shadows (with a positive range)
  bool light_rays;                               // shadows or ao_rays: light_visibility() runs
  float shadow_range;                            // RenderOptions::shadow_range_m
  int ao_rays;                                   // RenderOptions::ambient_occlusion_rays (0: off)
  float ao_range;                                // RenderOptions::ambient_occlusion_range_m
  std::array<std::array<float, 3>, 64> ao_dirs;  // the first ao_rays: ao_directions()
  float inv_f2;                                  // (pixel footprint at unit depth)^2
  float min_depth, max_depth;
  uint8_t background[3];
};

#if defined(__GNUC__)
#define HWR_FORCE_INLINE inline __attribute__((always_inline))
#else
#define HWR_FORCE_INLINE inline
#endif

inline void intersect(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRayHit4* rh) {
  rtcIntersect4(valid, scene, ctx, rh);
}
inline void intersect(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRayHit8* rh) {
  rtcIntersect8(valid, scene, ctx, rh);
}
inline void intersect(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRayHit16* rh) {
  rtcIntersect16(valid, scene, ctx, rh);
}
inline void occluded(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRay4* r) {
  rtcOccluded4(valid, scene, ctx, r);
}
inline void occluded(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRay8* r) {
  rtcOccluded8(valid, scene, ctx, r);
}
inline void occluded(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RTCRay16* r) {
  rtcOccluded16(valid, scene, ctx, r);
}
// One ray in the packets' layout, traced with rtcOccluded1 (the scalar path: no packet support needed).
struct Ray1 {
  float org_x[1], org_y[1], org_z[1], tnear[1], dir_x[1], dir_y[1], dir_z[1], time[1], tfar[1];
  unsigned mask[1], id[1], flags[1];
};
inline void occluded(const int* valid, RTCScene scene, RTCIntersectContext* ctx, Ray1* r) {
  if (!valid[0]) return;
  RTCRay ray;
  ray.org_x = r->org_x[0], ray.org_y = r->org_y[0], ray.org_z = r->org_z[0];
  ray.dir_x = r->dir_x[0], ray.dir_y = r->dir_y[0], ray.dir_z = r->dir_z[0];
  ray.tnear = r->tnear[0];
  ray.tfar = r->tfar[0];
  ray.time = r->time[0];
  ray.mask = r->mask[0];
  ray.id = r->id[0];
  ray.flags = r->flags[0];
  rtcOccluded1(scene, ctx, &ray);
  r->tfar[0] = ray.tfar;
}

// Ambient-occlusion directions in a hit's tangent frame (b1, b2, n): cosine-weighted, stratified in
// cos^2(polar angle) and spread in azimuth by the golden angle (the same for every hit: a noise-free
// estimate of how much of the sky the point sees, cosine weighted as a Lambertian surface takes it).
std::array<std::array<float, 3>, 64> ao_directions(int rays) {
  std::array<std::array<float, 3>, 64> d{};
  for (int j = 0; j < rays; ++j) {
    const double u = (j + 0.5) / rays, phi = 2.399963229728653 * j;  // golden angle
    const double r = std::sqrt(u);
    d[static_cast<size_t>(j)] = {static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi)),
                                 static_cast<float>(std::sqrt(1.0 - u))};
  }
  return d;
}

// How the light reaches the hits of one packet of N lanes (hit[i]: lane i hit a triangle; t, prim and
// the scene-frame ray direction d as the primary rays'): lit[i] = 0 where a shadow ray towards the
// light meets a surface within shadow_range (else 1), open[i] = the share of the ambient-occlusion
// rays that meet none within ao_range (else 1). The rays start at the hit, lifted 0.1 mm off the
// surface on the camera's side (the side that is shaded), and use the triangle's normal (a pipe's
// smooth shading normal differs by less than its facets' angle; near a pipe's terminator a facet
// may skip the shadow test). RayN: an Embree ray packet of >= N lanes, or Ray1.
template <int N, class RayN>
void light_visibility(const ShadeContext& c, RTCScene scene, const bool* hit, const float* t,
                      const unsigned* prim, const float* dx, const float* dy, const float* dz, float* lit,
                      float* open) {
  constexpr float kLiftM = 1e-4f;
  static_assert(N <= static_cast<int>(sizeof(RayN::tfar) / sizeof(float)), "packet too narrow");
  constexpr int kLanes = static_cast<int>(sizeof(RayN::tfar) / sizeof(float));
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  alignas(64) RayN ray;
  alignas(64) int valid[kLanes];
  float n_side[N][3] = {}, org[N][3] = {};
  for (int i = 0; i < kLanes; ++i) {
    valid[i] = 0;
    ray.org_x[i] = ray.org_y[i] = ray.org_z[i] = 0.0f;
    ray.dir_x[i] = ray.dir_y[i] = ray.dir_z[i] = 0.0f;
    ray.tfar[i] = 0.0f;
    ray.tnear[i] = 0.0f;
    ray.time[i] = 0.0f;
    ray.mask[i] = ~0u;
    ray.id[i] = static_cast<unsigned>(i);
    ray.flags[i] = 0;
  }
  for (int i = 0; i < N; ++i) {
    lit[i] = 1.0f;
    open[i] = 1.0f;
    if (!hit[i]) continue;
    const TriShade& s = c.tris[prim[i]];
    const float facing = s.n[0] * dx[i] + s.n[1] * dy[i] + s.n[2] * dz[i] > 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; ++k) n_side[i][k] = facing * s.n[k];
    org[i][0] = c.org[0] + t[i] * dx[i] + kLiftM * n_side[i][0];
    org[i][1] = c.org[1] + t[i] * dy[i] + kLiftM * n_side[i][1];
    org[i][2] = c.org[2] + t[i] * dz[i] + kLiftM * n_side[i][2];
  }
  auto trace = [&](auto direction, float range, auto on_blocked) {
    bool any = false;
    for (int i = 0; i < kLanes; ++i) {
      float dir[3] = {0.0f, 0.0f, 0.0f};
      valid[i] = i < N && hit[i] && direction(i, dir) ? -1 : 0;
      any = any || valid[i] != 0;
      if (!valid[i]) continue;
      ray.org_x[i] = org[i][0];
      ray.org_y[i] = org[i][1];
      ray.org_z[i] = org[i][2];
      ray.dir_x[i] = dir[0];
      ray.dir_y[i] = dir[1];
      ray.dir_z[i] = dir[2];
      ray.tfar[i] = range;
    }
    if (!any) return;
    occluded(valid, scene, &ctx, &ray);
    for (int i = 0; i < N; ++i)
      if (valid[i] && ray.tfar[i] < 0.0f) on_blocked(i);  // Embree sets an occluded ray's tfar to -inf
  };
  if (c.shadows) {
    // Only a side facing the light has direct light to lose (n . l <= 0 is shaded ambient only).
    trace(
        [&](int i, float* dir) {
          for (int k = 0; k < 3; ++k) dir[k] = c.light[k];
          return n_side[i][0] * c.light[0] + n_side[i][1] * c.light[1] + n_side[i][2] * c.light[2] > 0.0f;
        },
        c.shadow_range, [&](int i) { lit[i] = 0.0f; });
  }
  if (c.ao_rays > 0) {
    float b1[N][3] = {}, b2[N][3] = {};
    for (int i = 0; i < N; ++i) {
      if (!hit[i]) continue;
      const float* n = n_side[i];
      // b1 = normalize(a x n) with a = x, or y where n is near x; b2 = n x b1.
      const float a[3] = {std::fabs(n[0]) < 0.9f ? 1.0f : 0.0f, std::fabs(n[0]) < 0.9f ? 0.0f : 1.0f, 0.0f};
      float x[3] = {a[1] * n[2] - a[2] * n[1], a[2] * n[0] - a[0] * n[2], a[0] * n[1] - a[1] * n[0]};
      const float inv = 1.0f / std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
      for (int k = 0; k < 3; ++k) b1[i][k] = x[k] * inv;
      b2[i][0] = n[1] * b1[i][2] - n[2] * b1[i][1];
      b2[i][1] = n[2] * b1[i][0] - n[0] * b1[i][2];
      b2[i][2] = n[0] * b1[i][1] - n[1] * b1[i][0];
    }
    int blocked[N] = {};
    for (int j = 0; j < c.ao_rays; ++j) {
      const auto& l = c.ao_dirs[static_cast<size_t>(j)];
      trace(
          [&](int i, float* dir) {
            for (int k = 0; k < 3; ++k) dir[k] = l[0] * b1[i][k] + l[1] * b2[i][k] + l[2] * n_side[i][k];
            return true;
          },
          c.ao_range, [&](int i) { ++blocked[i]; });
    }
    for (int i = 0; i < N; ++i)
      if (hit[i]) open[i] = 1.0f - static_cast<float>(blocked[i]) / static_cast<float>(c.ao_rays);
  }
}

// Shades one hit: t is the z-depth, (dx, dy, dz) the scene-frame ray direction (d_cam.z = 1) with
// squared length d2; lit is 1, or 0 where the hit is in shadow (the diffuse term is dropped); open
// scales the ambient term (the share of the sky the point sees, light_visibility()).
template <bool kDepth>
HWR_FORCE_INLINE void shade_hit(const ShadeContext& c, float t, uint32_t prim, float dx, float dy, float dz,
                                float d2, float lit, float open, uint8_t* bgr, float* depth) {
  const TriShade& s = c.tris[prim];
  const float px = c.org[0] + t * dx, py = c.org[1] + t * dy, pz = c.org[2] + t * dz;
  float nx = s.n[0], ny = s.n[1], nz = s.n[2];
  if (s.cylinder) {
    const CylinderAxis& a = c.cylinders[s.object];
    const float vx = px - a.p[0], vy = py - a.p[1], vz = pz - a.p[2];
    const float along = vx * a.a[0] + vy * a.a[1] + vz * a.a[2];
    const float rx = vx - along * a.a[0], ry = vy - along * a.a[1], rz = vz - along * a.a[2];
    const float len2 = rx * rx + ry * ry + rz * rz;
    if (len2 > 0.0f) {
      const float inv = 1.0f / std::sqrt(len2);
      nx = rx * inv, ny = ry * inv, nz = rz * inv;
    }
  }
  // Two-sided: shade the side facing the camera.
  const float n_dot_d_raw = nx * dx + ny * dy + nz * dz;
  const float facing = n_dot_d_raw > 0.0f ? -1.0f : 1.0f;
  const float n_dot_d = facing * n_dot_d_raw;  // <= 0

  const float u = s.pu[0] * px + s.pu[1] * py + s.pu[2] * pz + s.pu[3];
  const float v = s.pv[0] * px + s.pv[1] * py + s.pv[2] * pz + s.pv[3];
  // Mip level = floor(log2(footprint)), footprint^2 = (t |d| / f)^2 / cos(incidence) texels^2 (area
  // of a pixel on the surface), cos = -n.d / |d|, so footprint^2 = t^2 |d|^3 / (f^2 (-n.d)).
  // |d| in [1, 1.2] for usual fields of view is replaced by (1 + |d|^2) / 2 (< 1 % off there).
  // Flooring (not rounding) keeps half a level more detail: a little aliasing, more corners.
  const float len_d = 0.5f * (1.0f + d2);
  const float f2 = t * t * d2 * len_d * c.inv_f2 * s.texels_per_m2 / std::max(-n_dot_d, 0.05f * len_d);
  const detail::Texture& tex = c.textures[s.material];
  int level = 0;
  if (f2 > 1.0f) {  // level = floor(log2(f2) / 2) from the float exponent
    uint32_t bits;
    std::memcpy(&bits, &f2, sizeof bits);
    level = std::min((static_cast<int>((bits >> 23) & 255u) - 127) >> 1, tex.levels - 1);
  }

  // Lambert: ambient + diffuse * max(0, n . l), applied to the texel in fixed point.
  const float n_dot_l = facing * (nx * c.light[0] + ny * c.light[1] + nz * c.light[2]);
  // Without shadows and occlusion the expression of old: a compiler that fuses multiply-adds (aarch64)
  // would round the longer one differently even with lit = open = 1.
  const float k = c.light_rays ? c.ambient * open + c.diffuse * lit * std::max(n_dot_l, 0.0f)
                               : c.ambient + c.diffuse * std::max(n_dot_l, 0.0f);
  detail::sample_shaded(tex, level, u, v, static_cast<uint32_t>(k * 65535.0f + 0.5f), bgr);
  if constexpr (kDepth) *depth = (t >= c.min_depth && t <= c.max_depth) ? t : 0.0f;
}

#if defined(__SSE2__)
// Four hits of flat-shaded triangles at once: the SSE2 twin of shade_hit(), with the same float
// operations in the same order, so both give the same bytes. Texture lookups stay per lane.
template <bool kDepth>
HWR_FORCE_INLINE void shade4(const ShadeContext& c, const TriShade* const* s, const float* t_in,
                             const float* dx_in, const float* dy_in, const float* dz_in, const float* d2_in,
                             const float* lit, const float* open, uint8_t* const* bgr, float* const* depth) {
  const bool same = s[0] == s[1] && s[0] == s[2] && s[0] == s[3];  // the usual case inside a tile
  auto gather = [&](auto field) {
    return same ? _mm_set1_ps(field(*s[0]))
                : _mm_setr_ps(field(*s[0]), field(*s[1]), field(*s[2]), field(*s[3]));
  };
  const __m128 t = _mm_loadu_ps(t_in), dx = _mm_loadu_ps(dx_in), dy = _mm_loadu_ps(dy_in);
  const __m128 dz = _mm_loadu_ps(dz_in), d2 = _mm_loadu_ps(d2_in);
  const __m128 px = _mm_add_ps(_mm_set1_ps(c.org[0]), _mm_mul_ps(t, dx));
  const __m128 py = _mm_add_ps(_mm_set1_ps(c.org[1]), _mm_mul_ps(t, dy));
  const __m128 pz = _mm_add_ps(_mm_set1_ps(c.org[2]), _mm_mul_ps(t, dz));
  const __m128 nx = gather([](const TriShade& x) { return x.n[0]; });
  const __m128 ny = gather([](const TriShade& x) { return x.n[1]; });
  const __m128 nz = gather([](const TriShade& x) { return x.n[2]; });
  const __m128 sign = _mm_set1_ps(-0.0f);
  const __m128 n_dot_d_raw =
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, dx), _mm_mul_ps(ny, dy)), _mm_mul_ps(nz, dz));
  const __m128 flip = _mm_and_ps(_mm_cmpgt_ps(n_dot_d_raw, _mm_setzero_ps()), sign);  // facing = -1
  const __m128 n_dot_d = _mm_xor_ps(n_dot_d_raw, flip);

  auto project = [&](const __m128& a0, const __m128& a1, const __m128& a2, const __m128& a3) {
    return _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(a0, px), _mm_mul_ps(a1, py)), _mm_mul_ps(a2, pz)), a3);
  };
  alignas(16) float u[4], v[4];
  _mm_store_ps(u, project(gather([](const TriShade& x) { return x.pu[0]; }),
                          gather([](const TriShade& x) { return x.pu[1]; }),
                          gather([](const TriShade& x) { return x.pu[2]; }),
                          gather([](const TriShade& x) { return x.pu[3]; })));
  _mm_store_ps(v, project(gather([](const TriShade& x) { return x.pv[0]; }),
                          gather([](const TriShade& x) { return x.pv[1]; }),
                          gather([](const TriShade& x) { return x.pv[2]; }),
                          gather([](const TriShade& x) { return x.pv[3]; })));

  const __m128 len_d = _mm_mul_ps(_mm_set1_ps(0.5f), _mm_add_ps(_mm_set1_ps(1.0f), d2));
  __m128 f2 = _mm_mul_ps(_mm_mul_ps(_mm_mul_ps(_mm_mul_ps(t, t), d2), len_d), _mm_set1_ps(c.inv_f2));
  f2 = _mm_mul_ps(f2, gather([](const TriShade& x) { return x.texels_per_m2; }));
  f2 = _mm_div_ps(f2, _mm_max_ps(_mm_xor_ps(n_dot_d, sign), _mm_mul_ps(_mm_set1_ps(0.05f), len_d)));
  const __m128i exponent = _mm_sub_epi32(
      _mm_and_si128(_mm_srli_epi32(_mm_castps_si128(f2), 23), _mm_set1_epi32(255)), _mm_set1_epi32(127));
  alignas(16) int32_t level[4];
  _mm_store_si128(
      reinterpret_cast<__m128i*>(level),
      _mm_and_si128(_mm_srai_epi32(exponent, 1), _mm_castps_si128(_mm_cmpgt_ps(f2, _mm_set1_ps(1.0f)))));

  const __m128 n_dot_l = _mm_xor_ps(
      _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, _mm_set1_ps(c.light[0])), _mm_mul_ps(ny, _mm_set1_ps(c.light[1]))),
                 _mm_mul_ps(nz, _mm_set1_ps(c.light[2]))),
      flip);
  const __m128 k = _mm_add_ps(_mm_mul_ps(_mm_set1_ps(c.ambient), _mm_loadu_ps(open)),
                              _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(c.diffuse), _mm_loadu_ps(lit)),
                                         _mm_max_ps(n_dot_l, _mm_setzero_ps())));
  alignas(16) int32_t k16[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(k16),
                  _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(k, _mm_set1_ps(65535.0f)), _mm_set1_ps(0.5f))));
  if constexpr (kDepth) {
    const __m128 in_range =
        _mm_and_ps(_mm_cmpge_ps(t, _mm_set1_ps(c.min_depth)), _mm_cmple_ps(t, _mm_set1_ps(c.max_depth)));
    alignas(16) float z[4];
    _mm_store_ps(z, _mm_and_ps(in_range, t));
    for (int i = 0; i < 4; ++i) *depth[i] = z[i];
  }
  for (int i = 0; i < 4; ++i) {
    const detail::Texture& tex = c.textures[s[i]->material];
    detail::sample_shaded(tex, std::min(level[i], tex.levels - 1), u[i], v[i], static_cast<uint32_t>(k16[i]),
                          bgr[i]);
  }
}
#endif

class EmbreeRenderer final : public Renderer {
 public:
  EmbreeRenderer() = default;
  EmbreeRenderer(const EmbreeRenderer&) = delete;
  EmbreeRenderer& operator=(const EmbreeRenderer&) = delete;
  ~EmbreeRenderer() override {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
  }

  core::Status build(const SceneSpec& spec);

  void render(const Eigen::Isometry3d& T_scene_cam, const hal::PinholeIntrinsics& intrinsics,
              const RenderOptions& options, cv::Mat* bgr, cv::Mat* depth_m) const override;
  double cast_ray(const Eigen::Vector3d& origin_scene, const Eigen::Vector3d& dir_scene) const override;
  size_t triangle_count() const override { return tris_.size(); }
  int native_packet_width() const override { return native_width_; }

 private:
  template <int TW, int TH, class RayHitN, bool kDepth>
  void render_packets(const ShadeContext& c, const Eigen::Matrix3f& R, const hal::PinholeIntrinsics& K,
                      cv::Mat* bgr, cv::Mat* depth) const;
  template <bool kDepth>
  void render_single(const ShadeContext& c, const Eigen::Matrix3f& R, const hal::PinholeIntrinsics& K,
                     cv::Mat* bgr, cv::Mat* depth) const;

  // Adds four rotated-grid samples to the centre samples in *bgr and averages them (area_sampling).
  void integrate_colour(int width, const ShadeContext& c, const Eigen::Matrix3f& R,
                        const hal::PinholeIntrinsics& K, cv::Mat* bgr) const;

  template <bool kDepth>
  void dispatch(int width, const ShadeContext& c, const Eigen::Matrix3f& R, const hal::PinholeIntrinsics& K,
                cv::Mat* bgr, cv::Mat* depth) const {
    switch (width) {
      case 16:
        render_packets<4, 4, RTCRayHit16, kDepth>(c, R, K, bgr, depth);
        break;
      case 8:
        render_packets<4, 2, RTCRayHit8, kDepth>(c, R, K, bgr, depth);
        break;
      case 4:
        render_packets<2, 2, RTCRayHit4, kDepth>(c, R, K, bgr, depth);
        break;
      default:
        render_single<kDepth>(c, R, K, bgr, depth);
        break;
    }
  }

  static void on_error(void* user, RTCError code, const char* message) {
    auto* self = static_cast<EmbreeRenderer*>(user);
    if (self->error_.empty())
      self->error_ = std::string("Embree error ") + std::to_string(code) + ": " + message;
  }
  core::Status embree_status(const char* what) const {
    if (error_.empty()) return core::Status::Ok();
    return core::Internal(std::string(what) + ": " + error_);
  }

  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  std::string error_;
  int native_width_ = 1;
  std::vector<TriShade> tris_;
  std::vector<CylinderAxis> cylinders_;  // indexed by object id (zero for non-pipes)
  detail::MaterialTextures textures_;
};

core::Status EmbreeRenderer::build(const SceneSpec& spec) {
  const detail::SceneMesh mesh = detail::build_scene_mesh(spec);

  device_ = rtcNewDevice(nullptr);
  if (!device_) {
    return core::Unavailable("scene '" + spec.name + "': cannot create the Embree device (error " +
                             std::to_string(rtcGetDeviceError(nullptr)) + ")");
  }
  rtcSetDeviceErrorFunction(device_, &EmbreeRenderer::on_error, this);
  if (rtcGetDeviceProperty(device_, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED)) {
    native_width_ = 16;
  } else if (rtcGetDeviceProperty(device_, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED)) {
    native_width_ = 8;
  } else if (rtcGetDeviceProperty(device_, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED)) {
    native_width_ = 4;
  }

  scene_ = rtcNewScene(device_);
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices_scene.size()));
  auto* indices = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), mesh.triangles.size()));
  if (vertices && indices) {
    for (size_t i = 0; i < mesh.vertices_scene.size(); ++i) {
      for (int k = 0; k < 3; ++k) vertices[3 * i + k] = mesh.vertices_scene[i][k];
    }
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) indices[3 * i + k] = mesh.triangles[i][k];
    }
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometryByID(scene_, geom, 0);  // the single geometry: side arrays are indexed by primID
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene_);
  HWR_RETURN_IF_ERROR(embree_status(("scene '" + spec.name + "': building the Embree scene").c_str()));

  // Shading side arrays.
  std::vector<std::pair<float, float>> object_offsets(mesh.objects.size());
  cylinders_.assign(mesh.objects.size(), CylinderAxis{});
  std::array<bool, detail::kMaterialCount> used{};
  for (size_t o = 0; o < mesh.objects.size(); ++o) {
    const uint64_t h = splitmix64(spec.texture_seed ^ splitmix64(o + 1));
    object_offsets[o] = {static_cast<float>(h & 1023u), static_cast<float>((h >> 10) & 1023u)};
    const detail::SceneObject& object = mesh.objects[o];
    used[static_cast<size_t>(object.material)] = true;
    if (object.kind == detail::ObjectKind::kPipe) {
      for (int k = 0; k < 3; ++k) {
        cylinders_[o].p[k] = static_cast<float>(object.axis_point_scene[k]);
        cylinders_[o].a[k] = static_cast<float>(object.axis_dir_scene[k]);
      }
    }
  }
  detail::generate_textures(spec.texture_seed, used, &textures_);

  tris_.resize(mesh.triangles.size());
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& tri = mesh.triangles[i];
    const Eigen::Vector3d a = mesh.vertices_scene[tri[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices_scene[tri[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices_scene[tri[2]].cast<double>();
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    const uint32_t o = mesh.tri_object[i];
    const detail::SceneObject& object = mesh.objects[o];
    const float texels_per_m = textures_[static_cast<size_t>(object.material)].texels_per_m;
    TriShade& s = tris_[i];
    for (int k = 0; k < 3; ++k) s.n[k] = static_cast<float>(n[k]);
    int axis = 0;
    n.cwiseAbs().maxCoeff(&axis);
    const int a0 = axis == 0 ? 1 : 0, a1 = axis == 2 ? 1 : 2;  // the two other axes
    for (int k = 0; k < 3; ++k) {
      s.pu[k] = k == a0 ? texels_per_m : 0.0f;
      s.pv[k] = k == a1 ? texels_per_m : 0.0f;
    }
    s.pu[3] = object_offsets[o].first;
    s.pv[3] = object_offsets[o].second;
    s.texels_per_m2 = texels_per_m * texels_per_m;
    s.material = static_cast<uint8_t>(object.material);
    s.cylinder = object.kind == detail::ObjectKind::kPipe && std::abs(n.dot(object.axis_dir_scene)) < 0.5;
    s.object = o;
  }
  return core::Status::Ok();
}

template <int TW, int TH, class RayHitN, bool kDepth>
void EmbreeRenderer::render_packets(const ShadeContext& c, const Eigen::Matrix3f& R,
                                    const hal::PinholeIntrinsics& K, cv::Mat* bgr, cv::Mat* depth) const {
  constexpr int N = TW * TH;
  const int W = K.width, H = K.height;
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  const float ifx = static_cast<float>(1.0 / K.fx), ify = static_cast<float>(1.0 / K.fy);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(64) RayHitN rh;
  alignas(64) int valid[N];
  alignas(16) float d2[N];
  // Embree writes only tfar and the hit: the other ray fields are set once.
  for (int i = 0; i < N; ++i) {
    rh.ray.org_x[i] = c.org[0];
    rh.ray.org_y[i] = c.org[1];
    rh.ray.org_z[i] = c.org[2];
    rh.ray.tnear[i] = 0.0f;
    rh.ray.time[i] = 0.0f;
    rh.ray.mask[i] = ~0u;
    rh.ray.id[i] = static_cast<unsigned>(i);
    rh.ray.flags[i] = 0;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  for (int ty = 0; ty < H; ty += TH) {
    for (int tx = 0; tx < W; tx += TW) {
      for (int i = 0; i < N; ++i) {
        const int px = tx + i % TW, py = ty + i / TW;
        valid[i] = (px < W && py < H) ? -1 : 0;
        const float xn = (static_cast<float>(px) - cx) * ifx;
        const float yn = (static_cast<float>(py) - cy) * ify;
        rh.ray.dir_x[i] = R(0, 0) * xn + R(0, 1) * yn + R(0, 2);
        rh.ray.dir_y[i] = R(1, 0) * xn + R(1, 1) * yn + R(1, 2);
        rh.ray.dir_z[i] = R(2, 0) * xn + R(2, 1) * yn + R(2, 2);
        rh.ray.tfar[i] = std::numeric_limits<float>::infinity();
        rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        d2[i] = xn * xn + yn * yn + 1.0f;
      }
      intersect(valid, scene_, &ctx, &rh);
      alignas(16) float lit[N], open[N];
      if (c.light_rays) {
        bool hit[N];
        for (int i = 0; i < N; ++i) hit[i] = valid[i] && rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
        light_visibility<N, decltype(RayHitN::ray)>(c, scene_, hit, rh.ray.tfar, rh.hit.primID, rh.ray.dir_x,
                                                    rh.ray.dir_y, rh.ray.dir_z, lit, open);
      } else {
        std::fill(lit, lit + N, 1.0f);
        std::fill(open, open + N, 1.0f);
      }
      uint8_t* bgr_rows[TH];
      float* depth_rows[TH];
      for (int r = 0; r < TH; ++r) {
        const int py = std::min(ty + r, H - 1);
        bgr_rows[r] = bgr->ptr<uint8_t>(py);
        depth_rows[r] = kDepth ? depth->ptr<float>(py) : nullptr;
      }
      static_assert(N % 4 == 0, "lanes are shaded in groups of four");
      for (int g = 0; g < N; g += 4) {
        uint8_t* out[4];
        float* z[4];
        const TriShade* s[4];
        bool flat_hits = true;  // all four lanes valid, hitting flat-shaded triangles
        for (int k = 0; k < 4; ++k) {
          const int i = g + k;
          const int px = tx + i % TW;
          out[k] = valid[i] ? bgr_rows[i / TW] + 3 * px : nullptr;
          z[k] = kDepth && valid[i] ? depth_rows[i / TW] + px : nullptr;
          const bool hit = valid[i] && rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
          s[k] = hit ? &c.tris[rh.hit.primID[i]] : nullptr;
          flat_hits = flat_hits && hit && !s[k]->cylinder;
        }
#if defined(__SSE2__)
        if (flat_hits) {
          shade4<kDepth>(c, s, &rh.ray.tfar[g], &rh.ray.dir_x[g], &rh.ray.dir_y[g], &rh.ray.dir_z[g], &d2[g],
                         &lit[g], &open[g], out, z);
          continue;
        }
#endif
        for (int k = 0; k < 4; ++k) {
          const int i = g + k;
          if (!valid[i]) continue;
          if (s[k]) {
            shade_hit<kDepth>(c, rh.ray.tfar[i], rh.hit.primID[i], rh.ray.dir_x[i], rh.ray.dir_y[i],
                              rh.ray.dir_z[i], d2[i], lit[i], open[i], out[k], z[k]);
          } else {
            out[k][0] = c.background[0], out[k][1] = c.background[1], out[k][2] = c.background[2];
            if constexpr (kDepth) *z[k] = 0.0f;
          }
        }
      }
    }
  }
}

template <bool kDepth>
void EmbreeRenderer::render_single(const ShadeContext& c, const Eigen::Matrix3f& R,
                                   const hal::PinholeIntrinsics& K, cv::Mat* bgr, cv::Mat* depth) const {
  const float cx = static_cast<float>(K.cx), cy = static_cast<float>(K.cy);
  const float ifx = static_cast<float>(1.0 / K.fx), ify = static_cast<float>(1.0 / K.fy);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  RTCRayHit rh;
  for (int py = 0; py < K.height; ++py) {
    uint8_t* out = bgr->ptr<uint8_t>(py);
    float* z = kDepth ? depth->ptr<float>(py) : nullptr;
    for (int px = 0; px < K.width; ++px, out += 3) {
      const float xn = (static_cast<float>(px) - cx) * ifx;
      const float yn = (static_cast<float>(py) - cy) * ify;
      rh.ray.org_x = c.org[0];
      rh.ray.org_y = c.org[1];
      rh.ray.org_z = c.org[2];
      rh.ray.tnear = 0.0f;
      rh.ray.dir_x = R(0, 0) * xn + R(0, 1) * yn + R(0, 2);
      rh.ray.dir_y = R(1, 0) * xn + R(1, 1) * yn + R(1, 2);
      rh.ray.dir_z = R(2, 0) * xn + R(2, 1) * yn + R(2, 2);
      rh.ray.time = 0.0f;
      rh.ray.tfar = std::numeric_limits<float>::infinity();
      rh.ray.mask = ~0u;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene_, &ctx, &rh);
      float* zp = kDepth ? z + px : nullptr;
      if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        float lit = 1.0f, open = 1.0f;
        if (c.light_rays) {
          const bool hit = true;
          light_visibility<1, Ray1>(c, scene_, &hit, &rh.ray.tfar, &rh.hit.primID, &rh.ray.dir_x,
                                    &rh.ray.dir_y, &rh.ray.dir_z, &lit, &open);
        }
        shade_hit<kDepth>(c, rh.ray.tfar, rh.hit.primID, rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z,
                          xn * xn + yn * yn + 1.0f, lit, open, out, zp);
      } else {
        out[0] = c.background[0], out[1] = c.background[1], out[2] = c.background[2];
        if constexpr (kDepth) *zp = 0.0f;
      }
    }
  }
}

void EmbreeRenderer::render(const Eigen::Isometry3d& T_scene_cam, const hal::PinholeIntrinsics& intrinsics,
                            const RenderOptions& options, cv::Mat* bgr, cv::Mat* depth_m) const {
  assert(intrinsics.valid() && "render() needs valid intrinsics");
  if (!intrinsics.valid()) return;
  const int W = intrinsics.width, H = intrinsics.height;
  // The colour pass always runs; without a caller buffer it goes to a per-thread scratch image.
  thread_local cv::Mat scratch_bgr;
  cv::Mat* colour = bgr ? bgr : &scratch_bgr;
  colour->create(H, W, CV_8UC3);  // no-op when size and type already match
  if (depth_m) depth_m->create(H, W, CV_32FC1);

  ShadeContext c;
  c.tris = tris_.data();
  c.cylinders = cylinders_.data();
  c.textures = textures_.data();
  const Eigen::Vector3d t = T_scene_cam.translation();
  for (int k = 0; k < 3; ++k) c.org[k] = static_cast<float>(t[k]);
  const Eigen::Vector3d light = -options.light_dir_scene.normalized();
  for (int k = 0; k < 3; ++k) c.light[k] = static_cast<float>(light[k]);
  c.ambient = static_cast<float>(std::clamp(options.ambient, 0.0, 1.0));
  c.diffuse = 1.0f - c.ambient;
  c.shadows = options.shadows && options.shadow_range_m > 0.0;
  c.shadow_range = static_cast<float>(options.shadow_range_m);
  c.ao_rays = options.ambient_occlusion_range_m > 0.0 ? std::clamp(options.ambient_occlusion_rays, 0, 64) : 0;
  c.ao_range = static_cast<float>(options.ambient_occlusion_range_m);
  c.ao_dirs = ao_directions(c.ao_rays);
  c.light_rays = c.shadows || c.ao_rays > 0;
  c.inv_f2 = static_cast<float>(1.0 / (intrinsics.fx * intrinsics.fy));
  c.min_depth = static_cast<float>(options.min_range_m);
  c.max_depth = static_cast<float>(options.max_range_m);
  for (int k = 0; k < 3; ++k) c.background[k] = cv::saturate_cast<uint8_t>(options.background_bgr[k]);
  const Eigen::Matrix3f R = T_scene_cam.linear().cast<float>();

  [[maybe_unused]] ScopedFlushDenormals ftz;
  const int width = options.packet_width == 0 ? native_width_ : options.packet_width;
  if (depth_m) {
    dispatch<true>(width, c, R, intrinsics, colour, depth_m);
  } else {
    dispatch<false>(width, c, R, intrinsics, colour, nullptr);
  }
  if (options.area_sampling && bgr) integrate_colour(width, c, R, intrinsics, bgr);
}

void EmbreeRenderer::integrate_colour(int width, const ShadeContext& c, const Eigen::Matrix3f& R,
                                      const hal::PinholeIntrinsics& K, cv::Mat* bgr) const {
  // Rotated grid (RGSS): every sample on its own row and column, so edges near horizontal or
  // vertical get five levels of coverage. Each sample still reads the texture at the whole pixel's
  // mip level, so texture detail is filtered by the mip chain and again by the average (a little
  // softer than a true box filter over the pixel); edges and sub-pixel geometry are what it is for.
  static constexpr float kOffsetPx[4][2] = {
      {0.125f, -0.375f}, {0.375f, 0.125f}, {-0.125f, 0.375f}, {-0.375f, -0.125f}};
  thread_local cv::Mat sample, sum;
  bgr->convertTo(sum, CV_16UC3);
  for (const auto& offset : kOffsetPx) {
    // Pixel (u, v)'s ray is K^-1 [u v 1]: moving the principal point by -offset samples u + offset.
    hal::PinholeIntrinsics K_sample = K;
    K_sample.cx -= offset[0];
    K_sample.cy -= offset[1];
    sample.create(K.height, K.width, CV_8UC3);
    dispatch<false>(width, c, R, K_sample, &sample, nullptr);
    cv::add(sum, sample, sum, cv::noArray(), CV_16UC3);
  }
  sum.convertTo(*bgr, CV_8UC3, 1.0 / 5.0);  // rounded to nearest
}

double EmbreeRenderer::cast_ray(const Eigen::Vector3d& origin_scene, const Eigen::Vector3d& dir_scene) const {
  const double inf = std::numeric_limits<double>::infinity();
  const double norm = dir_scene.norm();
  if (!(norm > 0.0) || !std::isfinite(norm) || !origin_scene.allFinite()) return inf;
  const Eigen::Vector3f o = origin_scene.cast<float>();
  const Eigen::Vector3f d = (dir_scene / norm).cast<float>();
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = o.x(), rh.ray.org_y = o.y(), rh.ray.org_z = o.z();
  rh.ray.dir_x = d.x(), rh.ray.dir_y = d.y(), rh.ray.dir_z = d.z();
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.time = 0.0f;
  rh.ray.mask = ~0u;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  {
    [[maybe_unused]] ScopedFlushDenormals ftz;
    rtcIntersect1(scene_, &ctx, &rh);
  }
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return inf;
  return static_cast<double>(rh.ray.tfar) * d.cast<double>().norm();
}

}  // namespace

core::Expected<std::unique_ptr<Renderer>> Renderer::create(const SceneSpec& scene) {
  HWR_RETURN_IF_ERROR(detail::validate_scene(scene));
  auto renderer = std::make_unique<EmbreeRenderer>();
  HWR_RETURN_IF_ERROR(renderer->build(scene));
  return std::unique_ptr<Renderer>(std::move(renderer));
}

}  // namespace hwr::sim
