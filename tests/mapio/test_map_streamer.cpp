// MapStreamer's slot rule and owed completions (mapio/map_streamer.hpp; issue #5 item 3): the last
// free batch slot is kept for a segment's completing batch, and a completing batch refused all the
// same is replaced by an empty completing chunk, so the ground station always learns the segment's
// final chunk_count.
//
// How the streamer thread is held still: a link window of one chunk and nobody acknowledging. The
// first batch's chunk fills the window, the second's waits for it, and from then on the thread takes
// no batch, so the slots the test fills stay filled. The slot-rule test runs on memq:// (nothing is
// received there); the end-to-end test needs a ground station in the same process on another LCM
// instance, so it runs on UDP multicast inside a private network namespace (private_netns.hpp),
// with the GroundStation library as the receiver.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/mapio/ground_station.hpp"
#include "hwr/mapio/ground_store.hpp"
#include "hwr/mapio/lcm_link.hpp"
#include "hwr/mapio/map_streamer.hpp"
#include "hwr/mapio/telemetry_wire.hpp"
#include "private_netns.hpp"

namespace hwr::mapio {
namespace {

namespace fs = std::filesystem;
constexpr const char* kUdpUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr int64_t kMs = 1'000'000;

// n points on a 2 cm grid, distinct per `tag` (z), so chunks of different batches differ.
std::vector<ChunkPoint> grid(int n, int tag) {
  std::vector<ChunkPoint> pts(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    ChunkPoint& p = pts[static_cast<size_t>(i)];
    p.x_m = 0.02f * static_cast<float>(i % 50);
    p.y_m = 0.02f * static_cast<float>(i / 50);
    p.z_m = 0.1f * static_cast<float>(tag);
    p.r = static_cast<uint8_t>(tag);
    p.g = static_cast<uint8_t>(i);
    p.b = 7;
    p.flags = 0;
  }
  return pts;
}

Eigen::Isometry3d T_world_segment(int32_t segment_id) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(10.0 * segment_id, 1.0, 0.0);
  return T;
}

MapStreamerConfig two_slots_one_chunk_window() {
  MapStreamerConfig c;
  c.batch_slots = 2;
  c.link.window_chunks = 1;  // unacknowledged, one chunk stops the thread from taking batches
  c.link.initial_rto_ns = 50 * kMs;
  c.link.max_rto_ns = 200 * kMs;  // a ground station started later gets a resend soon
  return c;
}

// Polls (bounded, 5 s) until pred holds; the wait is for the streamer thread to reach a state, the
// test asserts nothing about how long that took.
bool wait_until(const MapStreamer& s, const std::function<bool(const MapStreamerStats&)>& pred) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred(s.stats())) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return pred(s.stats());
}

struct Submitter {
  MapStreamer& s;
  bool operator()(int32_t segment_id, int n, bool complete, double wait_s = 0.0) {
    const std::vector<ChunkPoint> pts = grid(n, n / 100);
    return s.submit(segment_id, 0, T_world_segment(segment_id), pts.data(), nullptr, n, complete, wait_s);
  }
};

// Segment 0's first batch (100 points) in flight, segment 1's first (200 points) encoded and waiting
// for the window; every slot (batch_slots of them) free again, and the thread takes nothing more until
// an ack comes.
void hold_the_streamer_thread(MapStreamer& s, int batch_slots = 2) {
  Submitter submit{s};
  ASSERT_TRUE(submit(0, 100, false, 5.0));
  ASSERT_TRUE(wait_until(s, [](const MapStreamerStats& st) { return st.in_flight == 1; }));
  ASSERT_TRUE(submit(1, 200, false, 5.0));
  ASSERT_TRUE(wait_until(s, [batch_slots](const MapStreamerStats& st) {
    return st.chunks == 2 && st.batch_slots_free == batch_slots;
  })) << "the streamer thread did not take the second batch";
}

