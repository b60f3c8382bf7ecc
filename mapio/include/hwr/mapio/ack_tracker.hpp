#pragma once
// The ground side of the reliable chunk link (issue #5 item 3): which link_seq values of one
// (robot_id, run_id) are stored, summarized as the chunk_ack_t the robot's ChunkSender reads.
//
// State: cumulative_seq (every link_seq <= it is stored; -1: none) and a ring bitmap over the
// window [cumulative_seq + 1, cumulative_seq + capacity]. Memory is fixed at construction
// (capacity bits) whatever the run's length; record() and make_ack() do not allocate (make_ack
// reuses the ack's vector capacity).
// A link_seq beyond the window is refused, not recorded: the ground station must then not store the
// chunk, and the sender, seeing no ack, resends it later, by when the window has moved. The sender
// holds at most window_chunks chunks, but they can span more link_seqs than that when an old chunk
// keeps getting lost, so capacity should be well above LinkConfig::window_chunks (default 65536).
//
// Ground-station order for a received, verified chunk (so an ack never claims a chunk the disk
// lacks): classify() == kNew -> store durably -> record() -> send make_ack(). A duplicate (kStored)
// is not stored again but still acknowledged: the sender resent it because an ack was lost.
// After a restart: restore() from the seqs found on disk, then send make_ack(resume_report = true).

#include <cstdint>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/chunk_ack_t.hpp"

namespace hwr::mapio {

class AckTracker {
 public:
  enum class SeqClass {
    kNew,           // in the window and not recorded: store it, then record()
    kStored,        // already recorded: a duplicate, ignore (but acknowledge)
    kBeyondWindow,  // > cumulative_seq + capacity: refused for now, the sender will resend
    kInvalid,       // negative
  };

  // capacity: window size in link_seqs (>= 64, rounded up to a multiple of 64); max_selective: the
  // most selective values one ack lists (the lowest stored ones above cumulative_seq; >= 0).
  AckTracker(std::string robot_id, int64_t run_id, int capacity = 1 << 16, int max_selective = 256);

  SeqClass classify(int64_t link_seq) const;
  // Records link_seq; true when it was kNew, false otherwise (nothing changes).
  bool record(int64_t link_seq);
  // cumulative_seq, up to max_selective stored seqs above it (ascending), robot_id, run_id,
  // resume_report, sealed (seal_ack: num_selective and crc32); t_ns is left 0 for the caller to
  // stamp (it is outside the CRC).
  void make_ack(hwr_lcm::chunk_ack_t* ack, bool resume_report) const;

  // Forgets everything, then records link_seqs found on disk (any order, duplicates allowed).
  // Values that cannot be recorded are skipped and reported: kInvalidArgument for negative ones,
  // kOutOfRange for ones beyond the window (the sender resends those; the store's put is
  // idempotent). The state holds every recordable value in either case.
  core::Status restore(const std::vector<int64_t>& stored_link_seqs);

  int64_t cumulative_seq() const { return cumulative_; }
  int64_t highest_recorded() const { return highest_; }  // -1 when nothing
  int64_t num_recorded() const { return num_recorded_; }
  int capacity() const { return capacity_; }
  const std::string& robot_id() const { return robot_id_; }
  int64_t run_id() const { return run_id_; }

 private:
  bool bit(int64_t seq) const;
  void set_bit(int64_t seq);
  void clear_bit(int64_t seq);
  void reset();

  std::string robot_id_;
  int64_t run_id_;
  int capacity_;
  int max_selective_;
  int64_t cumulative_ = -1;
  int64_t highest_ = -1;
  int64_t num_recorded_ = 0;
  std::vector<uint64_t> bits_;  // bit (seq mod capacity): seq in the window is recorded
};

}  // namespace hwr::mapio
