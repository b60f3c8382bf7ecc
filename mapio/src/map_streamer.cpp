#include "hwr/mapio/map_streamer.hpp"
#include "hwr/mapio/spatial_order.hpp"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/core/log.hpp"
#include "hwr/core/object_pool.hpp"
#include "hwr/core/spsc_ring.hpp"
#include "hwr/core/time.hpp"
#include "hwr/mapio/chunk_wire.hpp"
#include "hwr/mapio/ground_store.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/operator_wire.hpp"
#include "hwr/mapio/telemetry_wire.hpp"
#include "hwr_lcm/keyframe_image_t.hpp"
#include "hwr_lcm/pose_t.hpp"

namespace hwr::mapio {
namespace {

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct PoseSample {
  int64_t t_ns = 0;
  double T_world_cam[12] = {};
  bool tracking = false;
};

// Batches and owed completions share one submission order: seq = 0, 1, 2, ... (MapStreamer::Impl::
// submitted at the time), which the streamer thread follows (consumed is the next seq it takes).
struct Batch {
  int64_t seq = 0;
  int32_t segment_id = 0, segment_version = 0;
  double T_world_segment[12] = {};
  bool complete = false;
  bool has_ids = false;
  int n = 0;
  std::vector<ChunkPoint> points;
  std::vector<uint32_t> ids;
};

// A completing batch submit() refused: the streamer thread sends an empty completing chunk for it.
struct OwedCompletion {
  int64_t seq = 0;
  int32_t segment_id = 0, segment_version = 0;
  double T_world_segment[12] = {};
};

}  // namespace

struct MapStreamer::Impl {
  Impl(LcmLink l, const std::string& robot_id, int64_t run_id, const MapStreamerConfig& c)
      : config(c),
        link(std::move(l)),
        sender(robot_id, run_id, c.link),
        pool(static_cast<size_t>(c.batch_slots), prototype(c)),
        queue(static_cast<size_t>(c.batch_slots)),
        owed(static_cast<size_t>(c.batch_slots)),
        spatial_order(c.max_batch_points),
        poses(64),
        robot_id_(robot_id),
        run_id_(run_id) {}

  static Batch prototype(const MapStreamerConfig& c) {
    Batch b;
    b.points.resize(static_cast<size_t>(c.max_batch_points));
    b.ids.resize(static_cast<size_t>(c.max_batch_points));
    return b;
  }

  MapStreamerConfig config;
  LcmLink link;
  ChunkSender sender;
  core::ObjectPool<Batch> pool;
  core::SpscRing<Batch*> queue;
  core::SpscRing<OwedCompletion> owed;
  SpatialOrder
      spatial_order;  // streamer thread  // mapping task -> streamer thread (map_streamer.hpp slot rule)
  core::SpscRing<PoseSample> poses;  // camera task -> streamer thread
  std::string robot_id_;
  int64_t run_id_;
  hwr_lcm::status_t status_pending;  // under mu
  bool status_due = false;           // under mu
  hwr_lcm::status_t status_out;      // streamer thread
  hwr_lcm::pose_t pose_out;          // streamer thread
  // The operator channel, under mu (operator-paced: a few messages, so plain queues).
  static constexpr size_t kMaxDetectionsWaiting = 1024, kMaxCommandsWaiting = 64;
  std::string last_command_error;  // under mu
  std::deque<hwr_lcm::detection_t> detections_out;
  std::deque<hwr_lcm::command_ack_t> acks_out;
  std::deque<hwr_lcm::operator_command_t> commands_in;
  static constexpr size_t kMaxImagesWaiting = 4;
  std::deque<std::pair<int64_t, cv::Mat>> images_out;  // keyframe_t_ns, BGR
  hwr_lcm::keyframe_image_t image_msg;                 // streamer thread
  hwr_lcm::operator_command_t command_scratch;         // streamer thread
  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<int64_t> submitted{0};    // batches and owed completions handed over (the next seq)
  std::atomic<int64_t> consumed{0};     // of those, fully encoded and offered (the next seq to take)
  bool completion_loss_warned = false;  // mapping task

  // Streamer-thread state.
  std::deque<hwr_lcm::map_chunk_t> pending;  // encoded, not yet in the sender's window
  std::map<std::pair<int32_t, int32_t>, int32_t> next_chunk_index;
  std::vector<uint8_t> payload;
  std::vector<uint8_t> wire;
  hwr_lcm::chunk_ack_t ack;
  Batch* next_batch = nullptr;  // popped from queue, waiting for its seq
  OwedCompletion next_owed;     // popped from owed, waiting for its seq when have_owed
  bool have_owed = false;

