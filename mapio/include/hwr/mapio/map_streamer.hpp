#pragma once
// The robot's map streamer (issue #5 items 2-3; paper sec. III-C): point batches of the local maps
// come in from the mapping task, are cut into Draco chunks small enough for one link datagram, and go
// out through the reliable link (ChunkSender over LcmLink) on the streamer's own thread, which also
// reads the ground station's acknowledgements. The mapping task never waits: submit() copies the
// batch into a preallocated slot and returns; with every slot busy the batch is refused and counted
// (the caller's map store still has it).
//
// Slot rule (a segment is always completed on the ground): of the batch_slots slots, the last free
// one is kept for a batch with segment_complete = true; a batch without it takes a slot only while
// at least 2 are free. A completing batch refused all the same (every slot busy, or too large) still
// completes its segment: submit() records an owed completion (segment id, version, T_world_segment)
// in a preallocated ring (room for at least batch_slots), and the streamer thread, in submission order (after
// the batches queued before it), sends an empty completing chunk in its place, so the ground station
// gets the segment's final chunk_count (stats.completions_owed). The refused batch's points are lost
// to the link, as for any refused batch. Only when that ring is full too is the completion lost
// (stats.completions_lost, one warning logged).
//
// Chunks: at most max_points_per_chunk points, and an encoded payload of at most max_chunk_bytes
// (a chunk over it is split in half until it fits). A batch that completes a segment ends with a
// chunk flagged segment_complete whose chunk_count is the segment's final count; a segment that
// closes with nothing left to send gets an empty completing chunk (num_points 0, no payload).

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "hwr/core/status.hpp"
#include "hwr/mapio/chunk_codec.hpp"
#include "hwr/mapio/chunk_sender.hpp"
#include "hwr_lcm/command_ack_t.hpp"
#include "hwr_lcm/detection_t.hpp"
#include "hwr_lcm/operator_command_t.hpp"
#include "hwr_lcm/status_t.hpp"

namespace hwr::mapio {

struct MapStreamerConfig {
  // Each voxel is streamed once (recon::MapStreamSink), so point ids are not sent by default: they
  // are hash-table slots, ~20 bits of entropy per point that would double the payload.
  // Colour in 5 bits per channel (error <= 4.6 of 255): with the split layout that takes ~1.2
  // bytes/point instead of ~2.3 lossless and makes a chunk >= 4x smaller than raw float xyz + rgb
  // (issue #5; hwr-bench transfer: 3.51 against 4.62 bytes/point). 8 keeps colours exact.
  ChunkCodecConfig codec = [] {
    ChunkCodecConfig c;
    c.color_bits = 5;
    return c;
  }();
  // In flight at most ~0.75 MB: LCM's udpm receiver queues undispatched messages in a 1000 KiB ring
  // (lcm_udpm.c LCM_RINGBUF_SIZE) and drops what does not fit, so a larger window only turns a busy
  // ground station into lost chunks and resends.
  LinkConfig link = [] {
    LinkConfig l;
    l.window_chunks = 16;
    l.window_bytes = 768u << 10;
    // A window's worth of chunks takes the ground station ~0.4 s to verify, decode and fsync; a
    // shorter timeout resends chunks that are merely queued.
    l.initial_rto_ns = 1'000'000'000;
    return l;
  }();
  int max_points_per_chunk = 16'384;
  size_t max_chunk_bytes = 60'000;  // one LCM datagram (no LCM fragmentation: a lost fragment loses all)
  int batch_slots = 16;             // batches waiting for the streamer thread (>= 2: see the slot rule)
  int max_batch_points = 65'536;    // points per submit() at most
  bool spatial_order = true;  // sort each batch along a Z-order curve before cutting it (spatial_order.hpp)
  // Keyframe images for the operator (HWR_KEYFRAME_IMAGE): JPEG at this quality, downscaled to at
  // most this width (a 640-wide JPEG at 80 is ~30-60 kB, one or two LCM datagrams).
  int keyframe_image_max_width = 640;
  int keyframe_jpeg_quality = 80;
};

struct MapStreamerStats {
  int64_t batches = 0, batches_refused = 0;  // submit() calls taken / refused (slots full, too large)
  int64_t completions_owed = 0;    // refused completing batches replaced by an empty completing chunk
  int64_t completions_lost = 0;    // refused completing batches whose completion could not be owed either
  int batch_slots_free = 0;        // slots free now (a snapshot)
  int64_t chunks = 0, points = 0;  // encoded and offered
  int64_t payload_bytes = 0;       // encoded payload bytes (first sends)
  int64_t raw_bytes = 0;           // 15 bytes per point (float xyz + rgb): the "direct" size
  int64_t encode_errors = 0;
  int64_t split_fallbacks =
      0;  // 5-bit chunks sent in the single layout (chunk_codec.hpp: far from the origin)
  int64_t sends = 0, resends = 0, acked = 0;  // from the ChunkSender
  int in_flight = 0;
  int64_t link_errors = 0;
  int64_t last_ack_ns = 0;  // steady clock
  int64_t poses_published = 0, poses_dropped = 0, status_published = 0;
  // The operator channel (docs/detection.md): detections and acknowledgements out, commands in.
  int64_t detections_published = 0, detections_dropped = 0, acks_published = 0;
  int64_t commands_received = 0;  // decoded, for this robot, handed to take_operator_command()
  int64_t commands_refused = 0;   // undecodable or invalid (operator_wire.hpp)
  int64_t commands_other_robot = 0, commands_dropped = 0;  // addressed to another robot; inbox full
  int64_t keyframe_images_published = 0, keyframe_images_dropped = 0;  // dropped: queue full or not encodable
};

class MapStreamer {
 public:
  // Opens the LCM URL (kIoError when it cannot) and starts the streamer thread. kInvalidArgument for
  // a robot_id the ground station would refuse ([A-Za-z0-9_-]{1,64}) or a bad config (e.g.
  // batch_slots < 2).
  static core::Expected<std::unique_ptr<MapStreamer>> start(const std::string& url,
                                                            const std::string& robot_id, int64_t run_id,
                                                            const MapStreamerConfig& config);
  ~MapStreamer();  // stops the thread without waiting for acknowledgements

