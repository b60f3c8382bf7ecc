#pragma once
// Replay of a recorded run (TUM RGB-D, EuRoC, our simulator's runs) as a SensorSource.
// Samples are held in memory (IMU/mag/GNSS are small); camera frames are decoded ahead of time on
// the replay's own prefetch thread into frames taken from the streams' pool, so poll() only moves
// pointers. Replay is deterministic: when the scheduler runs on a SimClock faster than the disk,
// poll() waits for the prefetcher rather than dropping a frame.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/status.hpp"
#include "hwr/hal/sensor_source.hpp"

namespace hwr::hal {

// What a dataset reader hands to the replay.
struct ReplayLog {
  SourceInfo info;
  std::vector<ImuSample> imu;
  std::vector<MagSample> mag;
  std::vector<GnssFix> gnss;
  std::vector<int64_t> frame_t_ns;  // strictly increasing
  // Decodes frame i into *out (called on the prefetch thread, in index order).
  std::function<core::Status(size_t i, RgbdFrame* out)> load_frame;
};

// Opens "tum:DIR" or "euroc:DIR" (the folder holding mav0/, or mav0 itself). The simulator's
// runs ("sim:DIR") are opened by hwr::sim::open_sim_run (hal/sim), which depends on this module.
core::Expected<ReplayLog> open_dataset_log(const std::string& spec);

class ReplaySource final : public SensorSource {
 public:
  // Validates the log (sorted timestamps, a loader when there are frames) and starts the
  // prefetch thread, which takes frames from streams->frame_pool.
  static core::Expected<std::unique_ptr<ReplaySource>> create(ReplayLog log, SensorStreams* streams);
  ~ReplaySource() override;

  const SourceInfo& info() const override { return log_.info; }
  core::Status poll(int64_t until_ns, SensorStreams* streams) override;
  bool finished() const override;
  SourceCounters counters() const override { return counters_; }

 private:
  struct Loaded {
    RgbdFrame* frame = nullptr;  // from the pool; poll() releases it when the load failed
    size_t index = 0;
    bool ok = false;
  };
  ReplaySource(ReplayLog log, SensorStreams* streams);
  void prefetch_loop();
  // True when the prefetcher waits for a pool frame and the pipeline holds all of them.
  bool prefetcher_blocked();

  ReplayLog log_;
  SensorStreams* streams_;
  SourceCounters counters_;
  size_t next_imu_ = 0, next_mag_ = 0, next_gnss_ = 0, next_frame_ = 0;

  core::SpscRing<Loaded> ready_;  // prefetch thread → poll()
  std::atomic<bool> stop_{false};
  std::mutex starve_mutex_;
  bool prefetch_starved_ = false;  // guarded: the last acquire found the pool empty
  std::atomic<bool> prefetch_done_{false};
  std::thread prefetcher_;
};

}  // namespace hwr::hal