  mutable std::mutex mu;
  std::condition_variable cv;
  MapStreamerStats stats;

  void publish(const hwr_lcm::map_chunk_t& c) {
    const core::Status st = encode_chunk_message(c, &wire);
    if (st.ok() && link.publish_bytes(kChannelMapChunk, wire.data(), wire.size()).ok()) return;
    std::lock_guard<std::mutex> lock(mu);
    ++stats.link_errors;
  }

  // A chunk of the segment's next index from `payload` (n points; n = 0: an empty completing chunk).
  void make_chunk(const Batch& b, int n, bool last_of_complete) {
    make_chunk(b.segment_id, b.segment_version, b.T_world_segment, n, last_of_complete);
  }
  void make_chunk(int32_t segment_id, int32_t segment_version, const double* T_world_segment, int n,
                  bool last_of_complete) {
    hwr_lcm::map_chunk_t c;
    c.segment_id = segment_id;
    c.segment_version = segment_version;
    int32_t& next = next_chunk_index[{segment_id, segment_version}];
    c.chunk_index = next++;
    c.chunk_count = next;
    c.segment_complete = last_of_complete ? 1 : 0;
    std::copy(T_world_segment, T_world_segment + 12, c.T_world_segment);
    c.num_points = n;
    c.has_normals = 0;
    if (n > 0) c.payload = payload;
    c.max_position_error_m = n > 0 ? static_cast<float>(last_error_m) : 0.0f;
    c.payload_size = static_cast<int32_t>(c.payload.size());
    pending.push_back(std::move(c));
  }

  double last_error_m = 0;

  // Encodes [pts, pts + n) into one chunk, halving until it fits max_chunk_bytes.
  void encode_range(const Batch& b, const ChunkPoint* pts, const uint32_t* ids, int n, bool ends_complete) {
    ChunkCodecConfig codec = config.codec;
    if (ids == nullptr) codec.with_point_ids = false;
    auto r = encode_chunk(pts, n, codec.with_point_ids ? ids : nullptr, nullptr, codec, &payload);
    // Over max_chunk_bytes (checked here, not through the codec's own limit, whose error code other
    // range errors share): halving cures it.
    if (r.ok() && payload.size() > config.max_chunk_bytes && n > 1) {
      const int half = n / 2;
      encode_range(b, pts, ids, half, false);
      encode_range(b, pts + half, ids != nullptr ? ids + half : nullptr, n - half, ends_complete);
      return;
    }
    if (!r.ok()) {
      HWR_LOG_WARN("mapio", "map streamer: %d points of segment %d not encoded: %s", n, b.segment_id,
                   r.status().message().c_str());
      std::lock_guard<std::mutex> lock(mu);
      ++stats.encode_errors;
      if (!ends_complete) return;
      n = 0;  // still tell the ground station the segment is complete
    } else {
      last_error_m = r->max_position_error_m;
      std::lock_guard<std::mutex> lock(mu);
      if (!r->split && codec.color_bits < 8 && !codec.preserve_order) ++stats.split_fallbacks;
      ++stats.chunks;
      stats.points += n;
      stats.payload_bytes += static_cast<int64_t>(payload.size());
      stats.raw_bytes += 15 * static_cast<int64_t>(n);
    }
    make_chunk(b, n, ends_complete);
  }

  void encode_batch(Batch& b) {
    if (b.n == 0) {
      if (b.complete) make_chunk(b, 0, true);
      return;
    }
    // Compact chunks: the batch in Z-order before it is cut (spatial_order.hpp).
    if (config.spatial_order)
      (void)spatial_order.sort(b.points.data(), b.has_ids ? b.ids.data() : nullptr, b.n);
    for (int first = 0; first < b.n; first += config.max_points_per_chunk) {
      const int n = std::min(config.max_points_per_chunk, b.n - first);
      const bool last = first + n == b.n;
      encode_range(b, b.points.data() + first, b.has_ids ? b.ids.data() + first : nullptr, n,
                   last && b.complete);
    }
  }

