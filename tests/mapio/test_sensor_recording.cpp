// SensorRecorder → LCM log → open_recording_log: what goes in comes back (samples exactly, the left
// and right images byte for byte, depth to the millimetre with "none" kept as none), a log cut at any
// event boundary or inside an event opens with what is whole, a damaged event is skipped and
// counted, and files that are not recordings are refused with a clear error.
#include "hwr/mapio/recording_log.hpp"
#include "hwr/mapio/sensor_recorder.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <unistd.h>

#include <opencv2/core.hpp>

namespace hwr::mapio {
namespace {

constexpr int kW = 32, kH = 24;

std::string temp_path(const std::string& name) {
  return ::testing::TempDir() + "hwr_rec_" + std::to_string(::getpid()) + "_" + name + ".lcmlog";
}

hal::SourceInfo stereo_info() {
  hal::SourceInfo info;
  info.name = "test:rig";
  info.intrinsics.width = kW;
  info.intrinsics.height = kH;
  info.intrinsics.fx = 30;
  info.intrinsics.fy = 31;
  info.intrinsics.cx = 15.5;
  info.intrinsics.cy = 11.5;
  info.T_imu_cam.translation() = Eigen::Vector3d(0.1, -0.02, 0.03);
  info.T_imu_cam.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  info.gnss_antenna_imu_m = Eigen::Vector3d(0.5, 0, 1.2);
  info.mag_hard_iron_uT = Eigen::Vector3d(3, -4, 5);
  info.has_imu = info.has_mag = info.has_gnss = true;
  info.stereo = true;
  info.camera_rate_hz = 30;
  info.imu_rate_hz = 400;
  info.first_t_ns = 1'000'000'000;
  return info;
}

hal::RgbdFrame make_frame(int k) {
  hal::RgbdFrame f;
  f.t_ns = int64_t{1'000'000'000} + int64_t{k} * 33'333'333;
  f.bgr.create(kH, kW, CV_8UC3);
  f.depth_m.create(kH, kW, CV_32FC1);
  f.right_gray.create(kH, kW, CV_8UC1);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      f.bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x * 7 + k), static_cast<uint8_t>(y * 9),
                                            static_cast<uint8_t>(x + y + 3 * k));
      f.depth_m.at<float>(y, x) = 0.5f + 0.01234f * static_cast<float>(x + y) + 0.1f * static_cast<float>(k);
      f.right_gray.at<uint8_t>(y, x) = static_cast<uint8_t>(x * y + k);
    }
  }
  f.depth_m.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  f.depth_m.at<float>(0, 1) = 0.0f;
  f.depth_m.at<float>(0, 2) = -1.0f;
  f.depth_m.at<float>(0, 3) = 70.0f;  // beyond 65.535 m
  return f;
}

// A recording of 2 s: 400 Hz IMU, 50 Hz mag, 5 Hz GNSS, 10 frames.
void write_recording(const std::string& path, SensorRecorderCounters* counters = nullptr,
                     const SensorRecorderConfig& config = {}) {
  auto rec = SensorRecorder::open(path, stereo_info(), config);
  ASSERT_TRUE(rec.ok()) << rec.status().message();
  for (int i = 0; i < 800; ++i) {
    hal::ImuSample s;
    s.t_ns = int64_t{1'000'000'000} + int64_t{i} * 2'500'000;
    s.accel_mps2 = Eigen::Vector3d(0.01 * i, -0.5, 9.81);
    s.gyro_radps = Eigen::Vector3d(0.001, 0.002 * i, -0.003);
    ASSERT_TRUE((*rec)->record_imu(s));
    if (i % 8 == 0) {
      hal::MagSample m;
      m.t_ns = s.t_ns;
      m.field_uT = Eigen::Vector3d(20, -3, 40 + i);
      ASSERT_TRUE((*rec)->record_mag(m));
    }
    if (i % 80 == 0) {
      hal::GnssFix g;
      g.t_ns = s.t_ns;
      g.fix_type = 3;
      g.num_sv = 12;
      g.lat_deg = 63.374473 + 1e-7 * i;
      g.lon_deg = 10.340960;
      g.height_m = 120.5;
      g.h_acc_m = 0.8;
      g.v_acc_m = 1.5;
      ASSERT_TRUE((*rec)->record_gnss(g));
    }
    if (i % 80 == 40) {
      // The writer drains every 5 ms; 8 slots are plenty for one frame per 80 samples.
      while ((*rec)->counters().frames + 8 <= static_cast<uint64_t>(i / 80)) {
      }
      ASSERT_TRUE((*rec)->record_frame(make_frame(i / 80)));
    }
  }
  ASSERT_TRUE((*rec)->close().ok());
  if (counters != nullptr) *counters = (*rec)->counters();
}

std::vector<char> read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}
void write_all(const std::string& path, const std::vector<char>& bytes, size_t n) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(n));
}

