#pragma once
// The ground station's durable chunk store (issue #5 item 4): every map chunk the link delivers,
// kept as received, so a restarted ground station knows what it already has (the ack tracker's
// restore) and rebuilds its maps without the robot resending. It keeps bytes, not points: it does not
// decode Draco. It checks each chunk's CRC32 (chunk_wire.hpp) on put() and again on reading it back.
//
// Layout under OUT_DIR:
//   OUT_DIR/.ground_store.lock                         flock(2): one GroundStore per folder
//   OUT_DIR/<robot_id>/<run_id>/seg_<SSSSSS>_v<V>/     one segment version (id zero-padded to 6)
//       chunk_<IIIIII>.drc    the Draco payload alone (Debian's draco_decoder reads it as is)
//       chunk_<IIIIII>.lcm    the whole hwr_lcm::map_chunk_t, LCM-encoded (with its fingerprint)
// robot_id matches [A-Za-z0-9_-]{1,64}; run_id is its decimal value (>= 0). OUT_DIR/<robot_id>/operator/
// and OUT_DIR/.operator_console.lock belong to the operator console (operator_console.hpp): the store
// leaves them alone.
//
// Atomicity: each file is written as FILE.tmp, fsync'ed and renamed (core::write_file_atomic), the
// .drc first, the .lcm last, then the folder is fsync'ed. A chunk counts as stored only when its .lcm exists,
// is at most kMaxStoredMessageBytes, decodes (chunk_wire's bounded decoder), matches its CRC32, and names the
// same robot/run/segment/version/index as its path. open() repairs what a crash at any moment can leave: it
// deletes *.tmp files and a .drc without its .lcm, renames an .lcm that does not decode to .lcm.corrupt (kept
// for inspection, never counted), and rewrites a .drc that is missing or differs from its .lcm's payload.
// OpenReport says what it did.
//
// Not thread-safe; one writer process per OUT_DIR (the lock file enforces it).

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr_lcm/map_chunk_t.hpp"

namespace hwr::mapio {

class GroundStore {
 public:
  // A stored .lcm larger than this is corrupt (a link chunk is <= 1 MiB; issue #5 item 2).
  static constexpr int64_t kMaxStoredMessageBytes = int64_t{64} << 20;

  struct OpenReport {
    int64_t chunks_loaded = 0;
    int64_t temp_files_removed = 0;     // *.tmp of an interrupted write
    int64_t lone_payloads_removed = 0;  // .drc whose .lcm was never written
    int64_t corrupt_quarantined = 0;    // .lcm renamed to .lcm.corrupt
    int64_t payloads_rewritten = 0;     // .drc missing or different from its .lcm's payload
    std::vector<std::string> notes;     // one line per finding above, and per entry ignored
  };

  struct SegmentInfo {
    int32_t segment_id = 0, version = 0;
    int32_t chunks_stored = 0;
    // The final count once the segment_complete chunk is stored, else the largest count seen so far.
    int32_t chunk_count = 0;
    bool complete = false;  // the segment_complete chunk and every chunk 0..chunk_count-1 are stored
    // From the stored chunk with the highest chunk_index (the sender's latest estimate); 3x4 [R | t]
    // row by row, metres.
    double T_world_segment[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    int64_t points_stored = 0;         // sum of num_points over the stored chunks
    int64_t payload_bytes_stored = 0;  // sum of payload_size over the stored chunks
  };

  // Creates OUT_DIR if needed, takes its lock (kUnavailable while another GroundStore holds it),
  // scans and repairs what is there (see above). kIoError when a folder cannot be created or read.
  static core::Expected<GroundStore> open(const std::string& out_dir);

  GroundStore(GroundStore&&) noexcept;
  GroundStore& operator=(GroundStore&&) noexcept;
  ~GroundStore();

  // Stores a chunk durably. The same chunk again (same robot, run, link_seq, place and CRC) is OK and
  // writes nothing (*was_new = false). kInvalidArgument for a malformed message (bad robot_id,
  // negative ids or counts, payload_size != payload.size(), a complete chunk with chunk_index >=
  // chunk_count, over kMaxStoredMessageBytes) or one that conflicts with what is stored (its link_seq
  // or its place already holds another chunk); kCorruptData when crc32 does not match
  // (chunk_wire.hpp: seal_chunk / verify_chunk); kIoError when a write fails.
  core::Status put(const hwr_lcm::map_chunk_t& chunk, bool* was_new = nullptr);

  bool has(const std::string& robot_id, int64_t run_id, int64_t link_seq) const;
  // Ascending; what the ack tracker restores after a restart.
  std::vector<int64_t> stored_link_seqs(const std::string& robot_id, int64_t run_id) const;
  // (robot_id, run_id) pairs with at least one stored chunk, sorted.
  std::vector<std::pair<std::string, int64_t>> runs() const;
  // Sorted by (segment_id, version).
  std::vector<SegmentInfo> segments(const std::string& robot_id, int64_t run_id) const;
  int64_t chunks_stored() const;

  // Everything stored for one segment version, ordered by chunk_index, read back from disk and
  // validated. kNotFound when nothing is stored for it, kCorruptData when a file changed under us.
  core::Status load_segment(const std::string& robot_id, int64_t run_id, int32_t segment_id, int32_t version,
                            std::vector<hwr_lcm::map_chunk_t>* out) const;

  // Paths of one chunk's files (whether or not they exist), e.g. for draco_decoder.
  std::string lcm_path(const std::string& robot_id, int64_t run_id, int32_t segment_id, int32_t version,
                       int32_t chunk_index) const;
  std::string drc_path(const std::string& robot_id, int64_t run_id, int32_t segment_id, int32_t version,
                       int32_t chunk_index) const;

  const std::string& out_dir() const;
  const OpenReport& open_report() const;

  // kInvalidArgument unless robot_id matches [A-Za-z0-9_-]{1,64} (it becomes a folder name).
  static core::Status validate_robot_id(const std::string& robot_id);

 private:
  struct State;
  explicit GroundStore(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace hwr::mapio
