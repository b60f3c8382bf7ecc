#pragma once
// The 3D points of the visual map (paper items 6–8): created from depth-backed keypoints
// (eq. 3) or by triangulation (eq. 4), refined by bundle adjustment (eq. 5). A fixed-capacity
// pool allocated at start-up (ARCHITECTURE.md firmware rules): slots are recycled through a free
// list, and every slot carries a generation so that a keyframe's reference to a culled point is
// recognised as stale without searching the keyframes.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "hwr/estimation/descriptor.hpp"

namespace hwr::estimation {

// A reference from a keyframe feature to a map point slot; stale when the generation differs.
struct MapPointHandle {
  int32_t index = -1;
  uint32_t generation = 0;
  bool valid() const { return index >= 0; }
};

struct MapPoint {
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  std::array<uint8_t, kOrbDescriptorBytes> descriptor{};
  uint32_t generation = 0;
  int32_t first_keyframe = -1;  // keyframe id that created it
  int32_t observations = 0;     // keyframes that observe it
  int32_t octave = 0;           // octave of the creating feature (search radius hint)
  uint32_t visible = 0;         // frames where it projected into the image
  uint32_t found = 0;           // frames where it was matched as an inlier
  uint32_t stamp = 0;           // scratch: last local-map collection that took it
  bool alive = false;
  bool triangulated = false;  // from two views (eq. 4), not from depth
};

class MapPointStore {
 public:
  explicit MapPointStore(int capacity);

  int capacity() const { return static_cast<int>(points_.size()); }
  int alive() const { return alive_; }
  // A new point, or an invalid handle when the pool is full (counted in exhausted()).
  MapPointHandle create(const Eigen::Vector3d& p_world_m, const uint8_t* descriptor, int keyframe_id,
                        int octave);
  void remove(MapPointHandle h);
  // nullptr for a stale or invalid handle.
  MapPoint* get(MapPointHandle h);
  const MapPoint* get(MapPointHandle h) const;
  MapPoint& at(int index) { return points_[static_cast<size_t>(index)]; }
  const MapPoint& at(int index) const { return points_[static_cast<size_t>(index)]; }
  MapPointHandle handle(int index) const { return {index, points_[static_cast<size_t>(index)].generation}; }
  uint64_t exhausted() const { return exhausted_; }

 private:
  std::vector<MapPoint> points_;
  std::vector<int32_t> free_;  // stack of free slots
  int alive_ = 0;
  uint64_t exhausted_ = 0;
};

}  // namespace hwr::estimation