  // Mapping task (one thread): points in the segment frame, ids (may be null) per point. Without a
  // slot it may take (slot rule above) it waits up to wait_s for one (0: never blocks), then refuses
  // (false, counted; a refused completing batch still completes its segment). A batch of more than
  // max_batch_points goes in slot-sized pieces (false if any piece was refused). Does not allocate.
  bool submit(int32_t segment_id, int32_t segment_version, const Eigen::Isometry3d& T_world_segment,
              const ChunkPoint* points_segment, const uint32_t* ids, int n, bool segment_complete,
              double wait_s = 0.0);
  // Whether submit() of n points would be taken whole right now without waiting: every slot-sized
  // piece finds a slot under the slot rule. Only the submitting thread takes slots (the streamer
  // thread only frees them), so on that thread a true stays true until it submits.
  bool would_take(int n, bool segment_complete) const;
  // Mapping task: a batch that must reach the ground station whole, sent over as many calls as the
  // slots allow. Submits its slot-sized pieces from point *first on, each only while a slot is free
  // for it (never refused, never waits), and advances *first past them. True once the whole batch,
  // its completion included, has been taken (an empty completing batch takes one empty piece);
  // false: call again later with the same arguments. hwr-robot streams updated prior segments so:
  // a refused piece would be a hole in that version.
  bool submit_while_free(int32_t segment_id, int32_t segment_version,
                         const Eigen::Isometry3d& T_world_segment, const ChunkPoint* points_segment, int n,
                         bool segment_complete, int* first);
  // Telemetry, published by the streamer thread so the caller never waits on the network:
  // HWR_POSE (a ring of 64 poses; a full ring drops the oldest, counted in stats) and HWR_STATUS
  // (the latest one replaces one not yet sent). robot_id and run_id are filled in.
  void post_pose(int64_t t_ns, const Eigen::Isometry3d& T_world_cam, bool tracking);
  void post_status(const hwr_lcm::status_t& status);
  // The operator channel (issue #7 item 4). post_detection: an entry of the robot's welding-region
  // list for HWR_DETECTION (robot_id, run_id filled in); at most 1024 wait, a full queue drops the
  // oldest (counted). post_command_ack: the answer to an operator command, on HWR_OPERATOR_ACK (robot_id
  // filled in). take_operator_command: the next HWR_OPERATOR_CMD addressed to this robot that decoded and
  // validated (operator_wire.hpp), oldest first; false when none waits (at most 64 wait: a full inbox
  // drops the newest, counted, and the ground station resends it). Any thread; the messages are sent
  // and received by the streamer thread.
  void post_detection(const hwr_lcm::detection_t& detection);
  void post_command_ack(const hwr_lcm::command_ack_t& ack);
  bool take_operator_command(hwr_lcm::operator_command_t* command);
  // A keyframe's colour image (8-bit BGR) for the operator to draw on, copied here and JPEG-encoded
  // by the streamer thread (keyframe_image_t on HWR_KEYFRAME_IMAGE). At most 4 wait; a full queue
  // drops the oldest (counted). Operator-paced (a few per second at most): the copy allocates.
  void post_keyframe_image(int64_t keyframe_t_ns, const cv::Mat& bgr);
  // Waits until everything submitted has been acknowledged (true) or timeout_s passed (false).
  bool flush(double timeout_s);
  MapStreamerStats stats() const;
  // Why the last refused operator command was refused (empty when none was).
  std::string last_command_error() const;

  MapStreamer(const MapStreamer&) = delete;
  MapStreamer& operator=(const MapStreamer&) = delete;

 private:
  struct Impl;
  explicit MapStreamer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::mapio
