// libFuzzer target: arbitrary bytes as a received HWR_MAP_ACK message, through the robot's handler
// (decode_ack_message, verify_ack with the ack's CRC32, ChunkSender::on_ack with a window of chunks
// in flight for the ack's own robot and run) and the ground's AckTracker (record / restore /
// make_ack of the values it carries; make_ack seals). Seeds: make_ack_seeds.cpp (sealed acks). A
// crash, a sanitizer report or a broken invariant is a finding.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "hwr/mapio/ack_tracker.hpp"
#include "hwr/mapio/chunk_sender.hpp"
#include "hwr/mapio/chunk_wire.hpp"

namespace {

constexpr int kChunks = 8;

hwr_lcm::map_chunk_t small_chunk(int i) {
  hwr_lcm::map_chunk_t c;  // LCM types leave their scalars uninitialized: set every field
  c.t_ns = 0;
  c.segment_id = 0;
  c.segment_version = 0;
  c.chunk_index = i;
  c.segment_complete = 0;
  c.chunk_count = i + 1;
  for (int k = 0; k < 12; ++k) c.T_world_segment[k] = (k % 5 == 0) ? 1.0 : 0.0;
  c.num_points = 1;
  c.has_normals = 0;
  c.max_position_error_m = 0.001f;
  c.payload.assign(16, static_cast<uint8_t>(i));
  return c;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static hwr_lcm::chunk_ack_t ack;
  static hwr_lcm::chunk_ack_t made;
  static hwr_lcm::chunk_ack_t resealed;
  static std::vector<uint8_t> again;
  const hwr::mapio::ChunkWireLimits limits;
  const hwr::core::Status decoded = hwr::mapio::decode_ack_message(data, size, &ack, limits);
  if (!decoded.ok()) {
    if (decoded.message().empty()) std::abort();
    return 0;
  }
  if (!hwr::mapio::encode_ack_message(ack, &again).ok()) std::abort();
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
  if (ack.selective.size() > static_cast<size_t>(limits.max_selective)) std::abort();
  const bool valid = hwr::mapio::verify_ack(ack, limits).ok();
  // An ack that verifies carries its own CRC; sealing it again changes nothing.
  if (valid && static_cast<int64_t>(hwr::mapio::ack_crc32(ack)) != ack.crc32) std::abort();
  if (valid) {
    resealed = ack;
    hwr::mapio::seal_ack(&resealed);
    if (resealed.crc32 != ack.crc32 || resealed.num_selective != ack.num_selective) std::abort();
  }

  // Robot side: the handler must hold its accounting whatever the ack says (it is given even
  // unverified acks: on_ack checks on its own what it relies on).
  hwr::mapio::LinkConfig config;
  config.window_chunks = kChunks;
  hwr::mapio::ChunkSender sender(ack.robot_id, ack.run_id, config);
  for (int i = 0; i < kChunks; ++i) {
    if (!sender.offer(small_chunk(i), 0)) std::abort();
  }
  int published = 0;
  sender.service(0, [&](const hwr_lcm::map_chunk_t&) { ++published; });
  if (published != kChunks) std::abort();
  sender.on_ack(ack, 1);
  const auto& st = sender.stats();
  if (st.in_flight < 0 || st.in_flight + st.acked != kChunks) std::abort();
  if (st.in_flight_bytes != static_cast<size_t>(st.in_flight) * 16u) std::abort();
  const bool accepted = st.acks == 1;  // same robot and run, only link_seqs it assigned
  if (accepted && ack.cumulative_seq == kChunks - 1 && !sender.idle()) std::abort();
  sender.service(10'000'000'000, [&](const hwr_lcm::map_chunk_t& c) {
    if (accepted && c.link_seq <= ack.cumulative_seq) std::abort();  // an acknowledged chunk came back
  });

  // Ground side: the ack's values as link_seqs.
  hwr::mapio::AckTracker tracker(ack.robot_id, ack.run_id, 256, 64);
  (void)tracker.record(ack.cumulative_seq);
  for (int64_t s : ack.selective) (void)tracker.record(s);
  tracker.make_ack(&made, ack.resume_report != 0);
  if (valid && !hwr::mapio::verify_ack(made, limits).ok()) std::abort();
  (void)tracker.restore(ack.selective);
  if (tracker.cumulative_seq() < -1 || tracker.num_recorded() > static_cast<int64_t>(ack.selective.size())) {
    std::abort();
  }
  return 0;
}
