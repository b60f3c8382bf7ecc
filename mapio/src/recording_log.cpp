#include "hwr/mapio/recording_log.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <sys/stat.h>

#include <lcm/lcm-cpp.hpp>
#include <opencv2/core.hpp>

#include "hwr/mapio/lcm_link.hpp"
#include "lcm_reader.hpp"
#include "hwr_lcm/gnss_t.hpp"
#include "hwr_lcm/image_t.hpp"
#include "hwr_lcm/imu_t.hpp"
#include "hwr_lcm/mag_t.hpp"
#include "hwr_lcm/recording_info_t.hpp"

namespace hwr::mapio {
namespace {

// image_t.encoding (mapio/lcm/image_t.lcm) and what each holds per pixel.
constexpr int8_t kBgr8 = 0, kMono8 = 1, kDepthMm16 = 4;

// Decodes e into out; false also when the event's time stamp (µs) is not the message's t_ns (the
// recorder writes both), which catches most bit flips in either.
template <class Msg>
bool decode(const lcm::LogEvent& e, Msg* out) {
  return out->decode(e.data, 0, e.datalen) == e.datalen && e.timestamp == out->t_ns / 1000;
}

bool same_channel(const lcm::LogEvent& e, const char* channel) { return e.channel == channel; }

// image_t's fields before the pixels (mapio/lcm/image_t.lcm order).
struct ImageHeader {
  int64_t t_ns = 0;
  int32_t width = 0, height = 0, row_stride = 0, size = 0;
  int8_t encoding = 0;
};
constexpr size_t kImageHeaderBytes = 8 + 8 + 4 + 4 + 4 + 1 + 4;  // fingerprint ... size

// Walks image_t's header with the bounded reader (lcm_reader.hpp), so the pixel count is checked
// before LCM's generated decoder sizes its vector from it. pixel_bytes: what follows the header.
core::Status walk_image_header(const uint8_t* data, size_t size, size_t pixel_bytes, ImageHeader* h) {
  detail::BeReader r(data, size, "image_t");
  HWR_RETURN_IF_ERROR(r.check_fingerprint(hwr_lcm::image_t::getHash()));
  HWR_RETURN_IF_ERROR(r.i64(&h->t_ns, "t_ns"));
  HWR_RETURN_IF_ERROR(r.i32(&h->width, "width"));
  HWR_RETURN_IF_ERROR(r.i32(&h->height, "height"));
  HWR_RETURN_IF_ERROR(r.i32(&h->row_stride, "row_stride"));
  HWR_RETURN_IF_ERROR(r.need(1, "encoding"));
  h->encoding = static_cast<int8_t>(data[r.pos()]);
  HWR_RETURN_IF_ERROR(r.skip(1, "encoding"));
  HWR_RETURN_IF_ERROR(r.i32(&h->size, "size"));
  if (h->size < 0 || static_cast<size_t>(h->size) != pixel_bytes) {
    return core::ParseError("image_t: size " + std::to_string(h->size) + " but " +
                            std::to_string(pixel_bytes) + " pixel bytes follow");
  }
  return core::Status::Ok();
}

// image_t, header walked first (a damaged size would allocate gigabytes, or throw when negative).
bool decode_image(const lcm::LogEvent& e, hwr_lcm::image_t* out) {
  const auto* data = static_cast<const uint8_t*>(e.data);
  const auto size = static_cast<size_t>(e.datalen);
  ImageHeader h;
  return size >= kImageHeaderBytes && walk_image_header(data, size, size - kImageHeaderBytes, &h).ok() &&
         decode(e, out);
}

// recording_info_t, walked first: LCM's generated decoder copies length - 1 bytes of source_name, so a
// length of 0 or less (a damaged file; found by fuzz_recording_log) throws std::length_error.
bool decode_recording_info(const lcm::LogEvent& e, hwr_lcm::recording_info_t* out) {
  detail::BeReader r(static_cast<const uint8_t*>(e.data), static_cast<size_t>(e.datalen), "recording_info_t");
  return r.check_fingerprint(hwr_lcm::recording_info_t::getHash()).ok() && r.skip(8, "t_ns").ok() &&
         r.string(static_cast<size_t>(e.datalen), "source_name").ok() && decode(e, out);
}

// LCM log event header (LCM "Log File format", big-endian): sync word 0xEDA1DA01, event number
// (int64), timestamp (int64), channel length (int32), data length (int32), then channel and data.
constexpr uint32_t kSyncWord = 0xEDA1DA01u;
constexpr long kEventHeaderBytes = 28;

struct EventHeader {
  int64_t timestamp_us = 0;
  std::string channel;
  long data_at = 0;  // file offset of the message
  int32_t data_bytes = 0;
};

// Reads the event header at offset and its channel name, if it is one LCM's reader can take whole:
// the sync word, a channel name LCM accepts (1..999 bytes) and a data length that fits in the file.
// Checked before readNextEvent, which would otherwise allocate whatever a damaged length says.
// Leaves the file at offset.
bool read_event_header(FILE* f, long offset, long file_size, EventHeader* h) {
  uint8_t raw[kEventHeaderBytes];
  if (std::fseek(f, offset, SEEK_SET) != 0) return false;
  bool ok = std::fread(raw, 1, sizeof(raw), f) == sizeof(raw);
  int32_t sync = 0, channel_bytes = 0;
  int64_t eventnum = 0;
  detail::BeReader r(raw, sizeof(raw), "LCM log event");
  ok = ok && r.i32(&sync, "sync word").ok() && static_cast<uint32_t>(sync) == kSyncWord &&
       r.i64(&eventnum, "event number").ok() && r.i64(&h->timestamp_us, "timestamp").ok() &&
       r.i32(&channel_bytes, "channel length").ok() && r.i32(&h->data_bytes, "data length").ok() &&
       channel_bytes > 0 && channel_bytes < 1000 && h->data_bytes >= 0 &&
       static_cast<long>(h->data_bytes) <= file_size - offset - kEventHeaderBytes - channel_bytes;
  if (ok) {
    h->channel.resize(static_cast<size_t>(channel_bytes));
    ok = std::fread(h->channel.data(), 1, h->channel.size(), f) == h->channel.size();
    h->data_at = offset + kEventHeaderBytes + channel_bytes;
  }
  std::fseek(f, offset, SEEK_SET);
  return ok;
}

// After an event that is damaged or cut short, the position of the next event: the next sync word
// after from; -1 when none.
long next_sync_word(FILE* f, long from) {
  if (std::fseek(f, from, SEEK_SET) != 0) return -1;
  uint32_t window = 0;
  long pos = from;
  for (int c; (c = std::fgetc(f)) != EOF; ++pos) {
    window = (window << 8) | static_cast<uint32_t>(c);
    if (pos - from >= 3 && window == kSyncWord) return pos - 3;
  }
  return -1;
}

// Where a frame's images are in the file (ftell offsets of their events; -1: not seen).
struct FrameRef {
  long left = -1, depth = -1, right = -1;
};

// The open log and the frame index, shared by the replay's loader.
struct RecordingFile {
  std::unique_ptr<lcm::LogFile> file;
  std::vector<FrameRef> frames;
  hal::PinholeIntrinsics K;
  bool stereo = false;
  long file_size = 0;
  hwr_lcm::image_t image;  // scratch (the prefetch thread is the only caller)

