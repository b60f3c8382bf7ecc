// `hwr-bench record`: what `hwr-robot --record` costs and how fast it writes, for the ZED 2i's
// 1280x720 stereo frames (left colour, depth, right; mapio/sensor_recorder.hpp). Measured in one run:
//  - the camera task's cost of record_frame (copy into a preallocated slot, depth m -> mm);
//  - the recorder's sustained write rate (image_t encoding + lcm::LogFile), waiting for the writer;
//  - the peer: the same bytes written with plain fwrite to the same folder (the disk's ceiling here);
//  - the rate a live 30 Hz recording needs.
// Usage: hwr-bench record [--frames=N] [--width=W] [--height=H] [--dir=DIR] (default 120 frames,
// 1280x720, $TMPDIR or /tmp). Ends with key=value lines.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <unistd.h>

#include <opencv2/core.hpp>

#include "bench_command.hpp"
#include "hwr/mapio/sensor_recorder.hpp"

namespace hwr::bench {
namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int run_record(int argc, char** argv) {
  int frames = 120, width = 1280, height = 720;
  const char* tmp = std::getenv("TMPDIR");
  std::string dir = tmp != nullptr ? tmp : "/tmp";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--frames=", 0) == 0) {
      frames = std::atoi(a.c_str() + 9);
    } else if (a.rfind("--width=", 0) == 0) {
      width = std::atoi(a.c_str() + 8);
    } else if (a.rfind("--height=", 0) == 0) {
      height = std::atoi(a.c_str() + 9);
    } else if (a.rfind("--dir=", 0) == 0) {
      dir = a.substr(6);
    } else {
      std::fprintf(stderr, "hwr-bench record: unknown option '%s'\n", a.c_str());
      return 2;
    }
  }
  if (frames < 1 || width < 16 || height < 16) {
    std::fprintf(stderr, "hwr-bench record: --frames >= 1, --width and --height >= 16\n");
    return 2;
  }
  // One textured stereo frame (random pixels: nothing here compresses, as real images would not).
  hal::RgbdFrame f;
  f.bgr.create(height, width, CV_8UC3);
  f.right_gray.create(height, width, CV_8UC1);
  f.depth_m.create(height, width, CV_32FC1);
  cv::RNG rng(7);
  rng.fill(f.bgr, cv::RNG::UNIFORM, 0, 256);
  rng.fill(f.right_gray, cv::RNG::UNIFORM, 0, 256);
  rng.fill(f.depth_m, cv::RNG::UNIFORM, 0.3, 20.0);

  hal::SourceInfo info;
  info.name = "bench:record";
  info.intrinsics.width = width;
  info.intrinsics.height = height;
  info.intrinsics.fx = info.intrinsics.fy = 700;
  info.intrinsics.cx = width / 2.0;
  info.intrinsics.cy = height / 2.0;
  info.stereo = true;
  info.camera_rate_hz = 30;

  const std::string path = dir + "/hwr_bench_record_" + std::to_string(::getpid()) + ".lcmlog";
  mapio::SensorRecorderConfig config;
  config.wait_when_full = true;  // every frame written: the write rate is the writer's
  auto rec = mapio::SensorRecorder::open(path, info, config);
  if (!rec.ok()) {
    std::fprintf(stderr, "hwr-bench record: %s\n", rec.status().message().c_str());
    return 1;
  }
  std::vector<double> call_ms;
  call_ms.reserve(static_cast<size_t>(frames));
  const double t0 = now_s();
  for (int k = 0; k < frames; ++k) {
    f.t_ns = 1'000'000'000 + int64_t{k} * 33'333'333;
    const double c0 = now_s();
    (*rec)->record_frame(f);
    call_ms.push_back((now_s() - c0) * 1e3);
  }
  const core::Status closed = (*rec)->close();
  const double recorder_s = now_s() - t0;
  const mapio::SensorRecorderCounters c = (*rec)->counters();
  ::unlink(path.c_str());
  if (!closed.ok() || c.frames != static_cast<uint64_t>(frames)) {
    std::fprintf(stderr, "hwr-bench record: %s (%llu of %d frames written)\n", closed.message().c_str(),
                 static_cast<unsigned long long>(c.frames), frames);
    return 1;
  }
  // The call's cost while the writer keeps up: the frames slots are free for the first 8 calls.
  std::vector<double> free_slot(call_ms.begin(), call_ms.begin() + std::min<int>(frames, 8));
  std::sort(free_slot.begin(), free_slot.end());
  const double call_median_ms = free_slot[free_slot.size() / 2];

  // Peer: the same number of bytes with fwrite (one buffer per image, as the recorder's events).
  const size_t frame_bytes = static_cast<size_t>(width) * height * (3 + 2 + 1);
  std::vector<char> buffer(frame_bytes, 'x');
  const std::string raw_path = path + ".raw";
  const double r0 = now_s();
  FILE* raw = std::fopen(raw_path.c_str(), "wb");
  bool raw_ok = raw != nullptr;
  for (int k = 0; raw_ok && k < frames; ++k)
    raw_ok = std::fwrite(buffer.data(), 1, frame_bytes, raw) == frame_bytes;
  if (raw != nullptr && (std::fflush(raw) != 0 || std::fclose(raw) != 0)) raw_ok = false;
  const double raw_s = now_s() - r0;
  ::unlink(raw_path.c_str());
  if (!raw_ok) {
    std::fprintf(stderr, "hwr-bench record: cannot write %s\n", raw_path.c_str());
    return 1;
  }

  const double mb = static_cast<double>(c.bytes) * 1e-6;
  const double recorder_mb_s = mb / recorder_s;
  const double raw_mb_s = static_cast<double>(frame_bytes) * frames * 1e-6 / raw_s;
  const double needed_mb_s = static_cast<double>(c.bytes) / frames * 30.0 * 1e-6;
  std::printf("hwr-bench record: %d stereo frames %dx%d (%.2f MB each as recorded) -> %s\n", frames, width,
              height, mb / frames, dir.c_str());
  std::printf("%-34s %10s\n", "", "value");
  std::printf("%-34s %10.3f\n", "record_frame call (ms, median)", call_median_ms);
  std::printf("%-34s %10.1f\n", "recorder write rate (MB/s)", recorder_mb_s);
  std::printf("%-34s %10.1f\n", "plain fwrite, same bytes (MB/s)", raw_mb_s);
  std::printf("%-34s %10.2f\n", "recorder / fwrite", recorder_mb_s / raw_mb_s);
  std::printf("%-34s %10.1f\n", "needed live at 30 Hz (MB/s)", needed_mb_s);
  std::printf("record_frames=%d\nrecord_width=%d\nrecord_height=%d\n", frames, width, height);
  std::printf("record_call_ms=%.3f\nrecord_write_mb_s=%.1f\nrecord_fwrite_mb_s=%.1f\nrecord_vs_fwrite=%.2f\n",
              call_median_ms, recorder_mb_s, raw_mb_s, recorder_mb_s / raw_mb_s);
  std::printf("record_needed_mb_s_30hz=%.1f\n", needed_mb_s);
  return 0;
}

}  // namespace

HWR_BENCH_COMMAND(record, "record",
                  "hwr-robot --record: cost per frame, write rate vs plain fwrite, rate needed at 30 Hz",
                  run_record);

}  // namespace hwr::bench
