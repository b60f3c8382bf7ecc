// ReplaySource: every sample delivered once, in order, at its time; bad frames skipped and counted;
// the frame pool never leaks; deterministic whatever the prefetch thread's speed.

#include <chrono>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "hal_test_util.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::hal {
namespace {

constexpr int64_t kMs = 1'000'000;

// 2 s of 200 Hz IMU and 10 frames at 5 Hz; frame 3 cannot be decoded. slow_ms delays each decode.
ReplayLog synthetic_log(int slow_ms) {
  ReplayLog log;
  log.info.name = "synthetic";
  for (int i = 0; i < 400; ++i) {
    ImuSample s;
    s.t_ns = 1'000 * kMs + i * 5 * kMs;
    s.gyro_radps.x() = i;
    log.imu.push_back(s);
  }
  for (int i = 0; i < 10; ++i) log.frame_t_ns.push_back(1'000 * kMs + i * 200 * kMs);
  log.info.first_t_ns = 1'000 * kMs;
  log.info.last_t_ns = log.imu.back().t_ns;
  log.load_frame = [slow_ms](size_t i, RgbdFrame* out) -> core::Status {
    if (slow_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(slow_ms));
    if (i == 3) return core::CorruptData("frame 3: truncated PNG");
    out->seq = i;
    out->bgr.setTo(static_cast<double>(i));
    return core::Status::Ok();
  };
  return log;
}

SensorStreamsConfig small_streams() {
  SensorStreamsConfig c;
  c.width = 8;
  c.height = 6;
  c.frame_pool_size = 3;
  c.frame_capacity = 2;
  return c;
}

struct Delivered {
  std::vector<int64_t> imu_t;
  std::vector<uint64_t> frame_seq;
  std::vector<int64_t> frame_t;
};

// Polls every 5 ms of source time and consumes everything, like the scheduler's tasks.
Delivered run_replay(int slow_ms, SourceCounters* counters) {
  SensorStreams streams(small_streams());
  auto src = ReplaySource::create(synthetic_log(slow_ms), &streams);
  EXPECT_TRUE(src.ok()) << src.status().to_string();
  Delivered d;
  for (int64_t t = 1'000 * kMs; !src.value()->finished(); t += 5 * kMs) {
    EXPECT_TRUE(src.value()->poll(t, &streams).ok());
    ImuSample s;
    while (streams.imu.try_pop(s)) {
      EXPECT_LE(s.t_ns, t);
      d.imu_t.push_back(s.t_ns);
    }
    RgbdFrame* f = nullptr;
    while (streams.frames.try_pop(f)) {
      EXPECT_LE(f->t_ns, t);
      d.frame_seq.push_back(f->seq);
      d.frame_t.push_back(f->t_ns);
      streams.frame_pool.release(f);
    }
  }
  *counters = src.value()->counters();
  src.value().reset();
  EXPECT_EQ(streams.frame_pool.available(), 3u) << "a pooled frame leaked";
  return d;
}

TEST(ReplaySource, GivenALogWhenPolledToTheEndThenEverySampleArrivesOnceInOrder) {
  SourceCounters c;
  const Delivered d = run_replay(0, &c);
  ASSERT_EQ(d.imu_t.size(), 400u);
  for (size_t i = 1; i < d.imu_t.size(); ++i) EXPECT_GT(d.imu_t[i], d.imu_t[i - 1]);
  EXPECT_EQ(d.frame_seq, (std::vector<uint64_t>{0, 1, 2, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(c.frames, 9u);
  EXPECT_EQ(c.frame_errors, 1u);
  EXPECT_EQ(c.frames_dropped, 0u);
  EXPECT_EQ(c.imu, 400u);
}

TEST(ReplaySource, GivenASlowDiskWhenReplayedThenTheDeliveryIsIdentical) {
  SourceCounters fast_c, slow_c;
  const Delivered fast = run_replay(0, &fast_c);
  const Delivered slow = run_replay(15, &slow_c);
  EXPECT_EQ(fast.frame_seq, slow.frame_seq);
  EXPECT_EQ(fast.frame_t, slow.frame_t);
  EXPECT_EQ(fast.imu_t, slow.imu_t);
}

TEST(ReplaySource, GivenAPipelineThatNeverConsumesWhenPolledThenFramesAreDroppedNotLeaked) {
  SensorStreams streams(small_streams());
  auto src = ReplaySource::create(synthetic_log(0), &streams);
  ASSERT_TRUE(src.ok());
  for (int64_t t = 1'000 * kMs; t <= 3'000 * kMs; t += 5 * kMs)
    ASSERT_TRUE(src.value()->poll(t, &streams).ok());
  // The ring holds 2 frames; the third pool frame is decoded, finds the ring full and is dropped
  // back into the pool, so the replay goes on without waiting forever.
  EXPECT_EQ(streams.frames.size(), 2u);
  EXPECT_EQ(src.value()->counters().frames, 2u);
  src.value().reset();
  RgbdFrame* f = nullptr;
  while (streams.frames.try_pop(f)) streams.frame_pool.release(f);
  EXPECT_EQ(streams.frame_pool.available(), 3u);
}

TEST(ReplaySource, GivenUnsortedSamplesWhenCreatedThenAClearError) {
  SensorStreams streams(small_streams());
  ReplayLog log = synthetic_log(0);
  std::swap(log.imu[10], log.imu[11]);
  auto src = ReplaySource::create(std::move(log), &streams);
  ASSERT_FALSE(src.ok());
  EXPECT_NE(src.status().message().find("IMU samples are not in time order"), std::string::npos);
}

TEST(DatasetLog, GivenTheTumTeddyFolderWhenOpenedThenAllAssociatedFramesReplay) {
  HWR_REQUIRE_DATASET(testing::kTeddyDir);
  auto log = open_dataset_log("tum:" + testing::kTeddyDir);
  ASSERT_TRUE(log.ok()) << log.status().to_string();
  EXPECT_EQ(log->frame_t_ns.size(), 193u);
  EXPECT_FALSE(log->info.has_imu);
  SensorStreamsConfig cfg;
  SensorStreams streams(cfg);
  auto src = ReplaySource::create(std::move(log.value()), &streams);
  ASSERT_TRUE(src.ok());
  uint64_t frames = 0;
  for (int64_t t = src.value()->info().first_t_ns; !src.value()->finished(); t += 5 * kMs) {
    ASSERT_TRUE(src.value()->poll(t, &streams).ok());
    RgbdFrame* f = nullptr;
    while (streams.frames.try_pop(f)) {
      ++frames;
      EXPECT_EQ(f->bgr.cols, 640);
      streams.frame_pool.release(f);
    }
  }
  EXPECT_EQ(frames, 193u);
}

TEST(DatasetLog, GivenBadSpecsWhenOpenedThenOneClearLine) {
  auto a = open_dataset_log("tum:/nonexistent/folder");
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("/nonexistent/folder: no such folder"), std::string::npos);
  auto b = open_dataset_log("kinect:/tmp");
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("unknown kind 'kinect'"), std::string::npos);
  auto c = open_dataset_log("no-colon");
  ASSERT_FALSE(c.ok());
}

}  // namespace
}  // namespace hwr::hal
