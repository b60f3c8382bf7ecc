#pragma once
// Test helper: an in-memory, simulated-time message link that misbehaves on purpose, for the
// reliable chunk link tests (issue #5 acceptance: loss, reordering, duplication, a link cut).
// Each FaultChannel is one direction; FaultLink pairs two. Messages are byte strings (LCM-encoded),
// so the receiving side goes through the real decoder. Deterministic for a given seed.
//
// A message sent at t is, in this order:
//   dropped when t is in the cut window [cut_begin_ns, cut_end_ns);
//   put on the wire after the messages before it when rate_bytes_per_s > 0 (a bandwidth-limited
//   link with an unbounded send queue: t becomes the end of its transmission);
//   dropped with probability loss;
//   otherwise delivered at t + latency_ns, plus, with probability reorder, a uniform extra delay in
//   [0, reorder_max_delay_ns] (so later messages overtake it);
//   with probability duplicate, a second copy is scheduled with its own delay;
//   with probability corrupt, one random bit of a copy is flipped (the CRC must catch it);
//   a copy whose delivery time falls in the cut window is dropped too (it was on the wire).

#include <algorithm>
#include <cstdint>
#include <queue>
#include <random>
#include <utility>
#include <vector>

namespace hwr::mapio::test {

struct FaultConfig {
  int64_t latency_ns = 2'000'000;
  double rate_bytes_per_s = 0;  // > 0: messages are serialized onto the wire one after another
  double loss = 0.0;            // probability a message is dropped
  double reorder = 0.0;         // probability a copy gets an extra delay
  int64_t reorder_max_delay_ns = 30'000'000;
  double duplicate = 0.0;  // probability a message is delivered twice
  double corrupt = 0.0;    // probability a delivered copy has one bit flipped
  int64_t cut_begin_ns = 0;
  int64_t cut_end_ns = 0;  // empty window: no cut
};

struct FaultStats {
  int64_t sent = 0;
  int64_t lost = 0;  // random loss
  int64_t cut = 0;   // dropped by the cut window (at send or on the wire)
  int64_t duplicated = 0;
  int64_t reordered = 0;
  int64_t corrupted = 0;
  int64_t delivered = 0;
};

class FaultChannel {
 public:
  FaultChannel(FaultConfig config, uint64_t seed) : config_(config), rng_(seed) {}

  void send(const std::vector<uint8_t>& bytes, int64_t now_ns) {
    ++stats_.sent;
    if (in_cut(now_ns)) {
      ++stats_.cut;
      return;
    }
    int64_t t_ns = now_ns;
    if (config_.rate_bytes_per_s > 0) {
      const auto wire_ns =
          static_cast<int64_t>(static_cast<double>(bytes.size()) * 1e9 / config_.rate_bytes_per_s);
      wire_free_ns_ = std::max(wire_free_ns_, now_ns) + wire_ns;
      t_ns = wire_free_ns_;
    }
    if (chance(config_.loss)) {
      ++stats_.lost;
      return;
    }
    schedule(bytes, t_ns);
    if (chance(config_.duplicate)) {
      ++stats_.duplicated;
      schedule(bytes, t_ns);
    }
  }

  // Moves every message due at or before now_ns into `out` (cleared), in delivery order.
  void poll(int64_t now_ns, std::vector<std::vector<uint8_t>>* out) {
    out->clear();
    while (!queue_.empty() && queue_.top().deliver_ns <= now_ns) {
      // Moving out of top() is safe: pop() only compares the int keys, which a move leaves intact.
      Pending p = std::move(const_cast<Pending&>(queue_.top()));
      queue_.pop();
      if (in_cut(p.deliver_ns)) {
        ++stats_.cut;
        continue;
      }
      ++stats_.delivered;
      out->push_back(std::move(p.bytes));
    }
  }

  bool empty() const { return queue_.empty(); }
  const FaultStats& stats() const { return stats_; }
  const FaultConfig& config() const { return config_; }

 private:
  struct Pending {
    int64_t deliver_ns;
    uint64_t order;  // FIFO among equal delivery times
    std::vector<uint8_t> bytes;
  };
  struct Later {
    bool operator()(const Pending& a, const Pending& b) const {
      return a.deliver_ns != b.deliver_ns ? a.deliver_ns > b.deliver_ns : a.order > b.order;
    }
  };

  bool in_cut(int64_t t_ns) const { return t_ns >= config_.cut_begin_ns && t_ns < config_.cut_end_ns; }
  bool chance(double p) { return p > 0 && std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < p; }

  void schedule(const std::vector<uint8_t>& bytes, int64_t now_ns) {
    Pending p{now_ns + config_.latency_ns, next_order_++, bytes};
    if (chance(config_.reorder)) {
      ++stats_.reordered;
      p.deliver_ns += std::uniform_int_distribution<int64_t>(0, config_.reorder_max_delay_ns)(rng_);
    }
    if (!p.bytes.empty() && chance(config_.corrupt)) {
      ++stats_.corrupted;
      const auto bit = std::uniform_int_distribution<size_t>(0, p.bytes.size() * 8 - 1)(rng_);
      p.bytes[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    }
    queue_.push(std::move(p));
  }

  FaultConfig config_;
  std::mt19937_64 rng_;
  std::priority_queue<Pending, std::vector<Pending>, Later> queue_;
  uint64_t next_order_ = 0;
  int64_t wire_free_ns_ = 0;
  FaultStats stats_;
};

// Both directions of a link: up = robot -> ground (chunks), down = ground -> robot (acks).
struct FaultLink {
  FaultLink(const FaultConfig& up_config, const FaultConfig& down_config, uint64_t seed)
      : up(up_config, seed * 2 + 1), down(down_config, seed * 2 + 2) {}
  FaultChannel up;
  FaultChannel down;
};

}  // namespace hwr::mapio::test