TEST(SensorRecording, GivenARecordingThenEverySampleAndImageComesBack) {
  const std::string path = temp_path("roundtrip");
  SensorRecorderCounters written;
  write_recording(path, &written);
  EXPECT_EQ(written.imu, 800u);
  EXPECT_EQ(written.mag, 100u);
  EXPECT_EQ(written.gnss, 10u);
  EXPECT_EQ(written.frames, 10u);
  EXPECT_EQ(written.dropped, 0u);

  RecordingLogStats stats;
  auto log = open_recording_log(path, &stats);
  ASSERT_TRUE(log.ok()) << log.status().message();
  EXPECT_EQ(stats.undecodable + stats.bad_images + stats.incomplete_frames + stats.unknown_channels, 0u);
  const hal::SourceInfo& info = log->info;
  const hal::SourceInfo want = stereo_info();
  EXPECT_EQ(info.intrinsics.width, kW);
  EXPECT_EQ(info.intrinsics.fy, 31);
  EXPECT_EQ(info.intrinsics.cx, 15.5);
  EXPECT_TRUE(info.T_imu_cam.isApprox(want.T_imu_cam, 1e-15));
  EXPECT_EQ(info.gnss_antenna_imu_m, want.gnss_antenna_imu_m);
  EXPECT_EQ(info.mag_hard_iron_uT, want.mag_hard_iron_uT);
  EXPECT_TRUE(info.has_imu && info.has_mag && info.has_gnss && info.stereo);
  EXPECT_EQ(info.imu_rate_hz, 400);
  EXPECT_NE(info.name.find("test:rig"), std::string::npos);
  EXPECT_EQ(info.first_t_ns, 1'000'000'000);

  ASSERT_EQ(log->imu.size(), 800u);
  EXPECT_EQ(log->imu[123].t_ns, int64_t{1'000'000'000} + 123 * int64_t{2'500'000});
  EXPECT_EQ(log->imu[123].accel_mps2, Eigen::Vector3d(0.01 * 123, -0.5, 9.81));
  EXPECT_EQ(log->imu[123].gyro_radps, Eigen::Vector3d(0.001, 0.002 * 123, -0.003));
  ASSERT_EQ(log->mag.size(), 100u);
  EXPECT_EQ(log->mag[7].field_uT, Eigen::Vector3d(20, -3, 40 + 56));
  ASSERT_EQ(log->gnss.size(), 10u);
  EXPECT_EQ(log->gnss[2].lat_deg, 63.374473 + 1e-7 * 160);
  EXPECT_EQ(log->gnss[2].num_sv, 12);
  EXPECT_EQ(log->gnss[2].fix_type, 3);
  EXPECT_EQ(log->gnss[2].v_acc_m, 1.5);

  ASSERT_EQ(log->frame_t_ns.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    const hal::RgbdFrame want_f = make_frame(k);
    EXPECT_EQ(log->frame_t_ns[static_cast<size_t>(k)], want_f.t_ns);
    hal::RgbdFrame got;
    ASSERT_TRUE(log->load_frame(static_cast<size_t>(k), &got).ok());
    EXPECT_EQ(got.t_ns, want_f.t_ns);
    EXPECT_EQ(cv::norm(got.bgr, want_f.bgr, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(got.right_gray, want_f.right_gray, cv::NORM_INF), 0.0);
    EXPECT_EQ(got.intrinsics.fx, 30);
    // Depth: to the millimetre; NaN, 0, negative and past 65.535 m are all "none" (0).
    for (int x = 0; x < 4; ++x) EXPECT_EQ(got.depth_m.at<float>(0, x), 0.0f) << x;
    EXPECT_EQ(got.invalid_depth_px, 4u);
    for (int y = 1; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        ASSERT_NEAR(got.depth_m.at<float>(y, x), want_f.depth_m.at<float>(y, x), 0.0005 + 1e-6)
            << x << "," << y;
      }
    }
  }
  // Out of range: an error, not a crash.
  hal::RgbdFrame f;
  EXPECT_FALSE(log->load_frame(10, &f).ok());
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenAReplayRecordedWithTinyQueuesThenItWaitsForTheWriterAndDropsNothing) {
  const std::string path = temp_path("tiny");
  SensorRecorderConfig config;
  config.imu_capacity = 2;
  config.mag_capacity = 1;
  config.gnss_capacity = 1;
  config.frame_slots = 1;
  config.wait_when_full = true;
  SensorRecorderCounters written;
  write_recording(path, &written, config);
  EXPECT_EQ(written.imu, 800u);
  EXPECT_EQ(written.frames, 10u);
  EXPECT_EQ(written.dropped, 0u);
  auto log = open_recording_log(path);
  ASSERT_TRUE(log.ok()) << log.status().message();
  EXPECT_EQ(log->imu.size(), 800u);
  EXPECT_EQ(log->mag.size(), 100u);
  EXPECT_EQ(log->gnss.size(), 10u);
  EXPECT_EQ(log->frame_t_ns.size(), 10u);
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenALogCutAnywhereThenWhatIsWholeOpensAndNothingCrashes) {
  const std::string path = temp_path("whole");
  write_recording(path);
  const std::vector<char> bytes = read_all(path);
  const std::string cut = temp_path("cut");
  size_t last_frames = 0;
  // Cut at 200 places from the start to the end (inside events, on boundaries, inside images).
  for (int k = 1; k <= 200; ++k) {
    const size_t n = bytes.size() * static_cast<size_t>(k) / 200;
    write_all(cut, bytes, n);
    auto log = open_recording_log(cut);
    if (!log.ok()) {
      // Only a cut inside the first event (the recording's info) or before any sample is refused.
      EXPECT_EQ(log.status().code(), core::ErrorCode::kParseError) << n << ": " << log.status().message();
      continue;
    }
    EXPECT_GE(log->frame_t_ns.size(), last_frames) << n;  // a longer prefix never holds fewer frames
    last_frames = log->frame_t_ns.size();
    for (size_t i = 0; i < log->frame_t_ns.size(); ++i) {
      hal::RgbdFrame f;
      ASSERT_TRUE(log->load_frame(i, &f).ok()) << n << " frame " << i;
    }
  }
  EXPECT_EQ(last_frames, 10u);
  ::unlink(cut.c_str());
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenDamagedEventsThenTheyAreSkippedAndCounted) {
  const std::string path = temp_path("damaged");
  write_recording(path);
  std::vector<char> bytes = read_all(path);
  const size_t first_event_end = 400;  // past the recording info (28-byte header, channel, 305 bytes)
  // Flip a byte at 300 places spread over the rest of the file (headers, payloads, images).
  for (int k = 1; k < 300; ++k) {
    bytes[first_event_end + (bytes.size() - first_event_end) * static_cast<size_t>(k) / 300] ^= 0x5A;
  }
  const std::string bad = temp_path("damaged_out");
  write_all(bad, bytes, bytes.size());
  RecordingLogStats stats;
  auto log = open_recording_log(bad, &stats);
  ASSERT_TRUE(log.ok()) << log.status().message();
  EXPECT_GT(stats.undecodable + stats.resyncs, 0u);
  EXPECT_LT(log->imu.size(), 800u);  // some samples were hit...
  EXPECT_GT(log->imu.size(), 600u);  // ...most were not, and the reader found its way past each hit
  EXPECT_GE(log->imu.back().t_ns, int64_t{1'000'000'000} + 790 * int64_t{2'500'000});
  // A flipped time stamp does not get through: each sample's t_ns agrees with the event's µs stamp,
  // so it is within a microsecond of a time write_recording used.
  for (const hal::ImuSample& s : log->imu) {
    const int64_t i = (s.t_ns - 1'000'000'000) / 2'500'000;
    ASSERT_NEAR(static_cast<double>(s.t_ns), static_cast<double>(1'000'000'000 + i * 2'500'000), 999.0);
    ASSERT_GE(i, 0);
    ASSERT_LT(i, 800);
  }
  EXPECT_LE(log->frame_t_ns.size(), 10u);
  for (size_t i = 0; i < log->frame_t_ns.size(); ++i) {
    hal::RgbdFrame f;
    (void)log->load_frame(i, &f);  // whatever is indexed loads or says why, without crashing
  }
  ::unlink(bad.c_str());
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenLengthFieldsThatLieThenTheLogIsRefusedOrSkippedWithoutThrowing) {
  const std::string path = temp_path("lengths");
  write_recording(path);
  const std::vector<char> bytes = read_all(path);
  // The first event: 28-byte header, the channel HWR_RECORDING_INFO, then recording_info_t whose
  // source_name length is at byte 16 of the message (after the fingerprint and t_ns). LCM's decoder
  // would copy length - 1 bytes: 0 and negative lengths threw std::length_error (fuzz_recording_log).
  const size_t name_length_at = 28 + std::string("HWR_RECORDING_INFO").size() + 16;
  const std::string bad = temp_path("lengths_out");
  for (const uint32_t length : {0u, 0xFFFFFFFFu, 0x80000000u, 0x7FFFFFFFu}) {
    std::vector<char> b = bytes;
    for (int i = 0; i < 4; ++i) b[name_length_at + i] = static_cast<char>(length >> (24 - 8 * i));
    write_all(bad, b, b.size());
    auto log = open_recording_log(bad);
    ASSERT_FALSE(log.ok()) << length;
    EXPECT_NE(log.status().message().find("not a sensor recording"), std::string::npos)
        << log.status().message();
  }
  // An event whose data length points past the end of the file: skipped to the next sync word, not
  // believed (LCM's reader would allocate it), and the samples after it are still read.
  std::vector<char> b = bytes;
  const size_t second_event =
      28 + std::string("HWR_RECORDING_INFO").size() +
      ((static_cast<uint8_t>(bytes[24]) << 24) | (static_cast<uint8_t>(bytes[25]) << 16) |
       (static_cast<uint8_t>(bytes[26]) << 8) | static_cast<uint8_t>(bytes[27]));
  for (int i = 0; i < 4; ++i) b[second_event + 24 + i] = static_cast<char>(0x7F);
  write_all(bad, b, b.size());
  RecordingLogStats stats;
  auto log = open_recording_log(bad, &stats);
  ASSERT_TRUE(log.ok()) << log.status().message();
  EXPECT_EQ(stats.resyncs, 1u);
  EXPECT_EQ(log->imu.size(), 799u);
  EXPECT_EQ(log->frame_t_ns.size(), 10u);
  ::unlink(bad.c_str());
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenNonFiniteSamplesRecordedThenTheReplayLeavesThemOutAndCountsThem) {
  const std::string path = temp_path("non_finite");
  {
    auto rec = SensorRecorder::open(path, stereo_info());
    ASSERT_TRUE(rec.ok());
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int i = 0; i < 4; ++i) {
      hal::ImuSample s;
      s.t_ns = int64_t{1'000'000'000} + i * 2'500'000;
      s.accel_mps2 = Eigen::Vector3d(0, 0, i == 1 ? nan : 9.81);
      ASSERT_TRUE((*rec)->record_imu(s));
      hal::MagSample m;
      m.t_ns = s.t_ns;
      m.field_uT = Eigen::Vector3d(20, i == 2 ? nan : 0, 40);
      ASSERT_TRUE((*rec)->record_mag(m));
      hal::GnssFix g;
      g.t_ns = s.t_ns;
      g.lat_deg = i == 3 ? nan : 63.4;
      g.lon_deg = i == 0 ? 200.0 : 10.3;  // out of range
      ASSERT_TRUE((*rec)->record_gnss(g));
    }
    ASSERT_TRUE((*rec)->close().ok());
  }
  RecordingLogStats stats;
  auto log = open_recording_log(path, &stats);
  ASSERT_TRUE(log.ok()) << log.status().message();
  EXPECT_EQ(log->imu.size(), 3u);
  EXPECT_EQ(log->mag.size(), 3u);
  EXPECT_EQ(log->gnss.size(), 2u);
  EXPECT_EQ(stats.undecodable, 4u);
  ::unlink(path.c_str());
}

TEST(SensorRecording, GivenFilesThatAreNotRecordingsThenTheErrorSaysSo) {
  auto missing = open_recording_log("/nonexistent/run.lcmlog");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), core::ErrorCode::kNotFound);
  EXPECT_NE(missing.status().message().find("/nonexistent/run.lcmlog"), std::string::npos);

  const std::string junk = temp_path("junk");
  std::ofstream(junk) << "this is not an LCM log\n";
  auto j = open_recording_log(junk);
  ASSERT_FALSE(j.ok());
  EXPECT_EQ(j.status().code(), core::ErrorCode::kParseError);
  EXPECT_NE(j.status().message().find("not a sensor recording"), std::string::npos) << j.status().message();
  ::unlink(junk.c_str());
}

TEST(SensorRecorder, GivenAnUnwritablePathOrAWrongFrameThenTheErrorOrTheDropIsReported) {
  auto bad = SensorRecorder::open("/nonexistent/dir/run.lcmlog", stereo_info());
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), core::ErrorCode::kIoError);
  EXPECT_NE(bad.status().message().find("/nonexistent/dir/run.lcmlog"), std::string::npos);

  const std::string path = temp_path("wrong_frame");
  auto rec = SensorRecorder::open(path, stereo_info());
  ASSERT_TRUE(rec.ok());
  hal::RgbdFrame f = make_frame(0);
  f.right_gray.release();  // a stereo recording needs the right image
  EXPECT_FALSE((*rec)->record_frame(f));
  hal::RgbdFrame small = make_frame(0);
  small.bgr = cv::Mat(kH / 2, kW, CV_8UC3);
  EXPECT_FALSE((*rec)->record_frame(small));
  ASSERT_TRUE((*rec)->close().ok());
  EXPECT_EQ((*rec)->counters().dropped, 2u);
  EXPECT_EQ((*rec)->counters().frames, 0u);
  ::unlink(path.c_str());
}

}  // namespace
}  // namespace hwr::mapio
