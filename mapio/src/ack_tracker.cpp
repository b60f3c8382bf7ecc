#include "hwr/mapio/ack_tracker.hpp"

#include <algorithm>
#include <cassert>
#include <utility>

#include "hwr/mapio/chunk_wire.hpp"

namespace hwr::mapio {

AckTracker::AckTracker(std::string robot_id, int64_t run_id, int capacity, int max_selective)
    : robot_id_(std::move(robot_id)),
      run_id_(run_id),
      capacity_(((std::max(capacity, 64) + 63) / 64) * 64),
      max_selective_(std::max(max_selective, 0)) {
  bits_.assign(static_cast<size_t>(capacity_ / 64), 0);
}

bool AckTracker::bit(int64_t seq) const {
  const auto i = static_cast<uint64_t>(seq) % static_cast<uint64_t>(capacity_);
  return (bits_[i / 64] >> (i % 64)) & 1u;
}

void AckTracker::set_bit(int64_t seq) {
  const auto i = static_cast<uint64_t>(seq) % static_cast<uint64_t>(capacity_);
  bits_[i / 64] |= uint64_t{1} << (i % 64);
}

void AckTracker::clear_bit(int64_t seq) {
  const auto i = static_cast<uint64_t>(seq) % static_cast<uint64_t>(capacity_);
  bits_[i / 64] &= ~(uint64_t{1} << (i % 64));
}

AckTracker::SeqClass AckTracker::classify(int64_t link_seq) const {
  if (link_seq < 0) return SeqClass::kInvalid;
  if (link_seq <= cumulative_) return SeqClass::kStored;
  // link_seq >= cumulative_ + 1 >= 0 here, so the difference cannot overflow (link_seq may be huge).
  if (link_seq - (cumulative_ + 1) >= capacity_) return SeqClass::kBeyondWindow;
  return bit(link_seq) ? SeqClass::kStored : SeqClass::kNew;
}

bool AckTracker::record(int64_t link_seq) {
  if (classify(link_seq) != SeqClass::kNew) return false;
  set_bit(link_seq);
  ++num_recorded_;
  highest_ = std::max(highest_, link_seq);
  // Advance over the contiguous prefix; clearing each bit passed keeps the ring clean for the
  // seqs (cumulative + capacity) that will reuse those positions.
  while (cumulative_ + 1 <= highest_ && bit(cumulative_ + 1)) {
    clear_bit(cumulative_ + 1);
    ++cumulative_;
  }
  return true;
}

void AckTracker::make_ack(hwr_lcm::chunk_ack_t* ack, bool resume_report) const {
  ack->t_ns = 0;
  ack->robot_id = robot_id_;
  ack->run_id = run_id_;
  ack->cumulative_seq = cumulative_;
  ack->resume_report = resume_report ? 1 : 0;
  ack->selective.clear();
  // Every bit set lies in (cumulative_, highest_]; scan word by word.
  for (int64_t seq = cumulative_ + 1;
       seq <= highest_ && static_cast<int>(ack->selective.size()) < max_selective_;) {
    const auto i = static_cast<uint64_t>(seq) % static_cast<uint64_t>(capacity_);
    const uint64_t word = bits_[i / 64] >> (i % 64);
    if (word == 0) {
      seq += static_cast<int64_t>(64 - i % 64);  // rest of this word is empty
      continue;
    }
    const int skip = __builtin_ctzll(word);
    seq += skip;
    if (seq <= highest_) ack->selective.push_back(seq);
    ++seq;
  }
  seal_ack(ack);  // num_selective and the CRC32 (t_ns is outside it: the caller stamps it later)
}

void AckTracker::reset() {
  std::fill(bits_.begin(), bits_.end(), 0);
  cumulative_ = -1;
  highest_ = -1;
  num_recorded_ = 0;
}

core::Status AckTracker::restore(const std::vector<int64_t>& stored_link_seqs) {
  reset();
  std::vector<int64_t> seqs(stored_link_seqs);
  std::sort(seqs.begin(), seqs.end());
  seqs.erase(std::unique(seqs.begin(), seqs.end()), seqs.end());
  // Ascending order: the cumulative prefix advances as far as the stored seqs allow before the
  // window bound is applied to the rest.
  int64_t negative = 0, beyond = 0, first_beyond = -1;
  for (int64_t seq : seqs) {
    switch (classify(seq)) {
      case SeqClass::kNew:
        record(seq);
        break;
      case SeqClass::kInvalid:
        ++negative;
        break;
      case SeqClass::kBeyondWindow:
        if (beyond++ == 0) first_beyond = seq;
        break;
      case SeqClass::kStored:
        break;
    }
  }
  if (negative > 0) {
    return core::InvalidArgument("ack tracker restore (" + robot_id_ + " run " + std::to_string(run_id_) +
                                 "): skipped " + std::to_string(negative) + " negative link_seq values");
  }
  if (beyond > 0) {
    return core::OutOfRange("ack tracker restore (" + robot_id_ + " run " + std::to_string(run_id_) +
                            "): " + std::to_string(beyond) + " stored link_seq values from " +
                            std::to_string(first_beyond) + " lie beyond the window (cumulative " +
                            std::to_string(cumulative_) + " + capacity " + std::to_string(capacity_) +
                            "); not restored, the sender will resend them");
  }
  return core::Status::Ok();
}

}  // namespace hwr::mapio
