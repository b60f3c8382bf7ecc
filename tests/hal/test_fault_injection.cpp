// Fault injection over replay logs: the spec text round-trips and every malformed token is named;
// on synthetic and TUM teddy logs each fault does exactly what the spec says (frames and IMU
// samples in the window removed, colour scaled and saturated, the asked fraction of depth turned
// into NaN or 0 with the same rectangles for the same seed), and the faulted log still replays.

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "hal/hal_test_util.hpp"
#include "hwr/hal/fault_injection.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::hal {
namespace {

constexpr int64_t kMs = 1'000'000;
constexpr int64_t kS = 1'000'000'000;

void expect_same_spec(const FaultSpec& a, const FaultSpec& b) {
  ASSERT_EQ(a.camera_dropouts.size(), b.camera_dropouts.size());
  for (size_t i = 0; i < a.camera_dropouts.size(); ++i) {
    EXPECT_EQ(a.camera_dropouts[i].start_s, b.camera_dropouts[i].start_s);
    EXPECT_EQ(a.camera_dropouts[i].duration_s, b.camera_dropouts[i].duration_s);
  }
  ASSERT_EQ(a.imu_dropouts.size(), b.imu_dropouts.size());
  for (size_t i = 0; i < a.imu_dropouts.size(); ++i) {
    EXPECT_EQ(a.imu_dropouts[i].start_s, b.imu_dropouts[i].start_s);
    EXPECT_EQ(a.imu_dropouts[i].duration_s, b.imu_dropouts[i].duration_s);
  }
  ASSERT_EQ(a.exposure_jumps.size(), b.exposure_jumps.size());
  for (size_t i = 0; i < a.exposure_jumps.size(); ++i) {
    EXPECT_EQ(a.exposure_jumps[i].at_s, b.exposure_jumps[i].at_s);
    EXPECT_EQ(a.exposure_jumps[i].gain, b.exposure_jumps[i].gain);
  }
  ASSERT_EQ(a.depth_holes.size(), b.depth_holes.size());
  for (size_t i = 0; i < a.depth_holes.size(); ++i) {
    EXPECT_EQ(a.depth_holes[i].start_s, b.depth_holes[i].start_s);
    EXPECT_EQ(a.depth_holes[i].duration_s, b.depth_holes[i].duration_s);
    EXPECT_EQ(a.depth_holes[i].fraction, b.depth_holes[i].fraction);
    EXPECT_EQ(a.depth_holes[i].value_nan, b.depth_holes[i].value_nan);
  }
  EXPECT_EQ(a.seed, b.seed);
}

TEST(FaultSpec, GivenTheIssueExampleWhenParsedThenEveryFieldIsSetAndFormatGivesTheTextBack) {
  const std::string text =
      "dropout=30:2,exposure=40:2.5,depth-nan=10:5:0.3,depth-zero=12:1:1,imu-dropout=50:0.5,seed=7";
  auto spec = parse_fault_spec(text);
  ASSERT_TRUE(spec.ok()) << spec.status().to_string();
  ASSERT_EQ(spec->camera_dropouts.size(), 1u);
  EXPECT_EQ(spec->camera_dropouts[0].start_s, 30.0);
  EXPECT_EQ(spec->camera_dropouts[0].duration_s, 2.0);
  ASSERT_EQ(spec->exposure_jumps.size(), 1u);
  EXPECT_EQ(spec->exposure_jumps[0].at_s, 40.0);
  EXPECT_EQ(spec->exposure_jumps[0].gain, 2.5);
  ASSERT_EQ(spec->depth_holes.size(), 2u);
  EXPECT_EQ(spec->depth_holes[0].start_s, 10.0);
  EXPECT_EQ(spec->depth_holes[0].duration_s, 5.0);
  EXPECT_EQ(spec->depth_holes[0].fraction, 0.3);
  EXPECT_TRUE(spec->depth_holes[0].value_nan);
  EXPECT_FALSE(spec->depth_holes[1].value_nan);
  EXPECT_EQ(spec->depth_holes[1].fraction, 1.0);
  ASSERT_EQ(spec->imu_dropouts.size(), 1u);
  EXPECT_EQ(spec->imu_dropouts[0].start_s, 50.0);
  EXPECT_EQ(spec->imu_dropouts[0].duration_s, 0.5);
  EXPECT_EQ(spec->seed, 7u);
  EXPECT_FALSE(spec->empty());
  EXPECT_EQ(format_fault_spec(*spec), text);
}

TEST(FaultSpec, GivenAwkwardDoublesWhenFormattedAndParsedThenTheSpecIsBitIdentical) {
  FaultSpec spec;
  spec.camera_dropouts = {{0.1 + 0.2, 1.0 / 3.0}, {1e-7, 123456.789}};
  spec.exposure_jumps = {{2.0 / 3.0, 0.1}, {0.0, 1e3}};
  spec.depth_holes = {{0.0, 1e9, 0.3, true}, {5.5, 0.7, 1e-3, false}};
  spec.imu_dropouts = {{std::nextafter(2.0, 3.0), 0.005}};
  spec.seed = 18446744073709551615ull;
  auto back = parse_fault_spec(format_fault_spec(spec));
  ASSERT_TRUE(back.ok()) << back.status().to_string() << " for " << format_fault_spec(spec);
  expect_same_spec(spec, *back);
}

TEST(FaultSpec, GivenAnEmptyTextWhenParsedThenTheSpecIsEmpty) {
  auto spec = parse_fault_spec("  ");
  ASSERT_TRUE(spec.ok());
  EXPECT_TRUE(spec->empty());
  EXPECT_EQ(format_fault_spec(*spec), "");
}

TEST(FaultSpec, GivenABadTokenWhenParsedThenAOneLineErrorNamesTheTokenAndTheProblem) {
  const struct {
    const char* text;
    const char* token;
    const char* problem;
  } cases[] = {
      {"dropout=30:-2", "'dropout=30:-2'", "duration -2 must be > 0"},
      {"dropout=30:0", "'dropout=30:0'", "duration 0 must be > 0"},
      {"imu-dropout=-1:2", "'imu-dropout=-1:2'", "start -1 must be a finite time >= 0"},
      {"exposure=40:0", "'exposure=40:0'", "gain 0 must be finite and > 0"},
      {"exposure=40:-2.5", "'exposure=40:-2.5'", "gain -2.5 must be finite and > 0"},
      {"depth-nan=1:2:0", "'depth-nan=1:2:0'", "fraction 0 must be in (0, 1]"},
      {"depth-zero=1:2:1.5", "'depth-zero=1:2:1.5'", "fraction 1.5 must be in (0, 1]"},
      {"depth-nan=1:-2:0.5", "'depth-nan=1:-2:0.5'", "duration -2 must be > 0"},
      {"dropout=1:2,blur=3:1", "'blur=3:1'", "unknown key 'blur'"},
      {"dropout=30", "'dropout=30'", "expected dropout=START:DURATION, got 1 value(s)"},
      {"depth-nan=1:2", "'depth-nan=1:2'", "expected depth-nan=START:DURATION:FRACTION, got 2 value(s)"},
      {"exposure=", "'exposure='", "missing value, expected exposure=AT:GAIN"},
      {"dropout=1:", "'dropout=1:'", "missing value"},
      {"dropout", "'dropout'", "expected KEY=VALUE"},
      {"dropout=1:abc", "'dropout=1:abc'", "'abc' is not a finite number"},
      {"dropout=1:inf", "'dropout=1:inf'", "'inf' is not a finite number"},
      {"dropout=1:2s", "'dropout=1:2s'", "'2s' is not a finite number"},
      {"seed=-3", "'seed=-3'", "not an unsigned integer"},
      {"seed=", "'seed='", "missing value, expected seed=N"},
      {"dropout=1:2,,exposure=1:2", "'dropout=1:2,,exposure=1:2'", "empty token"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.text);
    auto spec = parse_fault_spec(c.text);
    ASSERT_FALSE(spec.ok());
    testing::expect_one_line_error(spec.status(), c.token);
    testing::expect_one_line_error(spec.status(), c.problem);
  }
}

// 10 s of 200 Hz IMU from t0, frames at 10 Hz starting 0.5 s later; each frame's colour is its
// original index, depth 2 m except a 0 (invalid) first row.
ReplayLog synthetic_log() {
  ReplayLog log;
  log.info.name = "synthetic";
  const int64_t t0 = 1'000 * kS;
  for (int i = 0; i < 2000; ++i) {
    ImuSample s;
    s.t_ns = t0 + i * 5 * kMs;
    log.imu.push_back(s);
  }
  for (int i = 0; i < 95; ++i) log.frame_t_ns.push_back(t0 + 500 * kMs + i * 100 * kMs);
  log.info.first_t_ns = t0;
  log.info.last_t_ns = log.imu.back().t_ns;
  log.load_frame = [](size_t i, RgbdFrame* out) -> core::Status {
    out->bgr.create(48, 64, CV_8UC3);
    out->bgr.setTo(cv::Scalar::all(static_cast<double>(i)));
    out->depth_m.create(48, 64, CV_32FC1);
    out->depth_m.setTo(2.0);
    out->depth_m.row(0).setTo(0.0);
    out->invalid_depth_px = 64;
    out->seq = i;
    return core::Status::Ok();
  };
  return log;
}

TEST(ApplyFaults, GivenImuAndCameraDropoutsWhenAppliedThenExactlyTheSamplesInTheWindowsGo) {
  const ReplayLog original = synthetic_log();
  auto spec = parse_fault_spec("dropout=2:1.5,imu-dropout=4:0.5,imu-dropout=9.99:1");
  ASSERT_TRUE(spec.ok());
  std::shared_ptr<FaultReport> report;
  auto faulted = apply_faults(original, *spec, &report);
  ASSERT_TRUE(faulted.ok()) << faulted.status().to_string();
  ASSERT_NE(report, nullptr);

  // Times count from the first IMU sample (t0), not from the first frame (t0 + 0.5 s).
  const int64_t t0 = original.imu.front().t_ns;
  std::vector<int64_t> want_imu;
  for (const auto& s : original.imu) {
    const int64_t rel = s.t_ns - t0;
    if ((rel >= 4 * kS && rel < 4500 * kMs) || rel >= 9990 * kMs) continue;
    want_imu.push_back(s.t_ns);
  }
  ASSERT_EQ(want_imu.size(), 2000u - 100u - 2u);  // [4, 4.5) s at 200 Hz; 9.990 and 9.995 s
  ASSERT_EQ(faulted->imu.size(), want_imu.size());
  for (size_t i = 0; i < want_imu.size(); ++i) EXPECT_EQ(faulted->imu[i].t_ns, want_imu[i]);
  EXPECT_EQ(report->imu_removed.load(), 102u);

  // Frames at 0.5 + 0.1·i s: [2, 3.5) holds i = 15..29 (the start is in, the end is out).
  ASSERT_EQ(faulted->frame_t_ns.size(), 95u - 15u);
  EXPECT_EQ(report->frames_removed.load(), 15u);
  std::vector<size_t> want_index;
  for (size_t j = 0; j < original.frame_t_ns.size(); ++j) {
    if (j < 15 || j > 29) want_index.push_back(j);
  }
  RgbdFrame frame;
  for (size_t i = 0; i < faulted->frame_t_ns.size(); ++i) {
    EXPECT_EQ(faulted->frame_t_ns[i], original.frame_t_ns[want_index[i]]);
    // The wrapped loader reads the original frame of the same time.
    ASSERT_TRUE(faulted->load_frame(i, &frame).ok());
    EXPECT_EQ(frame.seq, want_index[i]);
  }
  EXPECT_EQ(faulted->load_frame(faulted->frame_t_ns.size(), &frame).code(), core::ErrorCode::kOutOfRange);
  EXPECT_EQ(report->frames_exposure_changed.load(), 0u);
  EXPECT_EQ(report->frames_with_depth_holes.load(), 0u);
  // Untouched: the other streams, the time span.
  EXPECT_EQ(faulted->info.first_t_ns, original.info.first_t_ns);
}

TEST(ApplyFaults, GivenAnInvalidProgrammaticSpecWhenAppliedThenTheEntryIsNamed) {
  FaultSpec spec;
  spec.depth_holes.push_back({1.0, 2.0, 0.0, false});
  auto faulted = apply_faults(synthetic_log(), spec);
  ASSERT_FALSE(faulted.ok());
  testing::expect_one_line_error(faulted.status(), "'depth-zero=1:2:0'");
  testing::expect_one_line_error(faulted.status(), "fraction 0 must be in (0, 1]");
  spec.depth_holes.clear();
  spec.exposure_jumps.push_back({std::numeric_limits<double>::quiet_NaN(), 2.0});
  EXPECT_FALSE(apply_faults(synthetic_log(), spec).ok());
}

TEST(ApplyFaults, GivenAFullHoleOnASmallImageWhenLoadedThenEveryPixelIsHitAndOnlyValidOnesAreCounted) {
  FaultSpec spec;
  spec.depth_holes.push_back({0.0, 1e9, 1.0, false});
  auto faulted = apply_faults(synthetic_log(), spec);
  ASSERT_TRUE(faulted.ok());
  RgbdFrame frame;
  ASSERT_TRUE(faulted->load_frame(3, &frame).ok());
  EXPECT_EQ(cv::countNonZero(frame.depth_m), 0);
  EXPECT_EQ(frame.invalid_depth_px, 64u * 48u);  // the 64 already invalid are not counted twice
}

// --- TUM teddy -----------------------------------------------------------------------------------

ReplayLog open_teddy() {
  auto log = open_dataset_log("tum:" + testing::kTeddyDir);
  EXPECT_TRUE(log.ok()) << log.status().to_string();
  return log.ok() ? std::move(log).value() : ReplayLog{};
}

int count_nan(const cv::Mat& depth) {
  int n = 0;
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) n += std::isnan(depth.at<float>(y, x)) ? 1 : 0;
  }
  return n;
}

