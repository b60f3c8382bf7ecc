#include "hwr/mapio/chunk_sender.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <utility>

#include "hwr/mapio/chunk_wire.hpp"

namespace hwr::mapio {

ChunkSender::ChunkSender(const std::string& robot_id, int64_t run_id, LinkConfig config)
    : robot_id_(robot_id), run_id_(run_id), config_(config) {
  assert(config_.window_chunks >= 1 && config_.window_bytes >= 1);
  assert(config_.initial_rto_ns > 0 && config_.initial_rto_ns <= config_.max_rto_ns);
  assert(config_.rto_backoff >= 1.0 && config_.max_sends_per_service >= 1);
  slots_.resize(static_cast<size_t>(config_.window_chunks));
  due_.reserve(static_cast<size_t>(config_.window_chunks));
  ack_scratch_.reserve(256);
}

bool ChunkSender::can_accept(size_t payload_bytes) const {
  return stats_.in_flight < config_.window_chunks && payload_bytes <= config_.window_bytes &&
         stats_.in_flight_bytes <= config_.window_bytes - payload_bytes;
}

bool ChunkSender::offer(hwr_lcm::map_chunk_t&& chunk, int64_t now_ns) {
  if (!can_accept(chunk.payload.size())) {
    ++stats_.window_full_refusals;
    return false;
  }
  const auto it = std::find_if(slots_.begin(), slots_.end(), [](const Slot& s) { return !s.used; });
  assert(it != slots_.end());  // in_flight < window_chunks
  Slot& slot = *it;
  slot.used = true;
  slot.sends = 0;
  slot.due_ns = now_ns;  // publish at the next service()
  slot.rto_ns = config_.initial_rto_ns;
  slot.last_send_ns = now_ns;
  slot.chunk = std::move(chunk);
  slot.chunk.robot_id = robot_id_;
  slot.chunk.run_id = run_id_;
  slot.chunk.link_seq = next_seq_++;
  seal_chunk(&slot.chunk);

  ++stats_.in_flight;
  stats_.in_flight_bytes += slot.chunk.payload.size();
  stats_.max_in_flight = std::max(stats_.max_in_flight, stats_.in_flight);
  stats_.max_in_flight_bytes = std::max(stats_.max_in_flight_bytes, stats_.in_flight_bytes);
  return true;
}

int ChunkSender::collect_due(int64_t now_ns) {
  due_.clear();
  for (size_t i = 0; i < slots_.size(); ++i) {
    if (slots_[i].used && slots_[i].due_ns <= now_ns) due_.push_back(static_cast<int>(i));
  }
  // Oldest first: a resend of an old chunk goes before new chunks, so the ground's cumulative ack
  // (and the window) advance.
  std::sort(due_.begin(), due_.end(), [this](int a, int b) {
    return slots_[size_t(a)].chunk.link_seq < slots_[size_t(b)].chunk.link_seq;
  });
  const int n = std::min(static_cast<int>(due_.size()), config_.max_sends_per_service);
  due_.resize(static_cast<size_t>(n));
  return n;
}

void ChunkSender::prepare_send(int slot_index, int64_t now_ns) {
  Slot& slot = slots_[static_cast<size_t>(slot_index)];
  if (slot.sends == 0) slot.chunk.t_ns = now_ns;  // first send; t_ns is outside the CRC
}

void ChunkSender::mark_sent(int slot_index, int64_t now_ns) {
  Slot& slot = slots_[static_cast<size_t>(slot_index)];
  if (slot.sends == 0) {
    ++stats_.sends;
    slot.rto_ns = config_.initial_rto_ns;
  } else {
    ++stats_.resends;
    // Exponential backoff (RFC 6298 5.5), capped.
    const double next = static_cast<double>(slot.rto_ns) * config_.rto_backoff;
    slot.rto_ns =
        next >= static_cast<double>(config_.max_rto_ns) ? config_.max_rto_ns : static_cast<int64_t>(next);
  }
  ++slot.sends;
  slot.last_send_ns = now_ns;
  slot.due_ns = now_ns + slot.rto_ns;
  stats_.max_rto_seen_ns = std::max(stats_.max_rto_seen_ns, slot.rto_ns);
}

void ChunkSender::release(int slot_index) {
  Slot& slot = slots_[static_cast<size_t>(slot_index)];
  assert(slot.used);
  slot.used = false;
  --stats_.in_flight;
  stats_.in_flight_bytes -= slot.chunk.payload.size();
  ++stats_.acked;
  // The payload counted against window_bytes: free it with the slot.
  slot.chunk.payload = {};
}

void ChunkSender::on_ack(const hwr_lcm::chunk_ack_t& ack, int64_t now_ns) {
  if (ack.robot_id != robot_id_ || ack.run_id != run_id_) {
    ++stats_.foreign_acks;
    return;
  }
  // Only link_seq values this sender assigned can be acknowledged.
  bool valid = ack.cumulative_seq >= -1 && ack.cumulative_seq < next_seq_ && ack.num_selective >= 0 &&
               static_cast<size_t>(ack.num_selective) == ack.selective.size();
  for (size_t i = 0; valid && i < ack.selective.size(); ++i) {
    valid = ack.selective[i] >= 0 && ack.selective[i] < next_seq_;
  }
  if (!valid) {
    ++stats_.invalid_acks;
    return;
  }
  ++stats_.acks;
  ack_scratch_.assign(ack.selective.begin(), ack.selective.end());
  std::sort(ack_scratch_.begin(), ack_scratch_.end());

  bool progress = false;
  for (size_t i = 0; i < slots_.size(); ++i) {
    if (!slots_[i].used) continue;
    const int64_t seq = slots_[i].chunk.link_seq;
    if (seq <= ack.cumulative_seq || std::binary_search(ack_scratch_.begin(), ack_scratch_.end(), seq)) {
      release(static_cast<int>(i));
      progress = true;
    }
  }

  if (ack.resume_report != 0) {
    // A restarted ground station listed what it has; whatever it lacks is due now.
    ++stats_.resume_reports;
    for (Slot& slot : slots_) {
      if (!slot.used || slot.sends == 0) continue;
      slot.rto_ns = config_.initial_rto_ns;
      slot.due_ns = now_ns;
    }
  } else if (progress) {
    // The link delivers again: forget the backoff of the chunks still outstanding.
    for (Slot& slot : slots_) {
      if (!slot.used || slot.sends == 0) continue;
      slot.rto_ns = config_.initial_rto_ns;
      slot.due_ns = std::min(slot.due_ns, slot.last_send_ns + config_.initial_rto_ns);
    }
  }
}

int64_t ChunkSender::next_due_ns() const {
  int64_t t = std::numeric_limits<int64_t>::max();
  for (const Slot& slot : slots_) {
    if (slot.used) t = std::min(t, slot.due_ns);
  }
  return t;
}

}  // namespace hwr::mapio
