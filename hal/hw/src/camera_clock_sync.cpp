#include "hwr/hal/hw/camera_clock_sync.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace hwr::hal::hw {
namespace {

constexpr uint32_t kHalfRange = 0x8000'0000u;  // a u32 counter "went back" when it advances by more

CameraClockSyncConfig sanitized(CameraClockSyncConfig c) {
  c.window_pairs = std::max(c.window_pairs, 3);
  c.min_pairs_to_lock = std::clamp(c.min_pairs_to_lock, 3, c.window_pairs);
  c.pending_capacity = std::max(c.pending_capacity, 1);
  c.agreeing_pairs_for_offset = std::max(c.agreeing_pairs_for_offset, 1);
  c.mismatches_to_relock = std::max(c.mismatches_to_relock, 1);
  c.association_tolerance_ns = std::max<int64_t>(c.association_tolerance_ns, 0);
  c.outlier_floor_ns = std::max<int64_t>(c.outlier_floor_ns, 0);
  return c;
}

// a − b and a + b clamped to int64 (garbage inputs must not overflow; real clocks never get near).
int64_t sat_sub(int64_t a, int64_t b) {
  int64_t r = 0;
  if (!__builtin_sub_overflow(a, b, &r)) return r;
  return b < 0 ? INT64_MAX : INT64_MIN;
}
int64_t sat_add(int64_t a, int64_t b) {
  int64_t r = 0;
  if (!__builtin_add_overflow(a, b, &r)) return r;
  return b > 0 ? INT64_MAX : INT64_MIN;
}

// Median of v[0, n) (partially reorders v).
double median(std::vector<double>& v, size_t n) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(v.begin(), mid, v.begin() + static_cast<std::ptrdiff_t>(n));
  if (n % 2 == 1) return *mid;
  const double upper = *mid;
  const double lower = *std::max_element(v.begin(), mid);
  return 0.5 * (lower + upper);
}

struct Line {
  double a = 0, b = 0;  // y = a + b·x
  double sxx = 0;
  size_t n = 0;
  bool ok = false;
};

// Least squares y = a + b·x over the points with inlier[i] != 0 (centred sums: the x are seconds
// of host time in ns, y microseconds of clock difference).
Line fit_line(const std::vector<double>& x, const std::vector<double>& y, const std::vector<uint8_t>& inlier,
              size_t n) {
  Line l;
  double sx = 0, sy = 0;
  for (size_t i = 0; i < n; ++i) {
    if (inlier[i] == 0) continue;
    sx += x[i];
    sy += y[i];
    ++l.n;
  }
  if (l.n < 2) return l;
  const double mx = sx / static_cast<double>(l.n), my = sy / static_cast<double>(l.n);
  double sxy = 0;
  for (size_t i = 0; i < n; ++i) {
    if (inlier[i] == 0) continue;
    l.sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (!(l.sxx > 0)) return l;
  l.b = sxy / l.sxx;
  l.a = my - l.b * mx;
  l.ok = std::isfinite(l.a) && std::isfinite(l.b);
  return l;
}

}  // namespace

CameraClockSync::CameraClockSync(const CameraClockSyncConfig& config)
    : config_(sanitized(config)), coarse_(config_.receipt_window_s) {
  const size_t pending = static_cast<size_t>(config_.pending_capacity);
  const size_t window = static_cast<size_t>(config_.window_pairs);
  syncs_.reserve(pending);
  frames_.reserve(pending);
  window_.resize(window);
  x_.resize(window);
  y_.resize(window);
  r_.resize(window);
  scratch_.resize(window);
  inlier_.resize(window);
}

void CameraClockSync::reset() {
  reset_association();
  coarse_.reset();
  last_receipt_imu_ns_.reset();
  last_sync_.reset();
  last_frame_.reset();
}

void CameraClockSync::reset_association() {
  syncs_.clear();  // keeps the capacity
  frames_.clear();
  k_trusted_ = false;
  k_ = 0;
  k_agree_ = 0;
  consecutive_mismatches_ = 0;
  window_head_ = window_size_ = 0;
  estimate_ = CameraClockEstimate{};
  estimate_frac_ns_ = 0;
}