// Pixels where the holes went: NaN, or 0 where the original had a depth.
cv::Mat hole_mask(const cv::Mat& original, const cv::Mat& faulted) {
  cv::Mat mask(original.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < original.rows; ++y) {
    for (int x = 0; x < original.cols; ++x) {
      const float o = original.at<float>(y, x), f = faulted.at<float>(y, x);
      if (std::isnan(f) || (f == 0.0f && o != 0.0f)) mask.at<uint8_t>(y, x) = 255;
    }
  }
  return mask;
}

TEST(ApplyFaultsTeddy, GivenACameraDropoutWhenAppliedThenExactlyTheFramesInTheWindowAreRemoved) {
  HWR_REQUIRE_DATASET(testing::kTeddyDir);
  ReplayLog original = open_teddy();
  ASSERT_EQ(original.frame_t_ns.size(), 193u);
  auto spec = parse_fault_spec("dropout=1:2");
  ASSERT_TRUE(spec.ok());
  std::shared_ptr<FaultReport> report;
  auto faulted = apply_faults(original, *spec, &report);
  ASSERT_TRUE(faulted.ok()) << faulted.status().to_string();

  const int64_t t0 = original.frame_t_ns.front();
  std::vector<size_t> kept;
  for (size_t j = 0; j < original.frame_t_ns.size(); ++j) {
    const int64_t rel = original.frame_t_ns[j] - t0;
    if (rel < 1 * kS || rel >= 3 * kS) kept.push_back(j);
  }
  const size_t removed = original.frame_t_ns.size() - kept.size();
  EXPECT_GE(removed, 55u);  // ~2 s at ~30 Hz
  EXPECT_LE(removed, 62u);
  EXPECT_EQ(report->frames_removed.load(), removed);
  ASSERT_EQ(faulted->frame_t_ns.size(), kept.size());
  for (size_t i = 0; i < kept.size(); ++i) EXPECT_EQ(faulted->frame_t_ns[i], original.frame_t_ns[kept[i]]);

  // The first frame after the gap is the original frame at that time, pixel for pixel.
  size_t after_gap = 0;
  while (kept[after_gap] == after_gap) ++after_gap;
  RgbdFrame a, b;
  ASSERT_TRUE(faulted->load_frame(after_gap, &a).ok());
  ASSERT_TRUE(original.load_frame(kept[after_gap], &b).ok());
  EXPECT_EQ(a.t_ns, original.frame_t_ns[kept[after_gap]]);
  EXPECT_EQ(cv::norm(a.bgr, b.bgr, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.depth_m, b.depth_m, cv::NORM_INF), 0.0);
}