  EventHeader header;  // scratch

  // Reads the image event at offset into image; checks it is w x h of the encoding.
  core::Status read_image(long offset, int8_t encoding, size_t i, const char* what) {
    if (!read_event_header(file->getFilePtr(), offset, file_size, &header)) {
      return core::CorruptData("frame " + std::to_string(i) + ": its " + what + " image event is gone");
    }
    const lcm::LogEvent* e = file->readNextEvent();
    if (e == nullptr || !decode_image(*e, &image)) {
      return core::CorruptData("frame " + std::to_string(i) + ": its " + what + " image no longer decodes");
    }
    const int bpp = encoding == kBgr8 ? 3 : encoding == kDepthMm16 ? 2 : 1;
    if (image.encoding != encoding || image.width != K.width || image.height != K.height ||
        image.row_stride != K.width * bpp || image.size != image.row_stride * image.height ||
        image.data.size() != static_cast<size_t>(image.size)) {
      return core::CorruptData("frame " + std::to_string(i) + ": its " + what + " image changed on disk");
    }
    return core::Status::Ok();
  }

  core::Status load(size_t i, hal::RgbdFrame* out) {
    const FrameRef& ref = frames[i];
    HWR_RETURN_IF_ERROR(read_image(ref.left, kBgr8, i, "left"));
    cv::Mat(K.height, K.width, CV_8UC3, image.data.data()).copyTo(out->bgr);
    HWR_RETURN_IF_ERROR(read_image(ref.depth, kDepthMm16, i, "depth"));
    const cv::Mat depth_mm(K.height, K.width, CV_16UC1, image.data.data());
    depth_mm.convertTo(out->depth_m, CV_32F, 1e-3);
    out->invalid_depth_px = static_cast<uint32_t>(depth_mm.total() - cv::countNonZero(depth_mm));
    if (stereo) {
      HWR_RETURN_IF_ERROR(read_image(ref.right, kMono8, i, "right"));
      cv::Mat(K.height, K.width, CV_8UC1, image.data.data()).copyTo(out->right_gray);
    }
    out->intrinsics = K;
    out->seq = i;
    return core::Status::Ok();
  }
};

hal::SourceInfo info_of(const hwr_lcm::recording_info_t& m, const std::string& path) {
  hal::SourceInfo info;
  info.name = "lcmlog:" + path + " (recorded from " + m.source_name + ")";
  info.intrinsics.width = m.width;
  info.intrinsics.height = m.height;
  info.intrinsics.fx = m.fx;
  info.intrinsics.fy = m.fy;
  info.intrinsics.cx = m.cx;
  info.intrinsics.cy = m.cy;
  for (int i = 0; i < 5; ++i) info.intrinsics.distortion[static_cast<size_t>(i)] = m.distortion[i];
  Eigen::Matrix4d T;
  for (int i = 0; i < 16; ++i) T(i / 4, i % 4) = m.T_imu_cam[i];
  info.T_imu_cam.matrix() = T;
  for (int i = 0; i < 3; ++i) {
    info.gnss_antenna_imu_m[i] = m.gnss_antenna_imu_m[i];
    info.mag_hard_iron_uT[i] = m.mag_hard_iron_ut[i];
  }
  info.has_imu = m.has_imu != 0;
  info.has_mag = m.has_mag != 0;
  info.has_gnss = m.has_gnss != 0;
  info.stereo = m.stereo != 0;
  info.camera_rate_hz = m.camera_rate_hz;
  info.imu_rate_hz = m.imu_rate_hz;
  return info;
}

template <class T>
void sort_by_time(std::vector<T>* v) {
  std::stable_sort(v->begin(), v->end(), [](const T& a, const T& b) { return a.t_ns < b.t_ns; });
  v->erase(std::unique(v->begin(), v->end(), [](const T& a, const T& b) { return a.t_ns == b.t_ns; }),
           v->end());
}

}  // namespace

core::Expected<hal::ReplayLog> open_recording_log(const std::string& path, RecordingLogStats* stats_out) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    return core::NotFound(path + ": no such file (source 'lcmlog:" + path + "')");
  auto rec = std::make_shared<RecordingFile>();
  rec->file = std::make_unique<lcm::LogFile>(path, "r");
  if (!rec->file->good()) return core::IoError(path + ": cannot open the recording for reading");
  FILE* f = rec->file->getFilePtr();
  RecordingLogStats stats;

