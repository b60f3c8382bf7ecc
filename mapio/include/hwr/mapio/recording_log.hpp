#pragma once
// A sensor recording (sensor_recorder.hpp; `hwr-robot --record FILE`) opened for replay as a
// hal::ReplayLog (`hwr-robot --source lcmlog:FILE`). The samples are read into memory at open; the
// frames stay on disk: open() reads only each image event's header (where it is, its size and time;
// the pixels are skipped), and the replay's prefetch thread reads them back one frame at a time.
// An image whose pixels were damaged after its header is found when its frame is loaded.
//
// Bad input loses nothing it need not: an event that does not decode (a damaged file) or an image
// of the wrong size or encoding is skipped and counted, a frame without its depth image is skipped,
// an event whose header LCM's reader refuses is skipped up to the next sync word (counted); a log
// cut short (the robot lost power while recording) ends at the last whole event. Errors: the file missing or
// unreadable (kNotFound / kIoError naming it), no HWR_RECORDING_INFO event first (not a recording:
// kParseError), or no samples at all.

#include <cstdint>
#include <string>

#include "hwr/core/status.hpp"
#include "hwr/hal/replay_source.hpp"

namespace hwr::mapio {

struct RecordingLogStats {
  uint64_t events = 0;
  uint64_t undecodable = 0;        // events whose message did not decode or held non-finite values
  uint64_t bad_images = 0;         // images of another size or encoding than the recording's camera
  uint64_t incomplete_frames = 0;  // a left image without its depth (or right, for stereo)
  uint64_t unknown_channels = 0;   // events on channels a recording does not use (kept out)
  uint64_t resyncs = 0;            // damaged event headers skipped to the next LCM sync word
};

// path: the log file. stats: what was skipped (may be null).
core::Expected<hal::ReplayLog> open_recording_log(const std::string& path,
                                                  RecordingLogStats* stats = nullptr);

}  // namespace hwr::mapio