TEST(ApplyFaultsTeddy, GivenExposureJumpsWhenFramesLoadThenColourIsScaledAndSaturatedUntilTheNextJump) {
  HWR_REQUIRE_DATASET(testing::kTeddyDir);
  ReplayLog original = open_teddy();
  ASSERT_FALSE(original.frame_t_ns.empty());
  auto spec = parse_fault_spec("exposure=2:1.7,exposure=4:1");
  ASSERT_TRUE(spec.ok());
  std::shared_ptr<FaultReport> report;
  auto faulted = apply_faults(original, *spec, &report);
  ASSERT_TRUE(faulted.ok());

  const int64_t t0 = original.frame_t_ns.front();
  size_t before = 0, during = 0, after = 0;
  for (size_t i = 0; i < original.frame_t_ns.size(); ++i) {
    const int64_t rel = original.frame_t_ns[i] - t0;
    if (rel < 2 * kS) before = i;
    if (during == 0 && rel >= 2 * kS) during = i;
    if (after == 0 && rel >= 4 * kS) after = i;
  }
  RgbdFrame f, o;
  for (const size_t i : {before, after}) {
    ASSERT_TRUE(faulted->load_frame(i, &f).ok());
    ASSERT_TRUE(original.load_frame(i, &o).ok());
    EXPECT_EQ(cv::norm(f.bgr, o.bgr, cv::NORM_INF), 0.0) << "frame " << i << " should be unchanged";
  }
  ASSERT_TRUE(faulted->load_frame(during, &f).ok());
  ASSERT_TRUE(original.load_frame(during, &o).ok());
  // A dark pixel scales, a bright one saturates at 255; every pixel follows min(255, 1.7·v).
  int dark = 0, bright = 0;
  for (int y = 0; y < o.bgr.rows; ++y) {
    for (int x = 0; x < o.bgr.cols; ++x) {
      const cv::Vec3b ov = o.bgr.at<cv::Vec3b>(y, x), fv = f.bgr.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) {
        const double want = std::min(255.0, std::round(1.7 * ov[c]));
        ASSERT_NEAR(fv[c], want, 1.0)
            << "pixel " << x << "," << y << " channel " << c << " was " << int(ov[c]);
        if (ov[c] >= 20 && ov[c] <= 100) ++dark;
        if (ov[c] >= 160) {
          ASSERT_EQ(fv[c], 255);
          ++bright;
        }
      }
    }
  }
  EXPECT_GT(dark, 1000);
  EXPECT_GT(bright, 10);
  EXPECT_EQ(cv::norm(f.depth_m, o.depth_m, cv::NORM_INF), 0.0) << "exposure must not touch depth";
  EXPECT_EQ(report->frames_exposure_changed.load(), 1u);
}