TEST(MapStreamer, GivenOneSlotFreeThenOnlyACompletingBatchTakesIt) {
  auto streamer = MapStreamer::start("memq://", "robot-slots", 1, two_slots_one_chunk_window());
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  MapStreamer& s = **streamer;
  hold_the_streamer_thread(s);
  if (HasFatalFailure()) return;
  Submitter submit{s};

  ASSERT_TRUE(submit(1, 300, false));  // two free: a non-completing batch may take one
  EXPECT_EQ(s.stats().batch_slots_free, 1);
  EXPECT_FALSE(submit(0, 400, false));  // one free: kept for a completion
  EXPECT_FALSE(submit(0, 400, false, 0.05)) << "waiting must not hand the kept slot to it either";
  EXPECT_EQ(s.stats().batches_refused, 2);
  EXPECT_EQ(s.stats().completions_owed, 0);  // not completing: nothing owed
  ASSERT_TRUE(submit(0, 500, true));         // a completing batch takes the last slot
  MapStreamerStats st = s.stats();
  EXPECT_EQ(st.batch_slots_free, 0);
  EXPECT_EQ(st.batches, 4);

  // Every slot busy: completing batches are refused, and owed (as many as there are slots) ...
  EXPECT_FALSE(submit(1, 600, true));
  EXPECT_FALSE(submit(2, 700, true));
  st = s.stats();
  EXPECT_EQ(st.batches_refused, 4);
  EXPECT_EQ(st.completions_owed, 2);
  EXPECT_EQ(st.completions_lost, 0);
  // ... then lost, and counted as such.
  EXPECT_FALSE(submit(3, 800, true));
  st = s.stats();
  EXPECT_EQ(st.batches_refused, 5);
  EXPECT_EQ(st.completions_owed, 2);
  EXPECT_EQ(st.completions_lost, 1);
  EXPECT_EQ(st.batches, 4);
  EXPECT_FALSE(s.flush(0.05));  // nobody acknowledges
}

// would_take() answers for a batch cut into slot-sized pieces: whether every piece finds a slot under
// the slot rule. hwr-robot asks it before streaming an updated prior segment, which a partial submit
// would have to send again in part.
TEST(MapStreamer, GivenABatchOfSeveralPiecesThenWouldTakeSaysWhetherSubmitTakesAllOfIt) {
  MapStreamerConfig c = two_slots_one_chunk_window();
  c.batch_slots = 4;
  c.max_batch_points = 1000;
  auto streamer = MapStreamer::start("memq://", "robot-pieces", 1, c);
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  MapStreamer& s = **streamer;
  hold_the_streamer_thread(s, c.batch_slots);
  if (HasFatalFailure()) return;
  Submitter submit{s};

  // Four free: a completing batch of up to 4 pieces, a non-completing one of up to 3 (its last piece
  // must leave the kept slot).
  EXPECT_TRUE(s.would_take(0, true));
  EXPECT_TRUE(s.would_take(4000, true));
  EXPECT_FALSE(s.would_take(4001, true));
  EXPECT_TRUE(s.would_take(3000, false));
  EXPECT_FALSE(s.would_take(3001, false));
  EXPECT_FALSE(s.would_take(-1, true));

  // submit() agrees: 4 non-completing pieces take 3 slots and the 4th is refused.
  EXPECT_FALSE(submit(2, 4000, false));
  MapStreamerStats st = s.stats();
  EXPECT_EQ(st.batches, 2 + 3);
  EXPECT_EQ(st.batches_refused, 1);
  EXPECT_EQ(st.batch_slots_free, 1);

  // One free: only a completing single piece.
  EXPECT_FALSE(s.would_take(1, false));
  EXPECT_TRUE(s.would_take(1000, true));
  EXPECT_FALSE(s.would_take(1001, true));
  EXPECT_TRUE(submit(3, 1000, true));
  EXPECT_FALSE(s.would_take(0, true));  // none free
  EXPECT_FALSE(s.flush(0.05));          // nobody acknowledges
}