  // Takes the next item in submission order (a batch or an owed completion) when it has arrived.
  // Both rings are popped ahead into next_batch / next_owed, and only the one whose seq is due is
  // used, so an owed completion never overtakes a batch submitted before it, nor the reverse.
  void take_next_item() {
    if (next_batch == nullptr) (void)queue.try_pop(next_batch);
    if (!have_owed) have_owed = owed.try_pop(next_owed);
    const int64_t due = consumed.load();
    if (have_owed && next_owed.seq == due) {
      // The refused batch's points are lost; its segment still ends with chunk_count final.
      make_chunk(next_owed.segment_id, next_owed.segment_version, next_owed.T_world_segment, 0, true);
      have_owed = false;
      consumed.fetch_add(1);
    } else if (next_batch != nullptr && next_batch->seq == due) {
      encode_batch(*next_batch);
      pool.release(next_batch);
      next_batch = nullptr;
      consumed.fetch_add(1);
    }
  }

  bool items_waiting() const {
    return next_batch != nullptr || have_owed || queue.size() > 0 || owed.size() > 0;
  }

  void run() {
    link.subscribe(kChannelMapAck, [this](const uint8_t* d, size_t n) {
      if (!decode_ack_message(d, n, &ack).ok() || !verify_ack(ack, ChunkWireLimits{}).ok()) return;
      sender.on_ack(ack, steady_ns());
      std::lock_guard<std::mutex> lock(mu);
      stats.last_ack_ns = steady_ns();
    });
    link.subscribe(kChannelOperatorCommand, [this](const uint8_t* d, size_t n) { on_command(d, n); });
    for (;;) {
      // Take the next batch only when the previous one's chunks are all in the window.
      if (pending.empty()) take_next_item();
      const int64_t now = steady_ns();
      while (!pending.empty() && sender.can_accept(pending.front().payload.size())) {
        if (!sender.offer(std::move(pending.front()), now)) break;
        pending.pop_front();
      }
      sender.service(now, [this](const hwr_lcm::map_chunk_t& c) { publish(c); });
      publish_telemetry();
      {
        std::lock_guard<std::mutex> lock(mu);
        const ChunkSender::Stats& s = sender.stats();
        stats.sends = s.sends;
        stats.resends = s.resends;
        stats.acked = s.acked;
        stats.in_flight = s.in_flight;
        drained = consumed.load() == submitted.load() && pending.empty() && sender.idle();
      }
      cv.notify_all();
      if (stop.load()) return;
      // Wait for acks; return early when there is encoding to do.
      const bool work =
          !pending.empty() ? sender.can_accept(pending.front().payload.size()) : items_waiting();
      auto r = link.handle(work ? 0 : 5);
      if (!r.ok()) {
        std::lock_guard<std::mutex> lock(mu);
        ++stats.link_errors;
      } else if (r.value() > 0) {
        (void)link.drain();
      }
    }
  }

  void on_command(const uint8_t* data, size_t size) {
    const core::Status st = decode_operator_command(data, size, &command_scratch);
    std::lock_guard<std::mutex> lock(mu);
    if (!st.ok()) {
      ++stats.commands_refused;
      last_command_error = st.message();
      return;
    }
    if (command_scratch.robot_id != robot_id_) {
      ++stats.commands_other_robot;
      return;
    }
    if (commands_in.size() >= kMaxCommandsWaiting) {
      ++stats.commands_dropped;
      return;
    }
    commands_in.push_back(command_scratch);
    ++stats.commands_received;
  }

  // Sends the detections and acknowledgements waiting (taken under mu, published outside it).
  void publish_operator_messages() {
    std::deque<hwr_lcm::detection_t> detections;
    std::deque<hwr_lcm::command_ack_t> acks;
    {
      std::lock_guard<std::mutex> lock(mu);
      if (detections_out.empty() && acks_out.empty()) return;
      detections.swap(detections_out);
      acks.swap(acks_out);
    }
    // Verified before they go out (operator_wire.hpp): the ground station refuses what does not pass.
    int64_t published_detections = 0, published_acks = 0;
    for (const auto& d : detections)
      if (encode_detection(d, &wire).ok() &&
          link.publish_bytes(kChannelDetection, wire.data(), wire.size()).ok())
        ++published_detections;
    for (const auto& a : acks)
      if (encode_command_ack(a, &wire).ok() &&
          link.publish_bytes(kChannelOperatorAck, wire.data(), wire.size()).ok())
        ++published_acks;
    std::lock_guard<std::mutex> lock(mu);
    stats.detections_published += published_detections;
    stats.acks_published += published_acks;
    stats.link_errors +=
        static_cast<int64_t>(detections.size() + acks.size()) - published_detections - published_acks;
  }