TEST(ApplyFaultsTeddy, GivenDepthHolesWhenFramesLoadThenTheFractionIsCoveredWithNanOrZeroDeterministically) {
  HWR_REQUIRE_DATASET(testing::kTeddyDir);
  ReplayLog original = open_teddy();
  ASSERT_GT(original.frame_t_ns.size(), 100u);
  const auto faulted_with = [&](const std::string& text) {
    auto spec = parse_fault_spec(text);
    EXPECT_TRUE(spec.ok()) << spec.status().to_string();
    auto log = apply_faults(original, *spec);
    EXPECT_TRUE(log.ok());
    return std::move(log).value();
  };
  ReplayLog nan_log = faulted_with("depth-nan=1:2:0.3,seed=5");
  ReplayLog zero_log = faulted_with("depth-zero=1:2:0.3,seed=5");
  ReplayLog nan_log_again = faulted_with("depth-nan=1:2:0.3,seed=5");
  ReplayLog other_seed = faulted_with("depth-nan=1:2:0.3,seed=6");

  const size_t k = 60;  // ~2 s in: inside the window
  const size_t outside = 10;
  RgbdFrame o, n, z, n2, s;
  ASSERT_TRUE(original.load_frame(k, &o).ok());
  ASSERT_TRUE(nan_log.load_frame(k, &n).ok());
  ASSERT_TRUE(zero_log.load_frame(k, &z).ok());
  ASSERT_TRUE(nan_log_again.load_frame(k, &n2).ok());
  ASSERT_TRUE(other_seed.load_frame(k, &s).ok());
  const int total = static_cast<int>(o.depth_m.total());
  ASSERT_EQ(count_nan(o.depth_m), 0);

  // NaN: the covered fraction is the asked one, and every other pixel is untouched.
  const int nan_px = count_nan(n.depth_m);
  EXPECT_NEAR(static_cast<double>(nan_px) / total, 0.3, 0.05);
  int changed_outside = 0, newly_invalid = 0;
  for (int y = 0; y < o.depth_m.rows; ++y) {
    for (int x = 0; x < o.depth_m.cols; ++x) {
      const float ov = o.depth_m.at<float>(y, x), nv = n.depth_m.at<float>(y, x);
      if (std::isnan(nv)) {
        newly_invalid += ov > 0 ? 1 : 0;
      } else if (nv != ov) {
        ++changed_outside;
      }
    }
  }
  EXPECT_EQ(changed_outside, 0);
  EXPECT_GT(newly_invalid, total / 10);
  EXPECT_EQ(n.invalid_depth_px, o.invalid_depth_px + static_cast<uint32_t>(newly_invalid));
  EXPECT_EQ(cv::norm(n.bgr, o.bgr, cv::NORM_INF), 0.0) << "holes must not touch colour";

  // Zero: no NaN, the same rectangles (same seed), counted the same.
  EXPECT_EQ(count_nan(z.depth_m), 0);
  const cv::Mat nan_valid_holes = hole_mask(o.depth_m, n.depth_m) & (o.depth_m > 0);
  EXPECT_EQ(cv::countNonZero(hole_mask(o.depth_m, z.depth_m) != nan_valid_holes), 0);
  EXPECT_EQ(z.invalid_depth_px, n.invalid_depth_px);

  // Deterministic: same seed, same holes; another seed, other holes of the same size.
  EXPECT_EQ(cv::countNonZero(hole_mask(o.depth_m, n.depth_m) != hole_mask(o.depth_m, n2.depth_m)), 0);
  const cv::Mat other = hole_mask(o.depth_m, s.depth_m);
  EXPECT_GT(cv::countNonZero(other != hole_mask(o.depth_m, n.depth_m)), total / 10);
  EXPECT_NEAR(static_cast<double>(count_nan(s.depth_m)) / total, 0.3, 0.05);

  // Another frame in the window gets other holes; a frame outside the window none.
  RgbdFrame o2, n3;
  ASSERT_TRUE(original.load_frame(k + 1, &o2).ok());
  ASSERT_TRUE(nan_log.load_frame(k + 1, &n3).ok());
  EXPECT_GT(cv::countNonZero(hole_mask(o2.depth_m, n3.depth_m) != hole_mask(o.depth_m, n.depth_m)),
            total / 10);
  ASSERT_TRUE(original.load_frame(outside, &o).ok());
  ASSERT_TRUE(nan_log.load_frame(outside, &n).ok());
  EXPECT_EQ(count_nan(n.depth_m), 0);
  EXPECT_EQ(cv::norm(n.depth_m, o.depth_m, cv::NORM_INF), 0.0);
}

