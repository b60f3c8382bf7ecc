#include "hwr/recon/keyframe_sensor_tags.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace hwr::recon {

KeyframeSensorTags::KeyframeSensorTags(const KeyframeSensorTagsConfig& config) : config_(config) {
  mag_.items.resize(static_cast<size_t>(std::max(config.mag_capacity, 1)));
  gnss_.items.resize(static_cast<size_t>(std::max(config.gnss_capacity, 1)));
  remembered_.items.resize(static_cast<size_t>(std::max(config.remembered_keyframes, 1)));
}

void KeyframeSensorTags::add_mag(const hal::MagSample& sample) {
  const hal::MagSample* last = mag_.back();
  if (last != nullptr && sample.t_ns < last->t_ns - config_.restart_gap_ns) mag_.clear();  // restarted
  last = mag_.back();
  if (!sample.field_uT.allFinite() || (last != nullptr && sample.t_ns <= last->t_ns)) {
    ++rejected_;
    return;
  }
  mag_.push(sample);
}

void KeyframeSensorTags::add_gnss(const hal::GnssFix& fix) {
  const hal::GnssFix* last = gnss_.back();
  if (last != nullptr && fix.t_ns < last->t_ns - config_.restart_gap_ns) gnss_.clear();  // restarted
  last = gnss_.back();
  if (!fix.has_3d_fix() || !std::isfinite(fix.lat_deg) || !std::isfinite(fix.lon_deg) ||
      !std::isfinite(fix.height_m) || (last != nullptr && fix.t_ns <= last->t_ns)) {
    ++rejected_;
    return;
  }
  gnss_.push(fix);
}

template <class T>
const T* KeyframeSensorTags::nearest(const Ring<T>& ring, int64_t t_ns, int64_t max_gap_ns) {
  // Times increase along the ring: binary search for the first item at or after t_ns.
  size_t lo = 0, hi = ring.count;
  while (lo < hi) {
    const size_t mid = (lo + hi) / 2;
    if (ring.at(mid).t_ns < t_ns)
      lo = mid + 1;
    else
      hi = mid;
  }
  const T* best = nullptr;
  int64_t best_gap = max_gap_ns;
  for (size_t i : {lo - 1, lo}) {  // lo - 1 wraps to SIZE_MAX when lo == 0: skipped below
    if (i >= ring.count) continue;
    const int64_t gap = std::llabs(ring.at(i).t_ns - t_ns);
    if (gap <= best_gap) {
      best_gap = gap;
      best = &ring.at(i);
    }
  }
  return best;
}

KeyframeSensorTags::Tags KeyframeSensorTags::tags_at(int64_t t_ns) const {
  Tags t;
  if (const hal::MagSample* m = nearest(mag_, t_ns, config_.max_mag_gap_ns)) {
    t.mag_valid = true;
    t.mag_imu_uT = m->field_uT;
  }
  if (const hal::GnssFix* g = nearest(gnss_, t_ns, config_.max_gnss_gap_ns)) {
    t.gnss_valid = true;
    t.lat_deg = g->lat_deg;
    t.lon_deg = g->lon_deg;
    t.alt_m = g->height_m;
  }
  return t;
}

void KeyframeSensorTags::remember(int32_t id, int64_t t_ns) {
  Tags t = tags_at(t_ns);
  t.id = id;
  remembered_.push(t);
}

void KeyframeSensorTags::tag(StoredKeyframe* keyframe) const {
  Tags t;
  bool found = false;
  for (size_t i = remembered_.count; i-- > 0;) {
    if (remembered_.at(i).id == keyframe->id) {
      t = remembered_.at(i);
      found = true;
      break;
    }
  }
  if (!found) t = tags_at(keyframe->t_ns);
  keyframe->mag_valid = t.mag_valid;
  keyframe->mag_imu_uT = t.mag_imu_uT;
  keyframe->gnss_valid = t.gnss_valid;
  keyframe->lat_deg = t.lat_deg;
  keyframe->lon_deg = t.lon_deg;
  keyframe->alt_m = t.alt_m;
}

}  // namespace hwr::recon