  // One keyframe image as JPEG on HWR_KEYFRAME_IMAGE (telemetry_wire.hpp); false when it failed.
  bool publish_keyframe_image(int64_t keyframe_t_ns, const cv::Mat& bgr) {
    cv::Mat scaled = bgr;
    if (bgr.cols > config.keyframe_image_max_width) {
      const double f = static_cast<double>(config.keyframe_image_max_width) / bgr.cols;
      cv::resize(bgr, scaled, cv::Size(), f, f, cv::INTER_AREA);
    }
    // Encoded straight into the message: no intermediate copy of the JPEG.
    if (!cv::imencode(".jpg", scaled, image_msg.jpeg,
                      {cv::IMWRITE_JPEG_QUALITY, config.keyframe_jpeg_quality}))
      return false;
    image_msg.t_ns = core::MonotonicClock().now_ns();
    image_msg.robot_id = robot_id_;
    image_msg.run_id = run_id_;
    image_msg.keyframe_t_ns = keyframe_t_ns;
    image_msg.width = bgr.cols;
    image_msg.height = bgr.rows;
    image_msg.jpeg_width = scaled.cols;
    image_msg.jpeg_height = scaled.rows;
    image_msg.size = static_cast<int32_t>(image_msg.jpeg.size());
    return encode_keyframe_image(image_msg, &wire).ok() &&
           link.publish_bytes(kChannelKeyframeImage, wire.data(), wire.size()).ok();
  }

  void publish_keyframe_images() {
    std::deque<std::pair<int64_t, cv::Mat>> images;
    {
      std::lock_guard<std::mutex> lock(mu);
      if (images_out.empty()) return;
      images.swap(images_out);
    }
    int64_t published = 0;
    for (const auto& [t_ns, bgr] : images) published += publish_keyframe_image(t_ns, bgr) ? 1 : 0;
    std::lock_guard<std::mutex> lock(mu);
    stats.keyframe_images_published += published;
    stats.keyframe_images_dropped += static_cast<int64_t>(images.size()) - published;
  }

  void publish_telemetry() {
    publish_operator_messages();
    publish_keyframe_images();
    PoseSample p;
    int64_t published = 0;
    while (poses.try_pop(p)) {
      pose_out.t_ns = p.t_ns;
      pose_out.robot_id = robot_id_;
      pose_out.run_id = run_id_;
      std::copy(p.T_world_cam, p.T_world_cam + 12, pose_out.T_world_cam);
      pose_out.tracking = p.tracking ? 1 : 0;
      pose_out.localized = 0;
      if (link.publish(kChannelPose, pose_out).ok()) ++published;
    }
    bool send_status = false;
    {
      std::lock_guard<std::mutex> lock(mu);
      stats.poses_published += published;
      stats.poses_dropped = static_cast<int64_t>(poses.dropped());
      if (status_due) {
        status_out = status_pending;
        status_due = false;
        send_status = true;
      }
    }
    if (send_status && link.publish(kChannelStatus, status_out).ok()) {
      std::lock_guard<std::mutex> lock(mu);
      ++stats.status_published;
    }
  }

  bool drained = true;  // under mu: at the end of the thread's last pass, nothing was left to send
};

MapStreamer::MapStreamer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

MapStreamer::~MapStreamer() {
  impl_->stop.store(true);
  if (impl_->thread.joinable()) impl_->thread.join();
}

core::Expected<std::unique_ptr<MapStreamer>> MapStreamer::start(const std::string& url,
                                                                const std::string& robot_id, int64_t run_id,
                                                                const MapStreamerConfig& config) {
  if (config.batch_slots < 2 || config.max_batch_points < 1 || config.max_points_per_chunk < 1 ||
      config.max_chunk_bytes < 1024 || config.max_chunk_bytes > config.link.window_bytes ||
      config.link.window_chunks < 1 || !(config.link.initial_rto_ns > 0) ||
      config.link.initial_rto_ns > config.link.max_rto_ns || config.link.rto_backoff < 1.0 ||
      config.link.max_sends_per_service < 1) {
    return core::InvalidArgument(
        "map streamer: needs batch_slots >= 2 (one is kept for segment completions), max_batch_points >= 1, "
        "max_points_per_chunk >= 1, "
        "1024 <= max_chunk_bytes <= link.window_bytes, link.window_chunks >= 1, "
        "0 < link.initial_rto_ns <= link.max_rto_ns, link.rto_backoff >= 1, link.max_sends_per_service >= 1");
  }
  HWR_RETURN_IF_ERROR(GroundStore::validate_robot_id(robot_id));
  auto link = LcmLink::open(url);
  if (!link.ok()) return link.status();
  std::unique_ptr<MapStreamer> s(
      new MapStreamer(std::make_unique<Impl>(std::move(link.value()), robot_id, run_id, config)));
  Impl* impl = s->impl_.get();
  impl->thread = std::thread([impl] { impl->run(); });
  return s;
}

namespace {

void copy_pose(const Eigen::Isometry3d& T, double* out) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) out[4 * r + c] = T.matrix()(r, c);
}

}  // namespace

