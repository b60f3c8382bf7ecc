#include "hwr/recon/segment_writer.hpp"

#include "hwr/core/log.hpp"

namespace hwr::recon {

StoreSegmentWriter::StoreSegmentWriter(MapStore store, int max_pending)
    : store_(std::move(store)), max_pending_(max_pending < 1 ? 1 : max_pending) {
  thread_ = std::thread([this] { run(); });
}

StoreSegmentWriter::~StoreSegmentWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void StoreSegmentWriter::take(SegmentRecord&& segment) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (static_cast<int>(queue_.size()) >= max_pending_) {
    ++counters_.stalls;
    cv_.wait(lock, [&] { return static_cast<int>(queue_.size()) < max_pending_; });
  }
  queue_.push_back(std::move(segment));
  cv_.notify_all();
}

void StoreSegmentWriter::drain() {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait(lock, [&] { return queue_.empty() && !busy_; });
}

SegmentWriterCounters StoreSegmentWriter::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

void StoreSegmentWriter::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stop_ and nothing left
    SegmentRecord segment = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    cv_.notify_all();  // a waiting take() has room now
    lock.unlock();
    const core::Status st = store_.write_segment(segment);
    lock.lock();
    busy_ = false;
    if (st.ok()) {
      ++counters_.written;
      counters_.bytes_points += segment.points_segment.size() * sizeof(CloudPoint);
    } else {
      ++counters_.failed;
      HWR_LOG_ERROR("map-store", "segment %u not written: %s", segment.segment_id, st.message().c_str());
    }
    cv_.notify_all();
  }
}

}  // namespace hwr::recon
