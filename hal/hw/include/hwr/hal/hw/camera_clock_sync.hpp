#pragma once
// Camera frame times on the ZED 2i's IMU clock (hardware.md "Frame/IMU sync"): with sensor sync
// enabled, the IMU report taken at a frame's exposure has frame_sync = 1 and an incremented
// frame_sync_count. Each such sync event is one frame's exposure on the MCU's clock (t_imu_ns); the
// V4L2 buffer of that frame carries the host's CLOCK_MONOTONIC stamp (t_host_ns) and a sequence
// number. Matched (t_host, t_imu) pairs give the affine map
//     t_imu = offset + (1 + drift) · t_host                                          (1)
// estimated by least squares over a sliding window of pairs, so frames can be put on the IMU's
// timeline without mixing the clocks (every name here says which clock it is on).
//
// Association. Both counters advance one per frame, so once a sync event and its frame are known,
// frame_sync_count − sequence (modulo 2^32) is a constant K and later pairs are matched exactly by
// it, across dropped frames (sequence gaps) and missed sync events (count gaps). Finding K needs a
// coarse link between the clocks: at a constant frame rate every K fits (1) equally well, shifted by
// whole frame periods. The link is the HID reports' host receipt times: the lower envelope of
// (t_receipt − t_imu) (ReceiptClockMap) puts a sync event on the host clock to within the USB
// latency floor (~1 ms), and the frame whose stamp lies within association_tolerance_ns of that
// (plus frame_stamp_lag_ns) is its partner. agreeing_pairs_for_offset such pairs with the same K
// make K trusted. Without receipt times the estimator stays unlocked (counted in no_coarse_map).
// zed-open-capture (src/sensorcapture.cpp) pairs the same two streams, by arrival order instead.
//
// Robustness. Each fit is least squares on the window, then residuals r_i against it are screened:
// |r_i − median(r)| > max(outlier_mad_k · 1.4826 · MAD, outlier_floor_ns) is an outlier (USB latency
// spikes on a frame stamp), and the fit is redone on the rest until the inlier set settles. Once
// locked, a K-matched pair off the fit by more than max_residual_ns is not added (counted as a
// mismatch); mismatches_to_relock consecutive ones (a broken association) drop K and start over.
// A sync or frame stream that restarts (its clock or counter goes back) resets the association.
//
// Memory: every buffer is sized in the constructor; nothing allocates afterwards.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "hwr/hal/hw/receipt_clock_map.hpp"
#include "hwr/hal/hw/zed_sensor_report.hpp"

namespace hwr::hal::hw {

struct CameraClockSyncConfig {
  int window_pairs = 256;  // pairs in the fit (≈ 8.5 s at 30 fps); minimum 3
  int min_pairs_to_lock = 16;
  int64_t min_span_to_lock_ns = 1'000'000'000;  // host time between the oldest and newest inlier
  int pending_capacity = 64;  // unmatched sync events / frames kept while their partner is on its way
  // Expected frame stamp minus the exposure's host time. hardware.md: uvcvideo stamps the start of
  // exposure and the MCU flags the IMU sample taken at the exposure, so 0. A driver that stamps
  // later (at the end of the transfer) needs that delay here, to within association_tolerance_ns;
  // the fit itself absorbs any constant lag into the offset (frames map as stamped).
  int64_t frame_stamp_lag_ns = 0;
  // How far a frame stamp may lie from its sync event's coarse host time. Must stay under half the
  // shortest frame period (5 ms at 100 fps) and above the USB latency floor plus jitter.
  int64_t association_tolerance_ns = 4'000'000;
  int agreeing_pairs_for_offset = 5;
  double outlier_mad_k = 4.0;
  int64_t outlier_floor_ns = 50'000;    // a jitter-free stream has MAD ≈ 0: never reject below this
  int64_t max_residual_ns = 5'000'000;  // locked: a pair further off the fit is not added
  int mismatches_to_relock = 8;
  int receipt_window_s = 10;  // ReceiptClockMap's window (at 100 ppm, 1 ms of drift)
};

// The current fit of (1). Only meaningful when locked.
struct CameraClockEstimate {
  bool locked = false;
  double drift_ppm = 0;      // (1)'s drift · 1e6: the IMU clock gains drift_ppm µs per host second
  double drift_std_ppm = 0;  // its standard error from the inlier residuals
  // Reference point of the fit: t_imu(ref_host_ns) = ref_host_ns + offset_ns (+ fractional ns).
  int64_t ref_host_ns = 0;  // the newest pair's host stamp
  // t_imu − t_host at ref_host_ns: (1)'s offset carried to the reference point, where the fit is
  // well conditioned (the offset at t_host = 0 is an extrapolation over the whole uptime).
  int64_t offset_ns = 0;
  double residual_rms_ns = 0;
  int pairs = 0;     // inliers
  int outliers = 0;  // pairs of the window left out of the last fit
  int64_t span_ns = 0;
};

struct CameraClockSyncCounters {
  uint64_t sync_events = 0, frames = 0, receipts = 0;
  // A frame with the sequence of the one before, or a sync event with its count (a resent report,
  // or a second flagged sample for one frame): ignored.
  uint64_t duplicates = 0;
  uint64_t sync_restarts = 0;     // the IMU clock or frame_sync_count went back: state reset
  uint64_t frame_restarts = 0;    // the V4L2 stamp or sequence went back: state reset
  uint64_t receipt_restarts = 0;  // a receipt's IMU time went back: coarse map reset
  uint64_t bad_receipts = 0;      // a time beyond ±2^61 ns (73 years): ignored
  uint64_t no_coarse_map = 0;     // association attempts without any receipt time yet
  uint64_t pairs = 0;             // matched pairs added to the window
  uint64_t syncs_unmatched = 0;   // sync events given up (their frame was dropped)
  uint64_t frames_unmatched = 0;  // frames given up (their sync event was missed)
  uint64_t offset_conflicts = 0;  // time-associated pairs that disagreed on K
  uint64_t mismatches = 0;        // locked: K-matched pairs off the fit by > max_residual_ns
  uint64_t relocks = 0;           // association dropped after consecutive mismatches
};

class CameraClockSync {
 public:
  explicit CameraClockSync(const CameraClockSyncConfig& config = {});

