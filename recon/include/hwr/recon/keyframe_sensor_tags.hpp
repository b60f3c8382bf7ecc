#pragma once
// Magnetometer and GNSS metadata of the stored keyframes (issue #6 item 1: the prior map keeps
// "GNSS and magnetometer metadata" for relocalization). The robot hands every magnetometer sample
// and every 3D GNSS fix to the mapper as it arrives. A keyframe is tagged with the samples nearest
// its image time, if they lie within the configured gaps: the magnetometer field in the IMU frame
// (relocalization recomputes the heading with the keyframe's attitude, estimation/mag_heading.hpp)
// and the fix's WGS-84 position. The mapper remembers a keyframe's tags as soon as the keyframe
// exists (remember()) and applies them when it stores the keyframe, keyframe_lag keyframes later
// (tag()): keyframes are made only on motion, so a long stop between the two would otherwise have
// pushed the samples out of the rings.
// A sample more than restart_gap_ns older than the newest is taken as a source restart (the rings
// start over); a slightly older or equal one is out of order and ignored.
// Fixed rings allocated at construction; add_*(), remember() and tag() never allocate.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "hwr/hal/gnss_fix.hpp"
#include "hwr/hal/mag_sample.hpp"
#include "hwr/recon/map_store.hpp"

namespace hwr::recon {

struct KeyframeSensorTagsConfig {
  int mag_capacity = 512;                  // ~10 s at the ZED 2i's 50 Hz magnetometer
  int gnss_capacity = 128;                 // ~25 s at 5 Hz
  int64_t max_mag_gap_ns = 50'000'000;     // 50 ms
  int64_t max_gnss_gap_ns = 500'000'000;   // 0.5 s
  int64_t restart_gap_ns = 1'000'000'000;  // a sample this much older than the newest: the source restarted
  int remembered_keyframes = 64;           // keyframes whose tags are kept until they are stored
};

class KeyframeSensorTags {
 public:
  explicit KeyframeSensorTags(const KeyframeSensorTagsConfig& config = {});

  // Samples in time order (an older or non-finite one is ignored and counted).
  void add_mag(const hal::MagSample& sample);
  // Only 3D fixes with a finite position are kept.
  void add_gnss(const hal::GnssFix& fix);
  // Computes and keeps the tags of keyframe `id` (image time t_ns) from the samples seen so far.
  void remember(int32_t id, int64_t t_ns);
  // Sets keyframe->mag_valid / mag_imu_uT and gnss_valid / lat, lon, alt: the tags remembered for
  // keyframe->id, else those of the samples nearest keyframe->t_ns within the gaps (valid flags
  // false when there are none).
  void tag(StoredKeyframe* keyframe) const;

  uint64_t rejected() const { return rejected_; }

 private:
  template <class T>
  struct Ring {
    std::vector<T> items;
    size_t head = 0, count = 0;
    void push(const T& v) {
      const size_t cap = items.size();
      if (cap == 0) return;
      items[(head + count) % cap] = v;
      if (count < cap)
        ++count;
      else
        head = (head + 1) % cap;
    }
    const T& at(size_t i) const { return items[(head + i) % items.size()]; }
    const T* back() const { return count > 0 ? &at(count - 1) : nullptr; }
    void clear() { head = count = 0; }
  };
  // The item of `ring` whose t_ns is nearest t_ns, or null when none lies within max_gap_ns.
  template <class T>
  static const T* nearest(const Ring<T>& ring, int64_t t_ns, int64_t max_gap_ns);

  struct Tags {
    int32_t id = -1;
    bool mag_valid = false, gnss_valid = false;
    Eigen::Vector3d mag_imu_uT = Eigen::Vector3d::Zero();
    double lat_deg = 0, lon_deg = 0, alt_m = 0;
  };
  Tags tags_at(int64_t t_ns) const;

  KeyframeSensorTagsConfig config_;
  Ring<hal::MagSample> mag_;
  Ring<hal::GnssFix> gnss_;
  Ring<Tags> remembered_;
  uint64_t rejected_ = 0;
};

}  // namespace hwr::recon