TEST(MapStreamer, GivenFewerThanTwoSlotsThenStartRefusesTheConfig) {
  MapStreamerConfig c;
  c.batch_slots = 1;
  auto streamer = MapStreamer::start("memq://", "robot-slots", 1, c);
  ASSERT_FALSE(streamer.ok());
  EXPECT_EQ(streamer.status().code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(streamer.status().message().find("batch_slots >= 2"), std::string::npos)
      << streamer.status().message();
}

// The ground station, on its own LCM instance and thread: stores, acknowledges.
class GroundThread {
 public:
  explicit GroundThread(GroundStation* g) : g_(g) {}
  core::Status start() {
    auto link = LcmLink::open(kUdpUrl);
    if (!link.ok()) return link.status();
    link_ = std::make_unique<LcmLink>(std::move(link.value()));
    link_->subscribe(kChannelMapChunk,
                     [this](const uint8_t* d, size_t n) { g_->on_chunk_message(d, n, now()); });
    thread_ = std::thread([this] {
      while (!stop_.load()) {
        if (!link_->handle(5).ok()) return;
        g_->service(now(),
                    [this](const hwr_lcm::chunk_ack_t& ack) { (void)link_->publish(kChannelMapAck, ack); });
      }
    });
    return core::Status::Ok();
  }
  ~GroundThread() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  void join() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }

 private:
  static int64_t now() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
  GroundStation* g_;
  std::unique_ptr<LcmLink> link_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
};

// A ground station storing under out_dir, listening and acknowledging on its own thread.
core::Status start_listening_ground(const std::string& out_dir, std::unique_ptr<GroundStation>* station,
                                    std::unique_ptr<GroundThread>* thread) {
  GroundStationConfig gc;
  gc.out_dir = out_dir;
  auto ground = GroundStation::open(gc);
  if (!ground.ok()) return ground.status();
  *station = std::move(ground.value());
  *thread = std::make_unique<GroundThread>(station->get());
  return (*thread)->start();
}