  // Any HID report's IMU time and when the host read it (CLOCK_MONOTONIC): the coarse map.
  void add_receipt(int64_t t_imu_ns, int64_t t_receipt_host_ns);
  // A report with frame_sync = 1.
  void add_sync_event(int64_t t_imu_ns, uint32_t frame_sync_count);
  // A dequeued V4L2 buffer: its timestamp and sequence.
  void add_frame(int64_t t_host_ns, uint32_t sequence);
  // A parsed report: its receipt (when given) and, if flagged, its sync event.
  void add_report(const ZedSensorReport& report, std::optional<int64_t> t_receipt_host_ns);

  // t_host_ns on the IMU clock by (1); nothing until locked.
  std::optional<int64_t> to_imu_clock(int64_t t_host_ns) const;
  // The inverse: t_imu_ns on the host clock, t_host = ref + (t_imu − ref − offset) / (1 + drift);
  // nothing until locked. This is how IMU samples join the camera frames' timeline.
  std::optional<int64_t> to_host_clock(int64_t t_imu_ns) const;

  const CameraClockEstimate& estimate() const { return estimate_; }
  const CameraClockSyncCounters& counters() const { return counters_; }
  // frame_sync_count − sequence once trusted.
  std::optional<uint32_t> sequence_offset() const {
    return k_trusted_ ? std::optional<uint32_t>(k_) : std::nullopt;
  }
  // Forgets everything but the counters (both devices reopened).
  void reset();

 private:
  struct Sync {
    int64_t t_imu_ns;
    uint32_t count;
  };
  struct Frame {
    int64_t t_host_ns;
    uint32_t sequence;
  };
  struct Pair {
    int64_t t_host_ns;
    int64_t t_imu_ns;
  };

  void reset_association();
  void match();
  void match_by_offset();
  void match_by_time(int64_t coarse_offset_ns);
  void take_pair(const Pair& p);
  void fit();

  CameraClockSyncConfig config_;
  CameraClockSyncCounters counters_;
  CameraClockEstimate estimate_;
  double estimate_frac_ns_ = 0;  // the fractional ns of the offset at ref_host_ns
  ReceiptClockMap coarse_;
  std::optional<int64_t> last_receipt_imu_ns_;
  std::optional<Sync> last_sync_;
  std::optional<Frame> last_frame_;

  // Pending sync events and frames, oldest first (erase from the front of a reserved vector).
  std::vector<Sync> syncs_;
  std::vector<Frame> frames_;

  bool k_trusted_ = false;
  uint32_t k_ = 0;  // candidate or trusted frame_sync_count − sequence
  int k_agree_ = 0;
  int consecutive_mismatches_ = 0;

  // The window: a ring of pairs, and scratch for the fit.
  std::vector<Pair> window_;
  size_t window_head_ = 0, window_size_ = 0;
  std::vector<double> x_, y_, r_, scratch_;
  std::vector<uint8_t> inlier_;
};

}  // namespace hwr::hal::hw
