#pragma once
// Closed segments leave the mapping task through a SegmentSink. StoreSegmentWriter writes them to a
// MapStore on its own thread, so the scheduler loop never waits on the disk (ARCHITECTURE.md: no
// blocking I/O in the loop). At most `max_pending` segments wait; a further one makes take() wait
// for the writer (counted as a stall) rather than drop a segment. SegmentCollector keeps them in
// memory (tests, benches).

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "hwr/recon/local_mapper.hpp"
#include "hwr/recon/map_store.hpp"

namespace hwr::recon {

struct SegmentWriterCounters {
  uint64_t written = 0;
  uint64_t failed = 0;  // write_segment errors (logged)
  uint64_t stalls = 0;  // take() waited for a free slot
  uint64_t bytes_points = 0;
};

class StoreSegmentWriter final : public SegmentSink {
 public:
  StoreSegmentWriter(MapStore store, int max_pending = 2);
  ~StoreSegmentWriter() override;  // drains the queue, then joins
  StoreSegmentWriter(const StoreSegmentWriter&) = delete;
  StoreSegmentWriter& operator=(const StoreSegmentWriter&) = delete;

  void take(SegmentRecord&& segment) override;
  // Waits until every segment handed over so far is on disk.
  void drain();
  SegmentWriterCounters counters() const;
  const MapStore& store() const { return store_; }

 private:
  void run();
  MapStore store_;
  int max_pending_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<SegmentRecord> queue_;
  bool busy_ = false, stop_ = false;
  SegmentWriterCounters counters_;
  std::thread thread_;
};

class SegmentCollector final : public SegmentSink {
 public:
  void take(SegmentRecord&& segment) override { segments.push_back(std::move(segment)); }
  std::vector<SegmentRecord> segments;
};

}  // namespace hwr::recon
