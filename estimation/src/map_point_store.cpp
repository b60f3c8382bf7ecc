#include "hwr/estimation/map_point_store.hpp"

#include <cstring>

namespace hwr::estimation {

MapPointStore::MapPointStore(int capacity) : points_(static_cast<size_t>(capacity > 0 ? capacity : 1)) {
  free_.reserve(points_.size());
  for (int i = static_cast<int>(points_.size()) - 1; i >= 0; --i) free_.push_back(i);
}

MapPointHandle MapPointStore::create(const Eigen::Vector3d& p_world_m, const uint8_t* descriptor,
                                     int keyframe_id, int octave) {
  if (free_.empty()) {
    ++exhausted_;
    return {};
  }
  const int32_t i = free_.back();
  free_.pop_back();
  MapPoint& p = points_[static_cast<size_t>(i)];
  const uint32_t generation = p.generation + 1;
  p = MapPoint{};
  p.generation = generation;
  p.p_world_m = p_world_m;
  std::memcpy(p.descriptor.data(), descriptor, kOrbDescriptorBytes);
  p.first_keyframe = keyframe_id;
  p.octave = octave;
  p.alive = true;
  ++alive_;
  return {i, generation};
}

void MapPointStore::remove(MapPointHandle h) {
  MapPoint* p = get(h);
  if (p == nullptr) return;
  p->alive = false;
  ++p->generation;  // every outstanding handle becomes stale
  free_.push_back(h.index);
  --alive_;
}

MapPoint* MapPointStore::get(MapPointHandle h) {
  if (h.index < 0 || h.index >= capacity()) return nullptr;
  MapPoint& p = points_[static_cast<size_t>(h.index)];
  return (p.alive && p.generation == h.generation) ? &p : nullptr;
}

const MapPoint* MapPointStore::get(MapPointHandle h) const {
  return const_cast<MapPointStore*>(this)->get(h);
}

}  // namespace hwr::estimation
