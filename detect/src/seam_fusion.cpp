#include "hwr/detect/seam_fusion.hpp"

#include <algorithm>
#include <cmath>

namespace hwr::detect {

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

SeamFusion::SeamFusion(const SeamFusionConfig& config) : config_(config) {
  tracks_.reserve(static_cast<size_t>(std::max(config.max_tracks, 0)));
}

bool SeamFusion::add(const Detection& d) {
  const Eigen::Vector3d a = d.seam_world[0], b = d.seam_world[1];
  const double length = (b - a).norm();
  if (!(length > 1e-6)) return false;
  ++added_;
  const Eigen::Vector3d u = (b - a) / length;
  const SeamMatchConfig& m = config_.match;
  for (Track& t : tracks_) {
    if (t.kind != d.kind) continue;
    // The track's current line: mean midpoint, mean direction.
    Eigen::Vector3d axis = t.dir_sum.normalized();
    const Eigen::Vector3d centre = t.mid_sum / t.n;
    if (std::acos(std::min(1.0, std::fabs(axis.dot(u)))) > m.max_angle_rad) continue;
    if (distance_to_line_m(a, centre, axis) > m.max_lateral_m ||
        distance_to_line_m(b, centre, axis) > m.max_lateral_m)
      continue;
    // Along the track's first axis (fixed, so that its extent and ends stay comparable).
    double ta = t.axis.dot(a - t.origin), tb = t.axis.dot(b - t.origin);
    bool a_observed = d.end_observed[0], b_observed = d.end_observed[1];
    if (ta > tb) {
      std::swap(ta, tb);
      std::swap(a_observed, b_observed);
    }
    if (tb < t.t_lo - m.max_lateral_m || ta > t.t_hi + m.max_lateral_m) continue;  // apart along it
    t.mid_sum += 0.5 * (a + b);
    t.dir_sum += t.dir_sum.dot(u) >= 0 ? u : Eigen::Vector3d(-u);
    ++t.n;
    t.confident += d.support_only ? 0 : 1;
    t.grew = added_;
    t.t_lo = std::min(t.t_lo, ta);
    t.t_hi = std::max(t.t_hi, tb);
    // The first max_ends_per_track seen ends make each median: a run of any length keeps bounded memory.
    const size_t cap = static_cast<size_t>(std::max(config_.max_ends_per_track, 1));
    if (a_observed && t.ends_lo.size() < cap) t.ends_lo.push_back(ta);
    if (b_observed && t.ends_hi.size() < cap) t.ends_hi.push_back(tb);
    return true;
  }
  Track* slot = nullptr;
  if (static_cast<int>(tracks_.size()) >= config_.max_tracks) {
    // Full: the unconfirmed track that grew longest ago makes room.
    for (Track& t : tracks_)
      if (t.confident == 0 && (slot == nullptr || t.grew < slot->grew)) slot = &t;
    if (slot == nullptr) return false;
  }
  Track t;
  t.kind = d.kind;
  t.origin = 0.5 * (a + b);
  t.axis = u;
  t.mid_sum = t.origin;
  t.dir_sum = u;
  t.n = 1;
  t.confident = d.support_only ? 0 : 1;
  t.grew = added_;
  t.t_lo = -0.5 * length;
  t.t_hi = 0.5 * length;
  if (d.end_observed[0]) t.ends_lo.push_back(t.t_lo);
  if (d.end_observed[1]) t.ends_hi.push_back(t.t_hi);
  if (slot != nullptr) {
    *slot = std::move(t);
  } else {
    tracks_.push_back(std::move(t));
  }
  return true;
}

std::vector<FusedSeam> SeamFusion::fused() const {
  std::vector<FusedSeam> out;
  for (const Track& t : tracks_) {
    if (t.n < config_.min_detections || t.confident == 0) continue;
    const Eigen::Vector3d axis = t.dir_sum.normalized();
    const Eigen::Vector3d centre = t.mid_sum / t.n;
    // Ends measured along the first axis, placed on the mean line.
    const double lo = t.ends_lo.empty() ? t.t_lo : median(t.ends_lo);
    const double hi = t.ends_hi.empty() ? t.t_hi : median(t.ends_hi);
    auto on_line = [&](double s) {
      const Eigen::Vector3d p = t.origin + s * t.axis;
      return Eigen::Vector3d(centre + (p - centre).dot(axis) * axis);
    };
    FusedSeam f;
    f.seam.kind = t.kind;
    f.seam.a = on_line(lo);
    f.seam.b = on_line(hi);
    f.seam.end_known = {!t.ends_lo.empty(), !t.ends_hi.empty()};
    f.detections = t.n;
    out.push_back(f);
  }
  return out;
}

}  // namespace hwr::detect