bool MapStreamer::submit(int32_t segment_id, int32_t segment_version,
                         const Eigen::Isometry3d& T_world_segment, const ChunkPoint* points_segment,
                         const uint32_t* ids, int n, bool segment_complete, double wait_s) {
  Impl& m = *impl_;
  if (n > m.config.max_batch_points && points_segment != nullptr) {
    // Larger than a slot: in slot-sized pieces, the last one carrying the completion.
    const int piece = m.config.max_batch_points;
    bool all_taken = true;
    for (int first = 0; first < n; first += piece) {
      const int k = std::min(piece, n - first);
      all_taken =
          submit(segment_id, segment_version, T_world_segment, points_segment + first,
                 ids != nullptr ? ids + first : nullptr, k, segment_complete && first + k == n, wait_s) &&
          all_taken;
    }
    return all_taken;
  }
  // Slot rule (map_streamer.hpp): the last free slot is for a completing batch. Only this thread
  // acquires and the streamer thread only releases, so a count seen here can only grow before the
  // acquire below.
  auto take_slot = [&m, segment_complete]() -> Batch* {
    if (!segment_complete && m.pool.available() < 2) return nullptr;
    return m.pool.acquire();
  };
  Batch* b = nullptr;
  if (n >= 0 && n <= m.config.max_batch_points) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
    while ((b = take_slot()) == nullptr && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (b != nullptr) {
    b->segment_id = segment_id;
    b->segment_version = segment_version;
    copy_pose(T_world_segment, b->T_world_segment);
    b->complete = segment_complete;
    b->has_ids = ids != nullptr;
    b->n = n;
    std::copy(points_segment, points_segment + n, b->points.begin());
    if (ids != nullptr) std::copy(ids, ids + n, b->ids.begin());
    {
      // Before the batch is visible: a flush() from now on waits for the thread's next full pass.
      // The count moves under the same lock, so a pass that ends in between cannot declare the
      // old count drained after this batch was taken (flush() would return before its chunks).
      std::lock_guard<std::mutex> lock(m.mu);
      m.drained = false;
      b->seq = m.submitted.fetch_add(1);
    }
    if (m.queue.try_push(b)) {
      std::lock_guard<std::mutex> lock(m.mu);
      ++m.stats.batches;
      return true;
    }
    // Cannot happen (as many queue places as batches); the seq is given back, no gap is left.
    m.submitted.fetch_sub(1);
    m.pool.release(b);
  }
  // Refused. A completing batch is owed: its segment still gets an empty completing chunk.
  bool owed = false;
  if (segment_complete) {
    OwedCompletion o;
    o.segment_id = segment_id;
    o.segment_version = segment_version;
    copy_pose(T_world_segment, o.T_world_segment);
    {
      std::lock_guard<std::mutex> lock(m.mu);  // as for a batch above
      m.drained = false;
      o.seq = m.submitted.fetch_add(1);
    }
    owed = m.owed.try_push(o);
    if (!owed) m.submitted.fetch_sub(1);
  }
  bool warn = false;
  {
    std::lock_guard<std::mutex> lock(m.mu);
    ++m.stats.batches_refused;
    if (owed) ++m.stats.completions_owed;
    if (segment_complete && !owed) {
      ++m.stats.completions_lost;
      warn = !m.completion_loss_warned;
      m.completion_loss_warned = true;
    }
  }
  if (warn) {
    HWR_LOG_WARN("mapio",
                 "map streamer: segment %d v%d: its completing batch was refused and %d owed completions "
                 "are already waiting; the ground station will not see this segment complete "
                 "(stats.completions_lost counts every such segment; warned once)",
                 segment_id, segment_version, m.config.batch_slots);
  }
  return false;
}

bool MapStreamer::flush(double timeout_s) {
  Impl& m = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  std::unique_lock<std::mutex> lock(m.mu);
  for (;;) {
    // `drained` was computed at the end of a pass; a batch submitted since makes submitted > consumed.
    if (m.drained && m.consumed.load() == m.submitted.load()) return true;
    if (m.cv.wait_until(lock, deadline) == std::cv_status::timeout) return false;
  }
}

void MapStreamer::post_pose(int64_t t_ns, const Eigen::Isometry3d& T_world_cam, bool tracking) {
  PoseSample p;
  p.t_ns = t_ns;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) p.T_world_cam[4 * r + c] = T_world_cam.matrix()(r, c);
  p.tracking = tracking;
  impl_->poses.push_drop_oldest(p);
}

