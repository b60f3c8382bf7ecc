#include "hwr/estimation/projection_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>

#include "hwr/estimation/hamming_kernel.hpp"

namespace hwr::estimation {

// The candidates (int) are read by hamming_distances_at as their unsigned variant ([basic.lval]).
static_assert(std::is_same_v<std::make_unsigned_t<int>, uint32_t>, "int's unsigned variant is uint32_t");

ProjectionMatcher::ProjectionMatcher(int max_points, int max_features)
    : max_points_(std::max(max_points, 0)),
      max_features_(std::max(max_features, 0)),
      candidates_(static_cast<size_t>(std::max(max_features, 1))),
      distances_(static_cast<size_t>(std::max(max_features, 1))),
      owners_(max_features) {}

int ProjectionMatcher::match(const MapPointRef* points, int n, const Eigen::Isometry3d& T_cam_world,
                             const hal::PinholeIntrinsics& K, const FrameFeatures& frame,
                             const ProjectionMatchConfig& cfg, FeatureMatch* out, int max_out) {
  const int n_points = std::min(n, max_points_);
  const int n_features = std::min(frame.size(), max_features_);
  owners_.reset(n_features);
  const Eigen::Matrix3d R = T_cam_world.linear();
  const Eigen::Vector3d t = T_cam_world.translation();
  const float w = static_cast<float>(K.width), h = static_cast<float>(K.height);
  const int last_octave = static_cast<int>(frame.scale_per_octave.size()) - 1;

  for (int i = 0; i < n_points; ++i) {
    const MapPointRef& mp = points[i];
    if (mp.descriptor == nullptr) continue;
    const Eigen::Vector3d p_cam = R * mp.p_world + t;
    if (!(p_cam.z() > cfg.min_depth_m)) continue;
    // Pinhole projection (the inverse of eq. 3).
    const float u = static_cast<float>(K.fx * p_cam.x() / p_cam.z() + K.cx);
    const float v = static_cast<float>(K.fy * p_cam.y() / p_cam.z() + K.cy);
    if (!(u >= 0 && v >= 0 && u < w && v < h)) continue;
    int min_oct = -1, max_oct = -1;
    float radius = cfg.radius_px;
    if (mp.octave_hint >= 0) {
      radius *= frame.scale(mp.octave_hint);
      min_oct = std::max(0, mp.octave_hint - cfg.octave_window);
      max_oct = std::min(std::max(last_octave, 0), mp.octave_hint + cfg.octave_window);
    }
    const int nc = frame.features_in_radius(u, v, radius, min_oct, max_oct, candidates_.data(),
                                            static_cast<int>(candidates_.size()));
    if (nc > 0) {
      // Feature indices are non-negative: the int array is read as its unsigned variant.
      hamming_distances_at(mp.descriptor, frame.descriptor(0),
                           reinterpret_cast<const uint32_t*>(candidates_.data()), nc, distances_.data());
    }
    TwoNearest nn;
    for (int k = 0; k < nc; ++k) {
      const int j = candidates_[static_cast<size_t>(k)];
      if (j >= n_features) continue;
      nn.add(distances_[static_cast<size_t>(k)], j);
    }
    if (nn.index < 0 || nn.best > cfg.max_distance) continue;
    if (nn.second <= 256 && static_cast<float>(nn.best) >= cfg.ratio * static_cast<float>(nn.second))
      continue;
    owners_.offer(nn.index, i, nn.best);
  }
  return owners_.write(out, max_out);
}

}  // namespace hwr::estimation
