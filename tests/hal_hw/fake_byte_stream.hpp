#pragma once
// A scripted hal::hw::ByteStream for the serial readers' tests: each read returns the next scripted
// chunk (or error); writes are recorded and may trigger scripted replies (a receiver answering its
// configuration); reopen() pops the next scripted result.
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "hwr/hal/hw/byte_stream.hpp"

namespace hwr::hal::hw::test {

struct ScriptedRead {
  std::vector<uint8_t> bytes;
  core::Status error;  // non-OK: read_some returns it
};

class FakeByteStream final : public ByteStream {
 public:
  explicit FakeByteStream(std::string name = "/dev/fake") : name_(std::move(name)) {}

  std::deque<ScriptedRead> reads;    // consumed front first; empty → a timeout (0 bytes)
  std::deque<core::Status> reopens;  // empty → reopen succeeds
  std::vector<std::vector<uint8_t>> writes;
  // Called after each write with the written bytes: may append to reads (a device's reply).
  std::function<void(const std::vector<uint8_t>&, FakeByteStream*)> on_write;
  int reopen_calls = 0;

  core::Expected<size_t> read_some(uint8_t* buf, size_t cap, int /*timeout_ms*/) override {
    if (reads.empty()) return size_t{0};
    ScriptedRead& r = reads.front();
    if (!r.error.ok()) {
      core::Status st = r.error;
      reads.pop_front();
      return st;
    }
    const size_t n = std::min(cap, r.bytes.size());
    std::copy(r.bytes.begin(), r.bytes.begin() + static_cast<std::ptrdiff_t>(n), buf);
    r.bytes.erase(r.bytes.begin(), r.bytes.begin() + static_cast<std::ptrdiff_t>(n));
    if (r.bytes.empty()) reads.pop_front();
    return n;
  }
  core::Status write_all(const uint8_t* bytes, size_t n) override {
    writes.emplace_back(bytes, bytes + n);
    if (on_write) on_write(writes.back(), this);
    return core::Status::Ok();
  }
  core::Status reopen() override {
    ++reopen_calls;
    if (reopens.empty()) return core::Status::Ok();
    core::Status st = reopens.front();
    reopens.pop_front();
    return st;
  }
  const std::string& name() const override { return name_; }

 private:
  std::string name_;
};

}  // namespace hwr::hal::hw::test