void MapStreamer::post_keyframe_image(int64_t keyframe_t_ns, const cv::Mat& bgr) {
  if (bgr.empty() || bgr.type() != CV_8UC3) return;
  cv::Mat copy = bgr.clone();
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  if (m.images_out.size() >= Impl::kMaxImagesWaiting) {
    m.images_out.pop_front();
    ++m.stats.keyframe_images_dropped;
  }
  m.images_out.emplace_back(keyframe_t_ns, std::move(copy));
}

void MapStreamer::post_status(const hwr_lcm::status_t& status) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  m.status_pending = status;
  m.status_pending.robot_id = m.robot_id_;
  m.status_pending.run_id = m.run_id_;
  m.status_due = true;
}

void MapStreamer::post_detection(const hwr_lcm::detection_t& detection) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  if (m.detections_out.size() >= Impl::kMaxDetectionsWaiting) {
    m.detections_out.pop_front();
    ++m.stats.detections_dropped;
  }
  m.detections_out.push_back(detection);
  m.detections_out.back().robot_id = m.robot_id_;
  m.detections_out.back().run_id = m.run_id_;
}

void MapStreamer::post_command_ack(const hwr_lcm::command_ack_t& ack) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  m.acks_out.push_back(ack);
  m.acks_out.back().robot_id = m.robot_id_;
}

bool MapStreamer::take_operator_command(hwr_lcm::operator_command_t* command) {
  Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mu);
  if (m.commands_in.empty()) return false;
  *command = std::move(m.commands_in.front());
  m.commands_in.pop_front();
  return true;
}

std::string MapStreamer::last_command_error() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->last_command_error;
}

bool MapStreamer::would_take(int n, bool segment_complete) const {
  const Impl& m = *impl_;
  if (n < 0) return false;
  const int64_t pieces = std::max<int64_t>(
      1, (static_cast<int64_t>(n) + m.config.max_batch_points - 1) / m.config.max_batch_points);
  // Slot rule: a piece without the completion needs 2 free slots when it is taken, the completing
  // one 1. Taken in order, the last piece is the one that finds the fewest free.
  const int64_t needed = segment_complete ? pieces : pieces + 1;
  return static_cast<int64_t>(m.pool.available()) >= needed;
}

bool MapStreamer::submit_while_free(int32_t segment_id, int32_t segment_version,
                                    const Eigen::Isometry3d& T_world_segment,
                                    const ChunkPoint* points_segment, int n, bool segment_complete,
                                    int* first) {
  const int piece = impl_->config.max_batch_points;
  if (*first > n || (*first == n && n > 0)) return true;  // all of it taken already
  do {                                                    // at least once: an empty batch is one empty piece
    const int k = std::min(piece, n - *first);
    const bool completes = segment_complete && *first + k == n;
    if (!would_take(k, completes)) return false;
    // Taken: only this thread takes slots, and would_take() saw one free for this piece.
    submit(segment_id, segment_version, T_world_segment, points_segment + *first, nullptr, k, completes, 0.0);
    *first += k;
  } while (*first < n);
  return true;
}

MapStreamerStats MapStreamer::stats() const {
  std::lock_guard<std::mutex> lock(impl_->mu);
  MapStreamerStats s = impl_->stats;
  s.batch_slots_free = static_cast<int>(impl_->pool.available());
  return s;
}

}  // namespace hwr::mapio
