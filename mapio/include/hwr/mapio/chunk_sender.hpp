#pragma once
// The robot side of the reliable chunk link (issue #5 item 3): a bounded send window of map chunks,
// each resent on its own retransmission timer until the ground station acknowledges it.
//
// Protocol (docs/mapio.md; wire rules in chunk_wire.hpp):
//  - offer() numbers a chunk with the next link_seq of this (robot_id, run_id), 0, 1, 2, ..., stamps
//    the ids and seals it (CRC32). The window holds at most window_chunks chunks and window_bytes
//    payload bytes not yet acknowledged; offer() refuses a chunk that does not fit (back-pressure:
//    the mapper keeps it and offers it again later).
//  - service() publishes, in link_seq order, every chunk that was never sent and every chunk whose
//    retransmission timer expired, at most max_sends_per_service per call. A chunk's timer starts at
//    initial_rto_ns when first sent and is multiplied by rto_backoff (capped at max_rto_ns) on each
//    resend (exponential backoff, as TCP, RFC 6298 section 5.5).
//  - on_ack(): cumulative_seq frees every chunk with link_seq <= it, selective frees those listed.
//    When an ack frees anything (progress: the link works again) every remaining chunk's timer is
//    reset to initial_rto_ns counted from its last send, so chunks lost during an outage go out
//    again at once instead of waiting out a long backed-off timer. A resume_report (a restarted
//    ground station telling what it has stored) rewinds: every chunk it does not list is due now.
//  - Acks of another robot or run are ignored; an ack naming a link_seq never assigned is ignored
//    as invalid (it can only come from a confused or hostile peer).
// Time is explicit (now_ns, any monotonic clock): no threads, no sleeping, deterministic. Memory:
// window_chunks slots sized at construction; chunks are moved in and out, so offer/service/on_ack
// do not allocate except to grow the ack scratch to the largest selective list seen.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hwr_lcm/chunk_ack_t.hpp"
#include "hwr_lcm/map_chunk_t.hpp"

namespace hwr::mapio {

struct LinkConfig {
  int window_chunks = 64;                // chunks in flight (sent or queued, not yet acknowledged)
  size_t window_bytes = 16u << 20;       // their payload bytes; a chunk larger than this is never accepted
  int64_t initial_rto_ns = 200'000'000;  // first retransmission timeout; > the link's round trip
  double rto_backoff = 2.0;              // timeout multiplier per resend (>= 1)
  int64_t max_rto_ns = 5'000'000'000;    // backoff cap
  int max_sends_per_service = 32;        // publications per service() call (bounds one call's work)
};

class ChunkSender {
 public:
  struct Stats {
    int64_t sends = 0;    // first publications
    int64_t resends = 0;  // publications after a timeout or a rewind
    int64_t acked = 0;    // chunks freed by acknowledgements
    int in_flight = 0;    // chunks in the window now
    size_t in_flight_bytes = 0;
    int max_in_flight = 0;  // high-water marks since construction
    size_t max_in_flight_bytes = 0;
    int64_t max_rto_seen_ns = 0;
    int64_t window_full_refusals = 0;  // offer() returned false
    int64_t acks = 0;                  // acks of this robot and run processed
    int64_t foreign_acks = 0;          // ignored: another robot or run
    int64_t invalid_acks = 0;          // ignored: a link_seq never assigned, or malformed
    int64_t resume_reports = 0;
  };

  // config must be sane: window_chunks >= 1, window_bytes >= 1, 0 < initial_rto_ns <= max_rto_ns,
  // rto_backoff >= 1, max_sends_per_service >= 1 (asserted).
  ChunkSender(const std::string& robot_id, int64_t run_id, LinkConfig config = {});

  // True when a chunk of payload_bytes fits in the window now (chunks and bytes).
  bool can_accept(size_t payload_bytes) const;
  // Takes the chunk (segment fields, num_points, has_normals, max_position_error_m, T_world_segment,
  // payload filled by the caller: LCM types leave scalars uninitialized, so set every one),
  // assigns link_seq, robot_id, run_id, payload_size and seals it; it is published at the next
  // service(). Returns false and leaves `chunk` untouched when the window is full.
  bool offer(hwr_lcm::map_chunk_t&& chunk, int64_t now_ns);

  // Publishes due chunks (see above) through publish(const hwr_lcm::map_chunk_t&), which must not
  // call back into this sender. t_ns is stamped at the first send and kept by resends (not in the
  // CRC). Returns how many were published.
  template <class Publish>
  int service(int64_t now_ns, Publish&& publish) {
    const int n = collect_due(now_ns);
    for (int i = 0; i < n; ++i) {
      const int slot = due_[static_cast<size_t>(i)];
      prepare_send(slot, now_ns);
      publish(static_cast<const hwr_lcm::map_chunk_t&>(slots_[static_cast<size_t>(slot)].chunk));
      mark_sent(slot, now_ns);
    }
    return n;
  }

  void on_ack(const hwr_lcm::chunk_ack_t& ack, int64_t now_ns);

  bool idle() const { return stats_.in_flight == 0; }
  // Earliest time a chunk becomes due (the caller may sleep until then); INT64_MAX when idle.
  int64_t next_due_ns() const;
  // The link_seq the next offered chunk gets.
  int64_t next_link_seq() const { return next_seq_; }
  const Stats& stats() const { return stats_; }
  const std::string& robot_id() const { return robot_id_; }
  int64_t run_id() const { return run_id_; }

 private:
  struct Slot {
    bool used = false;
    int sends = 0;  // publications so far
    int64_t due_ns = 0;
    int64_t rto_ns = 0;
    int64_t last_send_ns = 0;
    hwr_lcm::map_chunk_t chunk;
  };

  int collect_due(int64_t now_ns);  // fills due_ (slot indices in link_seq order), returns the count
  void prepare_send(int slot, int64_t now_ns);
  void mark_sent(int slot, int64_t now_ns);
  void release(int slot);

  std::string robot_id_;
  int64_t run_id_;
  LinkConfig config_;
  int64_t next_seq_ = 0;
  std::vector<Slot> slots_;
  std::vector<int> due_;
  std::vector<int64_t> ack_scratch_;
  Stats stats_;
};

}  // namespace hwr::mapio
