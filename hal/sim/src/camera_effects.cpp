// Sensor effects on noise-free renders. Randomness is counter-based: the value used at pixel i
// is a hash of (seed, i), so results depend only on the seed and never on call order or threads.

#include "hwr/sim/camera_effects.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "hwr/sim/random.hpp"

namespace hwr::sim {
namespace {

// Independent streams of one seed.
constexpr uint64_t kStreamDepthNoise = 0x6465707468ull;  // "depth"
constexpr uint64_t kStreamHoles = 0x686f6c6573ull;       // "holes"
constexpr uint64_t kStreamPixel = 0x706978656cull;       // "pixel"

inline uint64_t counter_hash(uint64_t key, uint64_t counter) {
  return splitmix64(key + 0x9E3779B97F4A7C15ull * counter);
}

// Inverse standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01, -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  const double lo = 0.02425;
  if (p < lo) {
    const double q = std::sqrt(-2.0 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  if (p > 1.0 - lo) return -inverse_normal_cdf(1.0 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

// 65536 equiprobable quantiles of N(0, 1) (tails to 4.2 sigma), rescaled to unit variance: a
// 16-bit slice of a hash indexes one normal sample, so one 64-bit hash gives four. A table lookup
// instead of Box-Muller's log, sqrt and sin per pair keeps a VGA frame's noise at about 1 ms.
constexpr int kNormalTableBits = 16;
using NormalTable = std::array<float, 1 << kNormalTableBits>;

const NormalTable& normal_table() {
  static const NormalTable table = [] {
    NormalTable t{};
    double sum2 = 0.0;
    for (size_t i = 0; i < t.size(); ++i) {
      const double v = inverse_normal_cdf((static_cast<double>(i) + 0.5) / static_cast<double>(t.size()));
      t[i] = static_cast<float>(v);
      sum2 += v * v;
    }
    const double scale = 1.0 / std::sqrt(sum2 / static_cast<double>(t.size()));
    for (float& v : t) v = static_cast<float>(v * scale);
    return t;
  }();
  return table;
}

// Depth discontinuities: marks pixels whose depth differs from a valid 4-neighbour by more than
// ratio * own depth.
void mark_edges(const cv::Mat& depth, double ratio, std::vector<uint8_t>* mask) {
  const int W = depth.cols, H = depth.rows;
  std::fill(mask->begin(), mask->begin() + static_cast<size_t>(W) * H, uint8_t{0});
  const float r = static_cast<float>(ratio);
  for (int y = 0; y < H; ++y) {
    const float* row = depth.ptr<float>(y);
    const float* up = y > 0 ? depth.ptr<float>(y - 1) : nullptr;
    const float* down = y + 1 < H ? depth.ptr<float>(y + 1) : nullptr;
    uint8_t* m = mask->data() + static_cast<size_t>(y) * W;
    for (int x = 0; x < W; ++x) {
      const float z = row[x];
      if (!(z > 0.0f)) continue;
      const float limit = r * z;
      auto far = [&](float n) { return n > 0.0f && std::abs(n - z) > limit; };
      m[x] = (x > 0 && far(row[x - 1])) || (x + 1 < W && far(row[x + 1])) || (up && far(up[x])) ||
             (down && far(down[x]));
    }
  }
}

// Hole blobs: n discs of radius r with centres uniform over the image grown by r on every side.
// A pixel is then covered by one disc with probability A / A_ext (A: pixels in a disc, A_ext: the
// grown area), so the expected hole fraction is 1 - (1 - A / A_ext)^n; n is solved from it.
void punch_holes(double fraction, int radius, uint64_t key, cv::Mat* depth) {
  const int W = depth->cols, H = depth->rows;
  if (fraction >= 1.0) {
    depth->setTo(0.0f);
    return;
  }
  const int r = std::max(radius, 0);
  int disc = 0;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) disc += (dx * dx + dy * dy <= r * r) ? 1 : 0;
  }
  const double ext_w = W + 2.0 * r, ext_h = H + 2.0 * r;
  const double p = std::min(static_cast<double>(disc) / (ext_w * ext_h), 0.5);
  const long n = std::lround(std::log1p(-fraction) / std::log1p(-p));
  for (long k = 0; k < n; ++k) {
    const uint64_t h = counter_hash(key, static_cast<uint64_t>(k));
    const int cx = static_cast<int>((h & 0xffffffffull) % static_cast<uint64_t>(ext_w)) - r;
    const int cy = static_cast<int>((h >> 32) % static_cast<uint64_t>(ext_h)) - r;
    for (int y = std::max(cy - r, 0); y <= std::min(cy + r, H - 1); ++y) {
      float* row = depth->ptr<float>(y);
      const int dy = y - cy;
      for (int x = std::max(cx - r, 0); x <= std::min(cx + r, W - 1); ++x) {
        const int dx = x - cx;
        if (dx * dx + dy * dy <= r * r) row[x] = 0.0f;
      }
    }
  }
}

}  // namespace

void apply_depth_noise(const DepthNoiseSpec& spec, uint64_t seed, cv::Mat* depth_m) {
  if (!spec.enabled || depth_m == nullptr || depth_m->empty()) return;
  CV_Assert(depth_m->type() == CV_32FC1);
  const int W = depth_m->cols, H = depth_m->rows;
  const uint64_t key = splitmix64(seed);

  // Discontinuities are found on the noise-free depth, before noise could trigger them.
  thread_local std::vector<uint8_t> edge_mask;
  const bool edges = spec.edge_dropout_ratio > 0.0;
  if (edges) {
    if (edge_mask.size() < static_cast<size_t>(W) * H) edge_mask.resize(static_cast<size_t>(W) * H);
    mark_edges(*depth_m, spec.edge_dropout_ratio, &edge_mask);
  }

  // Axial noise sigma(z) = sigma_c + sigma_q z^2; pixel i uses 16-bit slice (i mod 4) of hash(i / 4).
  const NormalTable& normal = normal_table();
  const float sc = static_cast<float>(spec.sigma_const_m), sq = static_cast<float>(spec.sigma_quad_per_m);
  const uint64_t noise_key = key ^ kStreamDepthNoise;
  for (int y = 0; y < H; ++y) {
    float* row = depth_m->ptr<float>(y);
    const uint64_t i0 = static_cast<uint64_t>(y) * W;
    for (int x = 0; x < W; ++x) {
      const float z = row[x];
      if (!(z > 0.0f) || !std::isfinite(z)) continue;
      const uint64_t i = i0 + x;
      const uint64_t h = counter_hash(noise_key, i >> 2);
      const float n = normal[(h >> (kNormalTableBits * (i & 3))) & 0xffffu];
      const float noisy = z + (sc + sq * z * z) * n;
      row[x] = noisy > 0.0f ? noisy : 0.0f;
    }
  }

  if (spec.hole_fraction > 0.0)
    punch_holes(spec.hole_fraction, spec.hole_radius_px, key ^ kStreamHoles, depth_m);

  if (edges) {
    for (int y = 0; y < H; ++y) {
      float* row = depth_m->ptr<float>(y);
      const uint8_t* m = edge_mask.data() + static_cast<size_t>(y) * W;
      for (int x = 0; x < W; ++x) {
        if (m[x]) row[x] = 0.0f;
      }
    }
  }
}

void apply_exposure(const ExposureSpec& spec, uint64_t seed, cv::Mat* bgr) {
  if (bgr == nullptr || bgr->empty()) return;
  CV_Assert(bgr->type() == CV_8UC3);
  if (spec.gain == 1.0 && spec.pixel_noise_sigma <= 0.0) return;
  const NormalTable& table = normal_table();
  constexpr uint64_t kMask = (1u << kNormalTableBits) - 1;
  const float gain = static_cast<float>(spec.gain);
  const float sigma = static_cast<float>(std::max(spec.pixel_noise_sigma, 0.0));
  const uint64_t key = splitmix64(seed) ^ kStreamPixel;
  const int W = bgr->cols, H = bgr->rows;
  for (int y = 0; y < H; ++y) {
    uint8_t* p = bgr->ptr<uint8_t>(y);
    const uint64_t i0 = static_cast<uint64_t>(y) * W;
    for (int x = 0; x < W; ++x, p += 3) {
      const uint64_t h = counter_hash(key, i0 + x);  // three 16-bit slices, one per channel
      for (int c = 0; c < 3; ++c) {
        const float v = gain * p[c] + sigma * table[(h >> (kNormalTableBits * c)) & kMask];
        p[c] = cv::saturate_cast<uint8_t>(v);
      }
    }
  }
}

}  // namespace hwr::sim
