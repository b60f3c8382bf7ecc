#include "hwr/mapio/world_cloud.hpp"

#include <unordered_map>

#include <Eigen/Geometry>

namespace hwr::mapio {

core::Status assemble_world_cloud(const std::vector<hwr_lcm::map_chunk_t>& chunks,
                                  const ChunkDecodeLimits& limits, DecodedChunk* scratch, WorldCloud* out) {
  if (chunks.empty()) return core::Status::Ok();
  const hwr_lcm::map_chunk_t& latest = chunks.back();  // ordered by chunk_index
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = latest.T_world_segment[4 * r + c];
  const Eigen::Matrix3f R = T.topLeftCorner<3, 3>().cast<float>();
  const Eigen::Vector3f t = T.topRightCorner<3, 1>().cast<float>();
  std::unordered_map<uint32_t, size_t> index_of_id;
  for (const hwr_lcm::map_chunk_t& c : chunks) {
    if (c.num_points == 0) continue;
    HWR_RETURN_IF_ERROR(decode_chunk(c.payload.data(), c.payload.size(), c.num_points, limits, scratch));
    for (size_t i = 0; i < scratch->points.size(); ++i) {
      const ChunkPoint& p = scratch->points[i];
      const Eigen::Vector3f w = R * Eigen::Vector3f(p.x_m, p.y_m, p.z_m) + t;
      size_t at = out->size();
      if (!scratch->ids.empty()) {
        auto [it, inserted] = index_of_id.emplace(scratch->ids[i], at);
        if (!inserted) at = it->second;
      }
      if (at == out->size()) {
        out->xyz.insert(out->xyz.end(), {w.x(), w.y(), w.z()});
        out->rgb.insert(out->rgb.end(), {p.r, p.g, p.b});
      } else {
        for (int k = 0; k < 3; ++k) out->xyz[3 * at + k] = w[k];
        out->rgb[3 * at] = p.r;
        out->rgb[3 * at + 1] = p.g;
        out->rgb[3 * at + 2] = p.b;
      }
    }
  }
  return core::Status::Ok();
}

void thin_world_cloud(const WorldCloud& in, int64_t max_points, WorldCloud* out) {
  const auto n = static_cast<int64_t>(in.size());
  const int64_t step = max_points <= 0 || n <= max_points ? 1 : (n + max_points - 1) / max_points;
  out->xyz.clear();
  out->rgb.clear();
  out->xyz.reserve(static_cast<size_t>(3 * ((n + step - 1) / step)));
  out->rgb.reserve(out->xyz.capacity());
  for (int64_t i = 0; i < n; i += step) {
    out->xyz.insert(out->xyz.end(), in.xyz.begin() + 3 * i, in.xyz.begin() + 3 * i + 3);
    out->rgb.insert(out->rgb.end(), in.rgb.begin() + 3 * i, in.rgb.begin() + 3 * i + 3);
  }
}

}  // namespace hwr::mapio