void CameraClockSync::add_receipt(int64_t t_imu_ns, int64_t t_receipt_host_ns) {
  ++counters_.receipts;
  // ReceiptClockMap works in plain int64 differences and sums: keep both times within ±2^61 ns
  // (±73 years) so that none of them can overflow.
  constexpr int64_t kLimit = int64_t{1} << 61;
  if (t_imu_ns < -kLimit || t_imu_ns > kLimit || t_receipt_host_ns < -kLimit || t_receipt_host_ns > kLimit) {
    ++counters_.bad_receipts;
    return;
  }
  if (last_receipt_imu_ns_ && t_imu_ns < *last_receipt_imu_ns_) {
    ++counters_.receipt_restarts;  // the MCU's clock restarted: the old envelope is of another clock
    coarse_.reset();
  }
  last_receipt_imu_ns_ = t_imu_ns;
  coarse_.map(t_imu_ns, t_receipt_host_ns);
}

void CameraClockSync::add_report(const ZedSensorReport& report, std::optional<int64_t> t_receipt_host_ns) {
  if (t_receipt_host_ns) add_receipt(report.t_imu_ns, *t_receipt_host_ns);
  if (report.frame_sync) add_sync_event(report.t_imu_ns, report.frame_sync_count);
}

void CameraClockSync::add_sync_event(int64_t t_imu_ns, uint32_t frame_sync_count) {
  ++counters_.sync_events;
  if (last_sync_) {
    const uint32_t advance = frame_sync_count - last_sync_->count;
    if (advance == 0 && t_imu_ns >= last_sync_->t_imu_ns) {
      ++counters_.duplicates;  // a resent report, or flagged twice for one frame: the first stands
      return;
    }
    if (t_imu_ns <= last_sync_->t_imu_ns || advance >= kHalfRange) {
      ++counters_.sync_restarts;
      reset_association();
    }
  }
  last_sync_ = Sync{t_imu_ns, frame_sync_count};
  if (syncs_.size() >= static_cast<size_t>(config_.pending_capacity)) {
    syncs_.erase(syncs_.begin());
    ++counters_.syncs_unmatched;
  }
  syncs_.push_back(Sync{t_imu_ns, frame_sync_count});
  match();
}

void CameraClockSync::add_frame(int64_t t_host_ns, uint32_t sequence) {
  ++counters_.frames;
  if (last_frame_) {
    const uint32_t advance = sequence - last_frame_->sequence;
    if (advance == 0) {
      ++counters_.duplicates;  // the same buffer seen twice (or a sequence that did not advance)
      return;
    }
    if (t_host_ns <= last_frame_->t_host_ns || advance >= kHalfRange) {
      ++counters_.frame_restarts;
      reset_association();
    }
  }
  last_frame_ = Frame{t_host_ns, sequence};
  if (frames_.size() >= static_cast<size_t>(config_.pending_capacity)) {
    frames_.erase(frames_.begin());
    ++counters_.frames_unmatched;
  }
  frames_.push_back(Frame{t_host_ns, sequence});
  match();
}

void CameraClockSync::match() {
  if (syncs_.empty() || frames_.empty()) return;
  if (k_trusted_) {
    match_by_offset();
    return;
  }
  const std::optional<int64_t> coarse = coarse_.offset_ns();
  if (!coarse) {
    ++counters_.no_coarse_map;
    return;
  }
  match_by_time(*coarse);
}

// Both queues are in arrival order, which is counter order: compare the oldest of each; the one
// whose partner would be older than everything pending on the other side has lost its partner.
void CameraClockSync::match_by_offset() {
  while (!syncs_.empty() && !frames_.empty()) {
    const uint32_t expected_sequence = syncs_.front().count - k_;
    const auto d = static_cast<int32_t>(frames_.front().sequence - expected_sequence);
    if (d == 0) {
      const Pair p{frames_.front().t_host_ns, syncs_.front().t_imu_ns};
      syncs_.erase(syncs_.begin());
      frames_.erase(frames_.begin());
      take_pair(p);
      if (!k_trusted_) return;  // a relock cleared everything
    } else if (d > 0) {
      syncs_.erase(syncs_.begin());  // its frame was dropped (a sequence gap)
      ++counters_.syncs_unmatched;
    } else {
      frames_.erase(frames_.begin());  // its sync event was missed (a count gap)
      ++counters_.frames_unmatched;
    }
  }
}

