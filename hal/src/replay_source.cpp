#include "hwr/hal/replay_source.hpp"

#include <cassert>
#include <chrono>
#include <exception>
#include <string>
#include <utility>

#include "hwr/core/log.hpp"

namespace hwr::hal {
namespace {

constexpr const char* kLog = "replay";

template <class T>
bool sorted_by_time(const std::vector<T>& v) {
  for (size_t i = 1; i < v.size(); ++i) {
    if (v[i].t_ns <= v[i - 1].t_ns) return false;
  }
  return true;
}

}  // namespace

core::Expected<std::unique_ptr<ReplaySource>> ReplaySource::create(ReplayLog log, SensorStreams* streams) {
  const std::string& name = log.info.name;
  if (!sorted_by_time(log.imu)) return core::InvalidArgument(name + ": IMU samples are not in time order");
  if (!sorted_by_time(log.mag))
    return core::InvalidArgument(name + ": magnetometer samples are not in time order");
  if (!sorted_by_time(log.gnss)) return core::InvalidArgument(name + ": GNSS fixes are not in time order");
  for (size_t i = 1; i < log.frame_t_ns.size(); ++i) {
    if (log.frame_t_ns[i] <= log.frame_t_ns[i - 1]) {
      return core::InvalidArgument(name + ": frame timestamps are not in time order at frame " +
                                   std::to_string(i));
    }
  }
  if (!log.frame_t_ns.empty() && !log.load_frame) {
    return core::InvalidArgument(name + ": frames listed but no frame loader");
  }
  if (streams->config().frame_pool_size < 2) {
    return core::InvalidArgument("replay needs a frame pool of at least 2 frames");
  }
  std::unique_ptr<ReplaySource> src(new ReplaySource(std::move(log), streams));
  if (!src->log_.frame_t_ns.empty()) {
    src->prefetcher_ = std::thread([s = src.get()] { s->prefetch_loop(); });
  } else {
    src->prefetch_done_ = true;
  }
  return src;
}

ReplaySource::ReplaySource(ReplayLog log, SensorStreams* streams)
    : log_(std::move(log)), streams_(streams), ready_(streams->config().frame_pool_size) {}

ReplaySource::~ReplaySource() {
  stop_.store(true);
  if (prefetcher_.joinable()) prefetcher_.join();
  // Frames decoded but never delivered go back to the pool.
  Loaded l;
  while (ready_.try_pop(l)) streams_->frame_pool.release(l.frame);
}

void ReplaySource::prefetch_loop() {
  uint64_t failures = 0;
  for (size_t i = 0; i < log_.frame_t_ns.size() && !stop_.load(); ++i) {
    RgbdFrame* frame = nullptr;
    // The pool is the memory bound: wait for the pipeline to release a frame. The acquire and the
    // starved flag change together under the lock, so poll() never sees a stale "starved".
    while (!stop_.load()) {
      {
        std::lock_guard<std::mutex> lock(starve_mutex_);
        frame = streams_->frame_pool.acquire();
        prefetch_starved_ = (frame == nullptr);
      }
      if (frame != nullptr) break;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (frame == nullptr) break;
    Loaded l;
    l.frame = frame;
    l.index = i;
    core::Status st;
    try {
      st = log_.load_frame(i, frame);
    } catch (const std::exception& e) {
      // An exception must not escape this thread (std::terminate); it is a bad frame like any other.
      st = core::Internal(std::string("frame decoder threw: ") + e.what());
    }
    l.ok = st.ok();
    if (!l.ok) {
      // A bad frame degrades the run; it never stops it. Report the first few in full.
      if (++failures <= 3) HWR_LOG_WARN(kLog, "skipping frame %zu: %s", i, st.to_string().c_str());
    } else {
      frame->t_ns = log_.frame_t_ns[i];
    }
    // ready_ holds at most pool-size entries, and we own one pool frame per entry: never full.
    while (!ready_.try_push(l) && !stop_.load()) std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  prefetch_done_.store(true);
}

bool ReplaySource::prefetcher_blocked() {
  std::lock_guard<std::mutex> lock(starve_mutex_);
  return prefetch_starved_ && streams_->frame_pool.available() == 0;
}

core::Status ReplaySource::poll(int64_t until_ns, SensorStreams* streams) {
  // Frames belong to the pool of the streams given at create(); releasing into another is UB.
  assert(streams == streams_);
  for (; next_imu_ < log_.imu.size() && log_.imu[next_imu_].t_ns <= until_ns; ++next_imu_) {
    streams->imu.push_drop_oldest(log_.imu[next_imu_]);
    ++counters_.imu;
  }
  for (; next_mag_ < log_.mag.size() && log_.mag[next_mag_].t_ns <= until_ns; ++next_mag_) {
    streams->mag.push_drop_oldest(log_.mag[next_mag_]);
    ++counters_.mag;
  }
  for (; next_gnss_ < log_.gnss.size() && log_.gnss[next_gnss_].t_ns <= until_ns; ++next_gnss_) {
    streams->gnss.push_drop_oldest(log_.gnss[next_gnss_]);
    ++counters_.gnss;
  }
  while (next_frame_ < log_.frame_t_ns.size() && log_.frame_t_ns[next_frame_] <= until_ns) {
    Loaded l;
    // Deterministic replay: wait for the prefetcher unless it cannot make progress because the
    // pipeline holds every pool frame (then the frame comes on a later poll). Only this thread
    // and the pipeline, which runs on it too, release frames, so the test below is stable.
    bool got = ready_.try_pop(l);
    if (!got) {
      const auto wait_start = std::chrono::steady_clock::now();
      bool waited = false;
      while (!got && !prefetch_done_.load() && !prefetcher_blocked()) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));
        waited = true;
        got = ready_.try_pop(l);
      }
      if (waited) {
        ++counters_.decode_waits;
        counters_.decode_wait_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::steady_clock::now() - wait_start)
                                        .count();
      }
    }
    if (!got) got = ready_.try_pop(l);
    if (!got) break;
    ++next_frame_;
    if (!l.ok) {
      ++counters_.frame_errors;
      streams->frame_pool.release(l.frame);
      continue;
    }
    if (!streams->frames.try_push(l.frame)) {
      // The pipeline is behind: the newest frame is dropped, the queue keeps its order.
      ++counters_.frames_dropped;
      streams->frame_pool.release(l.frame);
      continue;
    }
    ++counters_.frames;
  }
  return core::Status::Ok();
}

bool ReplaySource::finished() const {
  return next_imu_ >= log_.imu.size() && next_mag_ >= log_.mag.size() && next_gnss_ >= log_.gnss.size() &&
         next_frame_ >= log_.frame_t_ns.size();
}

}  // namespace hwr::hal