TEST(ApplyFaultsTeddy, GivenEveryFaultWhenReplayedThroughReplaySourceThenTheRunCompletesAndCountsMatch) {
  HWR_REQUIRE_DATASET(testing::kTeddyDir);
  ReplayLog original = open_teddy();
  ASSERT_EQ(original.frame_t_ns.size(), 193u);
  auto spec = parse_fault_spec("dropout=1:2,exposure=4:2.5,depth-nan=3.5:1:0.3,depth-zero=5:10:0.5");
  ASSERT_TRUE(spec.ok());
  std::shared_ptr<FaultReport> report;
  auto faulted = apply_faults(original, *spec, &report);
  ASSERT_TRUE(faulted.ok());

  const int64_t t0 = original.frame_t_ns.front();
  uint64_t want_exposure = 0, want_holes = 0, want_frames = 0;
  for (const int64_t t : original.frame_t_ns) {
    const int64_t rel = t - t0;
    if (rel >= 1 * kS && rel < 3 * kS) continue;
    ++want_frames;
    want_exposure += rel >= 4 * kS ? 1 : 0;
    want_holes += (rel >= 3500 * kMs && rel < 4500 * kMs) || rel >= 5 * kS ? 1 : 0;
  }

  SensorStreams streams(SensorStreamsConfig{});
  auto src = ReplaySource::create(std::move(faulted).value(), &streams);
  ASSERT_TRUE(src.ok()) << src.status().to_string();
  uint64_t frames = 0, nan_frames = 0;
  for (int64_t t = src.value()->info().first_t_ns; !src.value()->finished(); t += 5 * kMs) {
    ASSERT_TRUE(src.value()->poll(t, &streams).ok());
    RgbdFrame* f = nullptr;
    while (streams.frames.try_pop(f)) {
      ++frames;
      EXPECT_FALSE(f->t_ns - t0 >= 1 * kS && f->t_ns - t0 < 3 * kS) << "a dropped frame was delivered";
      nan_frames += count_nan(f->depth_m) > 0 ? 1 : 0;
      streams.frame_pool.release(f);
    }
  }
  EXPECT_EQ(frames, want_frames);
  EXPECT_EQ(src.value()->counters().frame_errors, 0u);
  EXPECT_EQ(report->frames_removed.load(), 193u - want_frames);
  EXPECT_EQ(report->frames_exposure_changed.load(), want_exposure);
  EXPECT_EQ(report->frames_with_depth_holes.load(), want_holes);
  EXPECT_GE(nan_frames, 25u);  // [3.5, 4.5) s at ~30 Hz
  EXPECT_LE(nan_frames, 32u);
}

}  // namespace
}  // namespace hwr::hal
