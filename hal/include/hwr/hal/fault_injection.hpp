#pragma once
// Sensor faults injected into a replay (issue #3 robustness): camera dropouts (the IMU keeps
// flowing, so the estimator must propagate on the IMU alone and then recover), exposure jumps,
// depth holes and IMU gaps. The transform works on any ReplayLog (simulator run, TUM, EuRoC), so
// the same faults can be replayed from hwr-robot's command line (`--faults SPEC`) and from tests.
//
// Depth holes may be written as NaN on purpose. The RgbdFrame contract (rgbd_frame.hpp) says an
// invalid depth pixel is exactly 0 because drivers turn NaN into 0; injected NaN stands for raw
// driver garbage that slipped through, and checks that everything downstream survives it.
//
// Times in a spec are seconds from the first sample of the log, whatever its stream (the earliest
// IMU, magnetometer, GNSS or camera timestamp). Spec text, comma-separated tokens:
//   dropout=START:DURATION             camera frames in [START, START+DURATION) removed
//   exposure=AT:GAIN                   colour × GAIN (saturating) from AT until the next jump
//   depth-nan=START:DURATION:FRACTION  ~FRACTION of each frame's depth set to NaN in the window
//   depth-zero=START:DURATION:FRACTION same, set to 0 (counted in invalid_depth_px)
//   imu-dropout=START:DURATION         IMU samples in [START, START+DURATION) removed
//   seed=N                             seed of the depth-hole rectangles (default 1)
// e.g. "dropout=30:2,exposure=40:2.5,depth-nan=10:5:0.3,imu-dropout=50:0.5".

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::hal {

struct FaultSpec {
  // Camera dropout: frames with start_s <= t - t_first < start_s + duration_s are removed (the IMU
  // keeps flowing). Several windows allowed.
  struct Window {
    double start_s = 0, duration_s = 0;
  };
  std::vector<Window> camera_dropouts;
  // Exposure jump: from at_s on, colour multiplied by gain (saturating), until the next jump (a
  // jump with gain 1 restores the original exposure). Jumps may be listed in any order.
  struct Exposure {
    double at_s = 0;
    double gain = 1;
  };
  std::vector<Exposure> exposure_jumps;
  // Depth holes: in frames within the window, rectangles drawn from a seeded generator (keyed by
  // seed, the entry's index and the frame's index in the original log) cover `fraction` of the
  // pixels (to within one rectangle row); their depth is set to NaN (value_nan) or 0.
  struct DepthHoles {
    double start_s = 0, duration_s = 1e9;
    double fraction = 0.3;
    bool value_nan = true;
  };
  std::vector<DepthHoles> depth_holes;
  // IMU gap: samples in the window removed.
  std::vector<Window> imu_dropouts;
  uint64_t seed = 1;

  bool empty() const;
};

// Parses the spec text above (an empty text is an empty spec). Errors name the bad token, e.g.
// "fault spec token 'dropout=30:-2': duration -2 must be > 0".
core::Expected<FaultSpec> parse_fault_spec(const std::string& text);
// The spec as text; parse_fault_spec(format_fault_spec(s)) gives s back exactly (shortest decimal
// that round-trips each double; seed written only when not 1).
std::string format_fault_spec(const FaultSpec& spec);

// What apply_faults injected. The loader wrapper updates it on the replay's prefetch thread, so
// the counters are atomics and the report is shared with the returned log.
struct FaultReport {
  std::atomic<uint64_t> frames_removed{0};           // camera dropouts (known when applied)
  std::atomic<uint64_t> frames_exposure_changed{0};  // frames loaded with a gain != 1
  std::atomic<uint64_t> frames_with_depth_holes{0};  // frames loaded with holes punched
  std::atomic<uint64_t> imu_removed{0};              // IMU dropouts (known when applied)
};

// Returns the log with the faults applied: frame_t_ns filtered, imu filtered, load_frame wrapped
// (it calls the original loader with the frame's ORIGINAL index, then edits the frame in place
// without allocating; invalid_depth_px grows by the previously valid pixels a hole covers, NaN or
// 0). info, mag and GNSS are unchanged. An invalid spec (same rules as the parser) is an error.
// The wrapped loader keeps the original's threading contract (one caller at a time).
core::Expected<ReplayLog> apply_faults(ReplayLog log, const FaultSpec& spec,
                                       std::shared_ptr<FaultReport>* report = nullptr);

}  // namespace hwr::hal