// Before K is trusted: a frame belongs to the sync event whose coarse host time (plus the expected
// stamp lag) lies within the tolerance of its stamp.
void CameraClockSync::match_by_time(int64_t coarse_offset_ns) {
  const int64_t tol = config_.association_tolerance_ns;
  while (!syncs_.empty() && !frames_.empty()) {
    const Sync s = syncs_.front();
    const Frame f = frames_.front();
    const int64_t predicted_host_ns =
        sat_add(sat_add(s.t_imu_ns, coarse_offset_ns), config_.frame_stamp_lag_ns);
    const int64_t d = sat_sub(f.t_host_ns, predicted_host_ns);
    if (d < -tol) {
      frames_.erase(frames_.begin());  // earlier than this sync event: its own was missed
      ++counters_.frames_unmatched;
      continue;
    }
    if (d > tol) {
      syncs_.erase(syncs_.begin());  // later than this sync event's frame: that frame was dropped
      ++counters_.syncs_unmatched;
      continue;
    }
    syncs_.erase(syncs_.begin());
    frames_.erase(frames_.begin());
    const uint32_t k = s.count - f.sequence;
    if (k_agree_ > 0 && k == k_) {
      ++k_agree_;
    } else {
      if (k_agree_ > 0) ++counters_.offset_conflicts;
      k_ = k;
      k_agree_ = 1;
      window_head_ = window_size_ = 0;  // pairs of the old candidate do not belong with these
    }
    k_trusted_ = k_agree_ >= config_.agreeing_pairs_for_offset;
    take_pair(Pair{f.t_host_ns, s.t_imu_ns});
    if (k_trusted_) {
      match_by_offset();
      return;
    }
  }
}

void CameraClockSync::take_pair(const Pair& p) {
  if (estimate_.locked) {
    const std::optional<int64_t> predicted = to_imu_clock(p.t_host_ns);
    const int64_t residual = predicted ? sat_sub(*predicted, p.t_imu_ns) : INT64_MAX;
    const bool far = residual > config_.max_residual_ns || residual < -config_.max_residual_ns;
    if (far) {
      ++counters_.mismatches;
      if (++consecutive_mismatches_ >= config_.mismatches_to_relock) {
        ++counters_.relocks;
        reset_association();
      }
      return;
    }
    consecutive_mismatches_ = 0;
  }
  const size_t cap = window_.size();
  if (window_size_ < cap) {
    window_[(window_head_ + window_size_) % cap] = p;
    ++window_size_;
  } else {
    window_[window_head_] = p;  // overwrite the oldest
    window_head_ = (window_head_ + 1) % cap;
  }
  ++counters_.pairs;
  fit();
}

