#include "plate_edge_rays.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace hwr::recon::plate_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Weighted median of (value, weight) pairs; the vector is reordered.
double weighted_median(std::vector<std::pair<double, double>>* v) {
  std::sort(v->begin(), v->end());
  double total = 0;
  for (const auto& [x, w] : *v) total += w;
  double acc = 0;
  for (const auto& [x, w] : *v) {
    acc += w;
    if (acc >= 0.5 * total) return x;
  }
  return v->empty() ? 0.0 : v->back().first;
}

// The range along the unit ray (c, u) to its first hit on the model: face h = 0 for s <= E, side
// s = E for -D <= h <= 0, support h = -D for s >= E (coordinates (s, t, h)); kInf when it misses.
double model_range(const Eigen::Vector3d& c, const Eigen::Vector3d& u, double E, double D) {
  double best = kInf;
  if (u.z() < 0) {
    const double lf = -c.z() / u.z();
    if (lf > 0 && c.x() + lf * u.x() <= E) best = std::min(best, lf);
    const double ld = (-D - c.z()) / u.z();
    if (ld > 0 && c.x() + ld * u.x() >= E) best = std::min(best, ld);
  }
  if (std::fabs(u.x()) > 1e-12) {
    const double ls = (E - c.x()) / u.x();
    const double h = c.z() + ls * u.z();
    if (ls > 0 && h <= 0 && h >= -D) best = std::min(best, ls);
  }
  return best;
}

}  // namespace

bool RangeNoise::fit(const std::vector<RaySample>& face_samples, double bin_m, double min_weight) {
  bin_m_ = bin_m;
  std::vector<std::vector<std::pair<double, double>>> bins;
  for (const RaySample& r : face_samples) {
    const Eigen::Vector3d d = r.p - r.viewpoint;
    const double rho = d.norm();
    if (!(rho > 0) || d.z() >= 0) continue;
    const Eigen::Vector3d u = d / rho;
    const double rho_face = -r.viewpoint.z() / u.z();
    const size_t b = static_cast<size_t>(rho / bin_m);
    if (b >= bins.size()) bins.resize(b + 1);
    bins[b].emplace_back(rho - rho_face, r.weight);
  }
  sigma_.assign(bins.size(), -1.0);
  bool any = false;
  for (size_t b = 0; b < bins.size(); ++b) {
    double weight = 0;
    for (const auto& [x, w] : bins[b]) weight += w;
    if (weight < min_weight) continue;
    const double med = weighted_median(&bins[b]);
    for (auto& [x, w] : bins[b]) x = std::fabs(x - med);
    sigma_[b] = std::max(1.4826 * weighted_median(&bins[b]), 1e-4);
    any = true;
  }
  if (!any) return false;
  // Empty bins take the nearest filled one.
  for (size_t b = 0; b < sigma_.size(); ++b) {
    if (sigma_[b] > 0) continue;
    for (size_t d = 1; d < sigma_.size(); ++d) {
      if (b >= d && sigma_[b - d] > 0) {
        sigma_[b] = sigma_[b - d];
        break;
      }
      if (b + d < sigma_.size() && sigma_[b + d] > 0) {
        sigma_[b] = sigma_[b + d];
        break;
      }
    }
  }
  return true;
}

double RangeNoise::sigma_m(double range_m) const {
  if (sigma_.empty()) return 1e-3;
  const double x = std::max(range_m / bin_m_, 0.0);
  const size_t b = std::min(static_cast<size_t>(x), sigma_.size() - 1);
  return sigma_[b];
}

EdgeOnSupport refine_edge_on_support(const std::vector<RaySample>& samples, const RangeNoise& noise,
                                     double e0, double depth_m, double search_m, double step_m) {
  EdgeOnSupport out;
  struct Ray {
    Eigen::Vector3d c, u;
    double rho, inv_sigma, w;
  };
  std::vector<Ray> rays;
  rays.reserve(samples.size());
  for (const RaySample& r : samples) {
    const Eigen::Vector3d d = r.p - r.viewpoint;
    const double rho = d.norm();
    if (!(rho > 0)) continue;
    rays.push_back({r.viewpoint, d / rho, rho, 1.0 / noise.sigma_m(rho), r.weight});
    out.weight += r.weight;
  }
  if (rays.empty()) return out;
  auto cost = [&](double E) {
    double c = 0;
    for (const Ray& r : rays) {
      const double z = (r.rho - model_range(r.c, r.u, E, depth_m)) * r.inv_sigma;
      c += r.w * std::min(z * z, 9.0);
    }
    return c;
  };
  const int n = static_cast<int>(std::ceil(search_m / step_m));
  double best_e = e0, best_c = kInf;
  const double c0 = cost(e0);
  for (int i = -n; i <= n; ++i) {
    const double E = e0 + i * step_m;
    const double c = cost(E);
    if (c < best_c) best_c = c, best_e = E;
  }
  // The grid minimum at the search's end means the model found no edge in it.
  if (std::fabs(best_e - e0) >= n * step_m - 1e-12) return out;
  out.ok = true;
  out.edge_s = best_e;
  out.cost_drop = c0 > 0 ? 1.0 - best_c / c0 : 0.0;
  return out;
}

}  // namespace hwr::recon::plate_detail
