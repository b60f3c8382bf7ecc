#pragma once
// A stored segment version as one point cloud in the robot's world frame: what the ground station
// writes as segment_*.ply and what the viewer draws (docs/ground_viewer.md).

#include <cstdint>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/mapio/chunk_codec.hpp"
#include "hwr_lcm/map_chunk_t.hpp"

namespace hwr::mapio {

struct WorldCloud {
  std::vector<float> xyz;    // 3 per point, metres, world frame
  std::vector<uint8_t> rgb;  // 3 per point
  size_t size() const { return xyz.size() / 3; }
};

// Decodes `chunks` (one segment version, ordered by chunk_index, as GroundStore::load_segment gives
// them) and places every point in the world with the T_world_segment of the last chunk (the sender's
// latest estimate). A point id seen again keeps the later chunk's point. Appends to `out`;
// `scratch` is reused between calls. The first chunk that does not decode is the error.
core::Status assemble_world_cloud(const std::vector<hwr_lcm::map_chunk_t>& chunks,
                                  const ChunkDecodeLimits& limits, DecodedChunk* scratch, WorldCloud* out);

// Every k-th point of `in` (k = ceil(n / max_points)) into `out`, so that at most max_points remain;
// max_points <= 0 keeps every point. Deterministic: the same cloud thins to the same points.
void thin_world_cloud(const WorldCloud& in, int64_t max_points, WorldCloud* out);

}  // namespace hwr::mapio