  EventHeader header;
  const lcm::LogEvent* e =
      read_event_header(f, 0, st.st_size, &header) ? rec->file->readNextEvent() : nullptr;
  hwr_lcm::recording_info_t info_msg;
  if (e == nullptr || !same_channel(*e, kChannelRecordingInfo) || !decode_recording_info(*e, &info_msg)) {
    return core::ParseError(path + ": not a sensor recording (its first event is not a " +
                            std::string(kChannelRecordingInfo) +
                            " message; record one with hwr-robot --record)");
  }
  ++stats.events;
  hal::ReplayLog log;
  log.info = info_of(info_msg, path);
  const hal::PinholeIntrinsics& K = log.info.intrinsics;
  if (!K.valid() || K.width > 16384 || K.height > 16384) {
    return core::ParseError(path + ": the recording's camera size " + std::to_string(K.width) + "x" +
                            std::to_string(K.height) + " is not plausible");
  }
  rec->K = K;
  rec->file_size = static_cast<long>(st.st_size);
  rec->stereo = log.info.stereo;

  std::map<int64_t, FrameRef> frames;
  hwr_lcm::imu_t imu{};
  hwr_lcm::mag_t mag{};
  hwr_lcm::gnss_t gnss{};
  uint8_t image_header[kImageHeaderBytes];
  for (;;) {
    const long offset = std::ftell(f);
    if (offset < 0 || offset >= st.st_size) break;
    const bool whole = read_event_header(f, offset, st.st_size, &header);
    const bool left = header.channel == kChannelCamLeft, depth = header.channel == kChannelCamDepth;
    if (whole && (left || depth || header.channel == kChannelCamRight)) {
      // An image: indexed from its header, its pixels not read until the replay loads the frame.
      ++stats.events;
      ImageHeader h;
      const size_t bytes = static_cast<size_t>(header.data_bytes);
      const bool read = bytes >= kImageHeaderBytes && std::fseek(f, header.data_at, SEEK_SET) == 0 &&
                        std::fread(image_header, 1, kImageHeaderBytes, f) == kImageHeaderBytes;
      if (std::fseek(f, header.data_at + header.data_bytes, SEEK_SET) != 0) break;
      if (!read || !walk_image_header(image_header, kImageHeaderBytes, bytes - kImageHeaderBytes, &h).ok() ||
          header.timestamp_us != h.t_ns / 1000) {
        ++stats.undecodable;
        continue;
      }
      const int8_t encoding = left ? kBgr8 : depth ? kDepthMm16 : kMono8;
      const int bpp = left ? 3 : depth ? 2 : 1;
      if (h.encoding != encoding || h.width != K.width || h.height != K.height ||
          h.row_stride != K.width * bpp || h.size != h.row_stride * h.height) {
        ++stats.bad_images;
        continue;
      }
      FrameRef& ref = frames[h.t_ns];
      (left ? ref.left : depth ? ref.depth : ref.right) = offset;
      continue;
    }
    e = whole ? rec->file->readNextEvent() : nullptr;
    if (e == nullptr) {
      // A damaged event header or a last event cut short: go on from the next sync word.
      const long next = next_sync_word(f, offset + 1);
      if (next < 0 || std::fseek(f, next, SEEK_SET) != 0) break;
      ++stats.resyncs;
      continue;
    }
    ++stats.events;
    if (same_channel(*e, kChannelImu)) {
      if (!decode(*e, &imu)) {
        ++stats.undecodable;
        continue;
      }
      hal::ImuSample s;
      s.t_ns = imu.t_ns;
      s.accel_mps2 = Eigen::Vector3d(imu.accel_mps2[0], imu.accel_mps2[1], imu.accel_mps2[2]);
      s.gyro_radps = Eigen::Vector3d(imu.gyro_radps[0], imu.gyro_radps[1], imu.gyro_radps[2]);
      if (s.accel_mps2.allFinite() && s.gyro_radps.allFinite()) {
        log.imu.push_back(s);
      } else {
        ++stats.undecodable;
      }
    } else if (same_channel(*e, kChannelMag)) {
      if (!decode(*e, &mag)) {
        ++stats.undecodable;
        continue;
      }
      hal::MagSample s;
      s.t_ns = mag.t_ns;
      s.field_uT = Eigen::Vector3d(mag.field_ut[0], mag.field_ut[1], mag.field_ut[2]);
      if (s.field_uT.allFinite()) {
        log.mag.push_back(s);
      } else {
        ++stats.undecodable;
      }
    } else if (same_channel(*e, kChannelGnss)) {
      if (!decode(*e, &gnss)) {
        ++stats.undecodable;
        continue;
      }
      hal::GnssFix g;
      g.t_ns = gnss.t_ns;
      g.lat_deg = gnss.latitude_deg;
      g.lon_deg = gnss.longitude_deg;
      g.height_m = gnss.height_m;
      g.fix_type = static_cast<uint8_t>(std::max<int8_t>(gnss.fix_type, 0));
      g.num_sv = static_cast<uint8_t>(std::max<int8_t>(gnss.num_satellites, 0));
      g.h_acc_m = gnss.h_acc_m;
      g.v_acc_m = gnss.v_acc_m;
      if (std::isfinite(g.lat_deg) && std::isfinite(g.lon_deg) && std::isfinite(g.height_m) &&
          std::fabs(g.lat_deg) <= 90 && std::fabs(g.lon_deg) <= 180) {
        log.gnss.push_back(g);
      } else {
        ++stats.undecodable;
      }
    } else if (!same_channel(*e, kChannelRecordingInfo)) {
      ++stats.unknown_channels;
    }
  }
  sort_by_time(&log.imu);
  sort_by_time(&log.mag);
  sort_by_time(&log.gnss);
  for (const auto& [t_ns, ref] : frames) {  // std::map: time order, one entry per t_ns
    if (ref.left < 0 || ref.depth < 0 || (rec->stereo && ref.right < 0)) {
      ++stats.incomplete_frames;
      continue;
    }
    log.frame_t_ns.push_back(t_ns);
    rec->frames.push_back(ref);
  }
  if (stats_out != nullptr) *stats_out = stats;
  if (log.frame_t_ns.empty() && log.imu.empty()) {
    return core::ParseError(path + ": the recording holds no frames and no IMU samples");
  }
  int64_t first = INT64_MAX, last = INT64_MIN;
  auto span = [&](int64_t t) {
    first = std::min(first, t);
    last = std::max(last, t);
  };
  if (!log.frame_t_ns.empty()) {
    span(log.frame_t_ns.front());
    span(log.frame_t_ns.back());
  }
  if (!log.imu.empty()) {
    span(log.imu.front().t_ns);
    span(log.imu.back().t_ns);
  }
  if (!log.mag.empty()) {
    span(log.mag.front().t_ns);
    span(log.mag.back().t_ns);
  }
  if (!log.gnss.empty()) {
    span(log.gnss.front().t_ns);
    span(log.gnss.back().t_ns);
  }
  log.info.first_t_ns = first;
  log.info.last_t_ns = last;
  log.info.has_imu = log.info.has_imu && !log.imu.empty();
  log.info.has_mag = log.info.has_mag && !log.mag.empty();
  log.info.has_gnss = log.info.has_gnss && !log.gnss.empty();
  // Frames are stamped from the index (each image's own t_ns is the same).
  std::vector<int64_t> stamps = log.frame_t_ns;
  log.load_frame = [rec, stamps](size_t i, hal::RgbdFrame* out) {
    if (i >= rec->frames.size())
      return core::InvalidArgument("frame " + std::to_string(i) + ": past the end");
    HWR_RETURN_IF_ERROR(rec->load(i, out));
    out->t_ns = stamps[i];
    return core::Status::Ok();
  };
  return log;
}

}  // namespace hwr::mapio
