// libFuzzer target: arbitrary bytes as a sensor recording (`hwr-robot --source lcmlog:FILE`,
// recording_log.hpp). The bytes are written to a file (open_recording_log reads a path through LCM's
// log reader), opened, and every indexed frame is loaded. Seeds: make_recording_seeds.cpp (small
// valid recordings). Findings: a crash, a sanitizer report, an allocation over the limits (a damaged
// length believed), an error without a message, samples out of time order, a frame that loads with
// the wrong size.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "hwr/mapio/recording_log.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/hwr_fuzz_recording_" + std::to_string(::getpid()) + ".lcmlog";
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  if (std::fclose(f) != 0) std::abort();

  hwr::mapio::RecordingLogStats stats;
  auto log = hwr::mapio::open_recording_log(path, &stats);
  if (!log.ok()) {
    if (log.status().message().empty()) std::abort();  // every refusal says why
    return 0;
  }
  for (size_t i = 1; i < log->imu.size(); ++i) {
    if (log->imu[i].t_ns <= log->imu[i - 1].t_ns) std::abort();
  }
  for (size_t i = 1; i < log->frame_t_ns.size(); ++i) {
    if (log->frame_t_ns[i] <= log->frame_t_ns[i - 1]) std::abort();
  }
  const hwr::hal::PinholeIntrinsics& K = log->info.intrinsics;
  for (size_t i = 0; i < log->frame_t_ns.size(); ++i) {
    hwr::hal::RgbdFrame frame;
    const hwr::core::Status st = log->load_frame(i, &frame);
    if (!st.ok()) {
      if (st.message().empty()) std::abort();
      continue;
    }
    if (frame.bgr.cols != K.width || frame.bgr.rows != K.height || frame.depth_m.cols != K.width ||
        frame.depth_m.rows != K.height || frame.t_ns != log->frame_t_ns[i]) {
      std::abort();
    }
  }
  return 0;
}
