#include "hwr/hal/hw/a9_reader.hpp"

#include <variant>

#include "hwr/core/log.hpp"

namespace hwr::hal::hw {

A9Reader::A9Reader(std::unique_ptr<ByteStream> port, core::SpscRing<ImuSample>* imu_out)
    : port_(std::move(port)), imu_out_(imu_out) {}

core::Status A9Reader::step(int64_t now_ns, int read_timeout_ms) {
  if (!connected_.load(std::memory_order_relaxed)) {
    if (!backoff_.due(now_ns)) {
      backoff_.wait_until_due(now_ns, read_timeout_ms);
      return core::Status::Ok();
    }
    if (core::Status st = port_->reopen(); !st.ok()) {
      backoff_.failed(now_ns);
      return st.code() == core::ErrorCode::kUnavailable || st.code() == core::ErrorCode::kNotFound ||
                     st.code() == core::ErrorCode::kIoError
                 ? core::Status::Ok()
                 : st;
    }
    backoff_.succeeded();
    // A replugged A9 restarts its clock and its byte stream: start both over.
    parser_.reset();  // its counters carry on (the buffered bytes count as discarded)
    unwrap_.reset();
    clock_.reset();
    connected_.store(true, std::memory_order_relaxed);
    reconnects_.fetch_add(1, std::memory_order_relaxed);
    HWR_LOG_INFO("a9", "%s: reconnected", port_->name().c_str());
  }
  auto n = port_->read_some(buf_.data(), buf_.size(), read_timeout_ms);
  if (!n.ok()) {
    if (n.status().code() != core::ErrorCode::kUnavailable &&
        n.status().code() != core::ErrorCode::kIoError) {
      return n.status();
    }
    connected_.store(false, std::memory_order_relaxed);
    disconnects_.fetch_add(1, std::memory_order_relaxed);
    backoff_.failed(now_ns);
    HWR_LOG_WARN("a9", "%s: %s; reconnecting", port_->name().c_str(), n.status().message().c_str());
    return core::Status::Ok();
  }
  parser_.push(buf_.data(), n.value(), [&](const A9Packet& packet) {
    if (const auto* imu = std::get_if<A9ImuPacket>(&packet)) {
      const int64_t t_device_ns = unwrap_.unwrap_us(imu->t_us) * 1000;
      const int64_t t_ns = clock_.map(t_device_ns, now_ns);
      imu_out_->push_drop_oldest(to_imu_sample(*imu, t_ns));
      samples_.fetch_add(1, std::memory_order_relaxed);
    } else {
      attitude_.fetch_add(1, std::memory_order_relaxed);
    }
  });
  crc_errors_.store(parser_.counters().crc_errors, std::memory_order_relaxed);
  bytes_discarded_.store(parser_.counters().bytes_discarded, std::memory_order_relaxed);
  return core::Status::Ok();
}

A9ReaderCounters A9Reader::counters() const {
  A9ReaderCounters c;
  c.samples = samples_.load(std::memory_order_relaxed);
  c.attitude = attitude_.load(std::memory_order_relaxed);
  c.disconnects = disconnects_.load(std::memory_order_relaxed);
  c.reconnects = reconnects_.load(std::memory_order_relaxed);
  c.crc_errors = crc_errors_.load(std::memory_order_relaxed);
  c.bytes_discarded = bytes_discarded_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace hwr::hal::hw