// Eq. (1) on the window, in the form d = t_imu − t_host = offset' + drift · (t_host − ref) about the
// newest pair (ref), with residual screening (see the header).
void CameraClockSync::fit() {
  const size_t n = window_size_;
  const size_t cap = window_.size();
  const Pair& newest = window_[(window_head_ + n - 1) % cap];
  const int64_t ref_host = newest.t_host_ns;
  const int64_t ref_d = sat_sub(newest.t_imu_ns, newest.t_host_ns);
  for (size_t i = 0; i < n; ++i) {
    const Pair& p = window_[(window_head_ + i) % cap];
    x_[i] = static_cast<double>(sat_sub(p.t_host_ns, ref_host));
    y_[i] = static_cast<double>(sat_sub(sat_sub(p.t_imu_ns, p.t_host_ns), ref_d));
    inlier_[i] = 1;
  }
  Line line = fit_line(x_, y_, inlier_, n);
  for (int iteration = 0; line.ok && iteration < 5; ++iteration) {
    for (size_t i = 0; i < n; ++i) r_[i] = y_[i] - line.a - line.b * x_[i];
    std::copy(r_.begin(), r_.begin() + static_cast<std::ptrdiff_t>(n), scratch_.begin());
    const double med = median(scratch_, n);
    for (size_t i = 0; i < n; ++i) scratch_[i] = std::fabs(r_[i] - med);
    const double mad = median(scratch_, n);
    const double threshold =
        std::max(config_.outlier_mad_k * 1.4826 * mad, static_cast<double>(config_.outlier_floor_ns));
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      const uint8_t in = std::fabs(r_[i] - med) <= threshold ? 1 : 0;
      changed = changed || in != inlier_[i];
      inlier_[i] = in;
    }
    if (!changed) break;
    line = fit_line(x_, y_, inlier_, n);
  }

  CameraClockEstimate e;
  if (line.ok) {
    double sum_r2 = 0;
    int64_t oldest_in = 0, newest_in = 0;
    bool any = false;
    for (size_t i = 0; i < n; ++i) {
      if (inlier_[i] == 0) continue;
      const double r = y_[i] - line.a - line.b * x_[i];
      sum_r2 += r * r;
      const int64_t t = window_[(window_head_ + i) % cap].t_host_ns;
      if (!any) oldest_in = t;
      newest_in = t;
      any = true;
    }
    e.pairs = static_cast<int>(line.n);
    e.outliers = static_cast<int>(n - line.n);
    e.span_ns = newest_in - oldest_in;
    e.residual_rms_ns = std::sqrt(sum_r2 / static_cast<double>(line.n));
    e.drift_ppm = line.b * 1e6;
    e.drift_std_ppm = line.n > 2 ? std::sqrt(sum_r2 / static_cast<double>(line.n - 2) / line.sxx) * 1e6 : 0.0;
    e.ref_host_ns = ref_host;
    const double whole = std::floor(line.a);
    e.offset_ns = sat_add(ref_d, static_cast<int64_t>(std::clamp(whole, -9e18, 9e18)));
    estimate_frac_ns_ = line.a - whole;
    e.locked = k_trusted_ && e.pairs >= config_.min_pairs_to_lock && e.span_ns >= config_.min_span_to_lock_ns;
  }
  estimate_ = e;
}

std::optional<int64_t> CameraClockSync::to_imu_clock(int64_t t_host_ns) const {
  if (!estimate_.locked) return std::nullopt;
  int64_t dt = 0, out = 0;
  if (__builtin_sub_overflow(t_host_ns, estimate_.ref_host_ns, &dt)) return std::nullopt;
  const double correction = estimate_frac_ns_ + estimate_.drift_ppm * 1e-6 * static_cast<double>(dt);
  if (!(std::fabs(correction) < 9e18)) return std::nullopt;
  if (__builtin_add_overflow(t_host_ns, estimate_.offset_ns, &out)) return std::nullopt;
  if (__builtin_add_overflow(out, static_cast<int64_t>(std::llround(correction)), &out)) return std::nullopt;
  return out;
}

std::optional<int64_t> CameraClockSync::to_host_clock(int64_t t_imu_ns) const {
  if (!estimate_.locked) return std::nullopt;
  // (1) about the reference: t_imu − ref = (t_host − ref)(1 + drift) + offset + frac.
  int64_t d = 0;
  if (__builtin_sub_overflow(t_imu_ns, estimate_.ref_host_ns, &d)) return std::nullopt;
  if (__builtin_sub_overflow(d, estimate_.offset_ns, &d)) return std::nullopt;
  const double dt_host = (static_cast<double>(d) - estimate_frac_ns_) / (1.0 + estimate_.drift_ppm * 1e-6);
  if (!(std::fabs(dt_host) < 9e18)) return std::nullopt;
  int64_t out = 0;
  if (__builtin_add_overflow(estimate_.ref_host_ns, static_cast<int64_t>(std::llround(dt_host)), &out)) {
    return std::nullopt;
  }
  return out;
}

}  // namespace hwr::hal::hw
