#pragma once
// One map transfer of `hwr-bench transfer` (issue #5, paper Table II): a MapStreamer (the robot) and
// a GroundStation on its own thread (the ground, hwr-ground's loop) talk over an LCM URL; the bench
// submits a map's batches either all at the stop (direct) or on the mapping timeline (streamed), and
// measures when the last point is stored on the ground, the bytes the link carried, and how far the
// stored points are from the submitted ones.

#include <cstdint>
#include <functional>
#include <string>

#include "hwr/mapio/map_streamer.hpp"
#include "transfer_bench_stream.hpp"

namespace hwr::bench {

enum class TransferMode {
  kDirect,    // the robot stops, then the whole map is encoded and sent (the paper's "direct")
  kStreamed,  // batches submitted as the mapper produced them; the robot stops after the last one
};

struct TransferSetup {
  std::string url;  // LCM URL shared by both ends
  mapio::MapStreamerConfig streamer;
  std::string tmp_root = "/tmp";  // the ground station's store goes to a fresh folder here (removed after)
  double time_compression = 1.0;  // streamed: the mapping timeline runs this many times faster
  double timeout_s = 120.0;       // after the stop, for the last point to be stored
  bool verify_points = true;      // decode the ground store and compare with the submitted points
  bool write_ground_maps = true;  // the ground writes completed segments' PLY/PCD every second (hwr-ground)
  // Bytes the link carried so far (e.g. the loopback's transmit counter), read before and after the
  // run; empty or returning < 0: not counted.
  std::function<int64_t()> link_byte_counter;
};

struct TransferResult {
  bool ok = false;
  std::string error;
  double latency_s = 0;     // last point stored on the ground minus the stop
  double replay_s = 0;      // streamed: wall time from the first submit to the stop
  int64_t link_bytes = -1;  // the link counter's difference over the run (chunks, acks, headers, resends)
  mapio::MapStreamerStats streamer;
  int64_t points_stored = 0, chunks_stored = 0, duplicates = 0, rejected = 0;
  // Streamed: points submitted but not yet encoded just before the last batch (0: encoding kept up),
  // the largest such backlog at any submit, and submits that found every batch slot busy.
  int64_t backlog_points_at_stop = 0, max_backlog_points = 0, submits_waited = 0;
  // verify_points: per-axis (L-inf) and Euclidean distance to the matched submitted point, the
  // largest colour channel difference (0 at color_bits 8), and decoded points without a partner of
  // the same (reduced) colour (must be 0).
  bool verified = false;
  double max_axis_error_mm = 0, max_error_mm = 0;
  int max_color_error = 0;
  int64_t points_checked = 0, unmatched = 0;
};

TransferResult run_transfer(const PointStream& map, TransferMode mode, int64_t run_id,
                            const TransferSetup& setup);

// Encodes the map's batches single-threaded, cut as the streamer cuts them (max_points_per_chunk,
// halved until a chunk fits max_chunk_bytes), then decodes every chunk: one core's throughput.
struct CodecThroughput {
  int64_t points = 0, chunks = 0, payload_bytes = 0;
  double encode_s = 0, decode_s = 0;
  int64_t errors = 0;
};
CodecThroughput measure_codec(const PointStream& map, const mapio::MapStreamerConfig& config);

}  // namespace hwr::bench