// submit_while_free() takes a batch's pieces while slots are free for them, never refusing one, and
// goes on from where it stopped once the streamer thread has freed slots: the ground station gets
// the whole batch with its completion.
TEST(MapStreamer, GivenTooFewSlotsForABatchThenSubmitWhileFreeTakesItOverSeveralCallsAndRefusesNothing) {
  if (!test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(test::setup_private_loopback());
  const std::string out =
      (fs::temp_directory_path() / ("hwr_while_free_" + std::to_string(getpid()))).string();
  fs::remove_all(out);
  const int64_t run_id = 7;
  MapStreamerConfig c = two_slots_one_chunk_window();
  c.batch_slots = 3;
  c.max_batch_points = 1000;
  auto streamer = MapStreamer::start(kUdpUrl, "robot-while-free", run_id, c);
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  MapStreamer& s = **streamer;
  hold_the_streamer_thread(s, c.batch_slots);  // segments 0 and 1: 100 and 200 points, not complete
  if (HasFatalFailure()) return;

  // 5500 points: 6 pieces. With 3 slots free, 2 go (a non-completing piece leaves the kept slot).
  const std::vector<ChunkPoint> pts = grid(5500, 9);
  int first = 0;
  EXPECT_FALSE(s.submit_while_free(4, 2, T_world_segment(4), pts.data(), 5500, true, &first));
  EXPECT_EQ(first, 2000);
  EXPECT_FALSE(s.submit_while_free(4, 2, T_world_segment(4), pts.data(), 5500, true, &first));
  EXPECT_EQ(first, 2000) << "no slot was freed, so nothing more may go";
  MapStreamerStats st = s.stats();
  EXPECT_EQ(st.batches_refused, 0);
  EXPECT_EQ(st.batch_slots_free, 1);

  // A ground station acknowledges: the thread frees slots, and the calls go on until all is taken.
  std::unique_ptr<GroundStation> ground;
  std::unique_ptr<GroundThread> gt;
  const core::Status started = start_listening_ground(out, &ground, &gt);
  ASSERT_TRUE(started.ok()) << started.message();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  bool whole = false;
  while (!whole && std::chrono::steady_clock::now() < deadline) {
    whole = s.submit_while_free(4, 2, T_world_segment(4), pts.data(), 5500, true, &first);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(whole) << "taken up to point " << first;
  EXPECT_EQ(first, 5500);
  EXPECT_TRUE(s.flush(10.0)) << "not everything was acknowledged";
  gt->join();
  st = s.stats();
  EXPECT_EQ(st.batches_refused, 0);
  EXPECT_EQ(st.completions_owed, 0);
  EXPECT_EQ(st.batches, 2 + 6);

  bool found = false;
  for (const auto& seg : ground->store().segments("robot-while-free", run_id)) {
    if (seg.segment_id != 4) continue;
    found = true;
    EXPECT_EQ(seg.version, 2);
    EXPECT_TRUE(seg.complete);
    EXPECT_EQ(seg.points_stored, 5500);
  }
  EXPECT_TRUE(found) << "segment 4 never reached the ground station";
  fs::remove_all(out);
}

TEST(MapStreamer, GivenTheCompletingBatchRefusedThenTheGroundStationStillSeesTheSegmentComplete) {
  if (!test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(test::setup_private_loopback());
  const std::string out = (fs::temp_directory_path() / ("hwr_owed_" + std::to_string(getpid()))).string();
  fs::remove_all(out);
  const int64_t run_id = 5;
  auto streamer = MapStreamer::start(kUdpUrl, "robot-owed", run_id, two_slots_one_chunk_window());
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  MapStreamer& s = **streamer;
  hold_the_streamer_thread(s);  // segment 0: 100 points in flight; segment 1: 200 points waiting
  if (HasFatalFailure()) return;
  Submitter submit{s};
  ASSERT_TRUE(submit(1, 300, false));   // segment 1, queued
  EXPECT_FALSE(submit(0, 400, false));  // the last slot is kept: lost to the link
  ASSERT_TRUE(submit(0, 500, true));    // segment 0 completes in the last slot
  EXPECT_FALSE(submit(1, 600, true));   // segment 1's completion refused: owed
  MapStreamerStats st = s.stats();
  EXPECT_EQ(st.batches_refused, 2);
  EXPECT_EQ(st.completions_owed, 1);

  // Only now does a ground station listen (the chunks sent so far went nowhere).
  std::unique_ptr<GroundStation> ground;
  std::unique_ptr<GroundThread> gt;
  const core::Status started = start_listening_ground(out, &ground, &gt);
  ASSERT_TRUE(started.ok()) << started.message();
  EXPECT_TRUE(s.flush(10.0)) << "not everything was acknowledged";
  gt->join();

  st = s.stats();
  EXPECT_EQ(st.chunks, 4);  // batches with points: 100, 200, 300, 500
  EXPECT_EQ(st.acked, 5);   // and the empty completing chunk owed for segment 1
  EXPECT_EQ(st.completions_owed, 1);
  EXPECT_EQ(st.completions_lost, 0);

  const GroundStore& store = ground->store();
  const auto segs = store.segments("robot-owed", run_id);
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_EQ(segs[0].segment_id, 0);
  EXPECT_TRUE(segs[0].complete);
  EXPECT_EQ(segs[0].chunk_count, 2);
  EXPECT_EQ(segs[0].points_stored, 100 + 500);
  EXPECT_EQ(segs[1].segment_id, 1);
  EXPECT_TRUE(segs[1].complete) << "segment 1's refused completion was never made up for";
  EXPECT_EQ(segs[1].chunk_count, 3);
  EXPECT_EQ(segs[1].points_stored, 200 + 300);
  // Order: the owed completion came after the batch queued before it (300 points), not before.
  std::vector<hwr_lcm::map_chunk_t> chunks;
  ASSERT_TRUE(store.load_segment("robot-owed", run_id, 1, 0, &chunks).ok());
  ASSERT_EQ(chunks.size(), 3u);
  EXPECT_EQ(chunks[0].num_points, 200);
  EXPECT_EQ(chunks[1].num_points, 300);
  EXPECT_EQ(chunks[1].segment_complete, 0);
  EXPECT_EQ(chunks[2].num_points, 0);
  EXPECT_EQ(chunks[2].segment_complete, 1);
  EXPECT_EQ(chunks[2].chunk_count, 3);
  EXPECT_DOUBLE_EQ(chunks[2].T_world_segment[3], 10.0);  // segment 1's pose, as submitted
  EXPECT_DOUBLE_EQ(chunks[2].T_world_segment[7], 1.0);
  streamer->reset();
  gt.reset();
  ground.reset();
  fs::remove_all(out);
}

TEST(MapStreamer, GivenKeyframeImagesThenLargeOnesDownscaledAndNonBgrOnesIgnored) {
  if (!test::in_private_netns()) {
    HWR_RUN_IN_PRIVATE_NETNS();
    return;
  }
  ASSERT_TRUE(test::setup_private_loopback());
  auto listener = LcmLink::open(kUdpUrl);
  ASSERT_TRUE(listener.ok()) << listener.status().message();
  std::vector<hwr_lcm::keyframe_image_t> received;
  listener->subscribe(kChannelKeyframeImage, [&](const uint8_t* d, size_t n) {
    hwr_lcm::keyframe_image_t m;
    ASSERT_TRUE(decode_keyframe_image(d, n, &m).ok());
    received.push_back(m);
  });
  auto streamer = MapStreamer::start(kUdpUrl, "robot-images", 9, MapStreamerConfig{});
  ASSERT_TRUE(streamer.ok()) << streamer.status().message();
  cv::Mat big(720, 1280, CV_8UC3, cv::Scalar(30, 60, 90));
  cv::rectangle(big, cv::Rect(100, 100, 400, 300), cv::Scalar(250, 250, 250), cv::FILLED);
  (*streamer)->post_keyframe_image(1000, big);
  (*streamer)->post_keyframe_image(2000, cv::Mat(48, 64, CV_8UC3, cv::Scalar(0, 0, 255)));
  (*streamer)->post_keyframe_image(3000, cv::Mat(48, 64, CV_32FC1));  // not BGR: ignored
  for (int i = 0; i < 100 && received.size() < 2; ++i) ASSERT_TRUE(listener->handle(50).ok());
  ASSERT_EQ(received.size(), 2u);
  EXPECT_EQ(received[0].robot_id, "robot-images");
  EXPECT_EQ(received[0].run_id, 9);
  EXPECT_EQ(received[0].keyframe_t_ns, 1000);
  EXPECT_EQ(received[0].width, 1280);  // box_px stays in the keyframe's pixels
  EXPECT_EQ(received[0].jpeg_width, 640);
  EXPECT_EQ(received[0].jpeg_height, 360);
  const cv::Mat decoded = cv::imdecode(received[0].jpeg, cv::IMREAD_COLOR);
  ASSERT_EQ(decoded.cols, 640);
  EXPECT_NEAR(decoded.at<cv::Vec3b>(100, 120)[0], 250, 8);  // inside the white rectangle, scaled by 1/2
  EXPECT_NEAR(decoded.at<cv::Vec3b>(300, 500)[2], 90, 8);
  EXPECT_EQ(received[1].jpeg_width, 64);
  // The streamer thread counts after it has published both: wait for its count.
  for (int i = 0; i < 200 && (*streamer)->stats().keyframe_images_published < 2; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ((*streamer)->stats().keyframe_images_published, 2);
  EXPECT_EQ((*streamer)->stats().keyframe_images_dropped, 0);
}

}  // namespace
}  // namespace hwr::mapio
