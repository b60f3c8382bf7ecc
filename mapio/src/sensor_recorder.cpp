#include "hwr/mapio/sensor_recorder.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

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

// image_t.encoding (mapio/lcm/image_t.lcm).
constexpr int8_t kBgr8 = 0, kMono8 = 1, kDepthMm16 = 4;

// The image_t of an image (rows packed), its pixels copied into msg->data without reallocating when
// the vector is already large enough.
void fill_image(const cv::Mat& image, int64_t t_ns, int8_t encoding, hwr_lcm::image_t* msg) {
  const size_t row_bytes = image.cols * image.elemSize();
  msg->t_ns = t_ns;
  msg->width = image.cols;
  msg->height = image.rows;
  msg->row_stride = static_cast<int32_t>(row_bytes);
  msg->encoding = encoding;
  msg->size = static_cast<int32_t>(row_bytes * image.rows);
  msg->data.resize(static_cast<size_t>(msg->size));
  for (int y = 0; y < image.rows; ++y) std::memcpy(msg->data.data() + y * row_bytes, image.ptr(y), row_bytes);
}

}  // namespace

SensorRecorder::SensorRecorder(const std::string& path, const hal::SourceInfo& info,
                               const SensorRecorderConfig& config)
    : path_(path),
      info_(info),
      wait_when_full_(config.wait_when_full),
      imu_(config.imu_capacity),
      mag_(config.mag_capacity),
      gnss_(config.gnss_capacity),
      frames_(config.frame_slots),
      slots_(config.frame_slots),
      image_(std::make_unique<hwr_lcm::image_t>()) {}

core::Expected<std::unique_ptr<SensorRecorder>> SensorRecorder::open(const std::string& path,
                                                                     const hal::SourceInfo& info,
                                                                     const SensorRecorderConfig& config) {
  if (!info.intrinsics.valid()) {
    return core::InvalidArgument("--record " + path + ": the source has no camera intrinsics to record");
  }
  if (config.frame_slots == 0 || config.imu_capacity == 0) {
    return core::InvalidArgument("--record: the recorder needs room for at least one frame and sample");
  }
  std::unique_ptr<SensorRecorder> r(new SensorRecorder(path, info, config));
  errno = 0;
  r->log_ = std::make_unique<lcm::LogFile>(path, "w");
  if (!r->log_->good()) {
    r->log_.reset();
    return core::IoError("--record " + path + ": cannot create the log file" +
                         (errno != 0 ? std::string(" (") + std::strerror(errno) + ")" : std::string()));
  }
  // Every frame slot sized for the camera now and its pages touched (zeroed), so record_frame() only
  // copies: a first write into fresh pages cost 30 ms for a 1280x720 stereo frame (hwr-bench record).
  const int w = info.intrinsics.width, h = info.intrinsics.height;
  std::vector<FrameSlot*> all;
  for (size_t i = 0; i < config.frame_slots; ++i) {
    FrameSlot* s = r->slots_.acquire();
    s->bgr.create(h, w, CV_8UC3);
    s->depth_mm.create(h, w, CV_16UC1);
    s->beyond.create(h, w, CV_8UC1);
    if (info.stereo) s->right.create(h, w, CV_8UC1);
    for (cv::Mat* m : {&s->bgr, &s->depth_mm, &s->beyond, &s->right}) {
      if (!m->empty()) m->setTo(0);
    }
    all.push_back(s);
  }
  for (FrameSlot* s : all) r->slots_.release(s);
  r->buf_.reserve(static_cast<size_t>(w) * h * 3 + 4096);

  hwr_lcm::recording_info_t m;
  m.t_ns = info.first_t_ns;
  m.source_name = info.name;
  m.width = w;
  m.height = h;
  m.fx = info.intrinsics.fx;
  m.fy = info.intrinsics.fy;
  m.cx = info.intrinsics.cx;
  m.cy = info.intrinsics.cy;
  for (int i = 0; i < 5; ++i) m.distortion[i] = info.intrinsics.distortion[static_cast<size_t>(i)];
  const Eigen::Matrix4d T = info.T_imu_cam.matrix();
  for (int i = 0; i < 16; ++i) m.T_imu_cam[i] = T(i / 4, i % 4);
  for (int i = 0; i < 3; ++i) {
    m.gnss_antenna_imu_m[i] = info.gnss_antenna_imu_m[i];
    m.mag_hard_iron_ut[i] = info.mag_hard_iron_uT[i];
  }
  m.has_imu = info.has_imu ? 1 : 0;
  m.has_mag = info.has_mag ? 1 : 0;
  m.has_gnss = info.has_gnss ? 1 : 0;
  m.stereo = info.stereo ? 1 : 0;
  m.camera_rate_hz = info.camera_rate_hz;
  m.imu_rate_hz = info.imu_rate_hz;
  if (!r->write_message(kChannelRecordingInfo, info.first_t_ns, m)) {
    return core::IoError("--record " + path + ": cannot write to the log file");
  }
  r->writer_ = std::thread([p = r.get()]() { p->writer_loop(); });
  return r;
}

SensorRecorder::~SensorRecorder() { (void)close(); }

// Pushes v; waits for the writer when it is behind and config.wait_when_full, else drops.
template <class T>
bool SensorRecorder::push(core::SpscRing<T>* ring, const T& v) {
  while (!failed_.load(std::memory_order_relaxed)) {
    if (ring->try_push(v)) return true;
    if (!wait_when_full_) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  dropped_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

SensorRecorder::FrameSlot* SensorRecorder::acquire_slot() {
  while (!failed_.load(std::memory_order_relaxed)) {
    if (FrameSlot* s = slots_.acquire(); s != nullptr) return s;
    if (!wait_when_full_) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  return nullptr;
}

bool SensorRecorder::record_imu(const hal::ImuSample& s) { return push(&imu_, s); }
bool SensorRecorder::record_mag(const hal::MagSample& s) { return push(&mag_, s); }
bool SensorRecorder::record_gnss(const hal::GnssFix& s) { return push(&gnss_, s); }

bool SensorRecorder::record_frame(const hal::RgbdFrame& f) {
  const int w = info_.intrinsics.width, h = info_.intrinsics.height;
  const bool fits =
      f.bgr.type() == CV_8UC3 && f.bgr.cols == w && f.bgr.rows == h && f.depth_m.type() == CV_32FC1 &&
      f.depth_m.cols == w && f.depth_m.rows == h &&
      (!info_.stereo || (f.right_gray.type() == CV_8UC1 && f.right_gray.cols == w && f.right_gray.rows == h));
  FrameSlot* s = fits ? acquire_slot() : nullptr;
  if (s == nullptr) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  s->t_ns = f.t_ns;
  f.bgr.copyTo(s->bgr);
  // Metres → millimetres, rounded (convertTo saturates: NaN and ≤ 0 become 0, "none"); a depth past
  // the uint16 range would saturate to 65.535 m, a wrong depth, so it is set to none instead.
  f.depth_m.convertTo(s->depth_mm, CV_16U, 1000.0);
  cv::compare(f.depth_m, 65.535, s->beyond, cv::CMP_GT);
  s->depth_mm.setTo(0, s->beyond);
  if (info_.stereo) f.right_gray.copyTo(s->right);
  if (!frames_.try_push(s)) {  // cannot happen: the ring holds as many as there are slots
    slots_.release(s);
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  return true;
}

bool SensorRecorder::write_event(const char* channel, int64_t t_ns, const void* data, size_t size) {
  lcm::LogEvent e;
  e.eventnum = 0;  // numbered by LCM
  e.timestamp = t_ns / 1000;
  e.channel = channel;
  e.datalen = static_cast<int32_t>(size);
  e.data = const_cast<void*>(data);
  if (log_->writeEvent(&e) != 0) return false;
  bytes_.fetch_add(size, std::memory_order_relaxed);
  return true;
}

template <class Msg>
bool SensorRecorder::write_message(const char* channel, int64_t t_ns, const Msg& msg) {
  return detail::encode_lcm(msg, channel, &buf_).ok() && write_event(channel, t_ns, buf_.data(), buf_.size());
}

bool SensorRecorder::write_image(const char* channel, int64_t t_ns, const cv::Mat& image, int8_t encoding) {
  fill_image(image, t_ns, encoding, image_.get());
  return write_message(channel, t_ns, *image_);
}

// One pass over the queues; false on a write error.
bool SensorRecorder::drain_once() {
  hal::ImuSample imu;
  while (imu_.try_pop(imu)) {
    hwr_lcm::imu_t m;
    m.t_ns = imu.t_ns;
    for (int i = 0; i < 3; ++i) {
      m.accel_mps2[i] = imu.accel_mps2[i];
      m.gyro_radps[i] = imu.gyro_radps[i];
    }
    if (!write_message(kChannelImu, imu.t_ns, m)) return false;
    written_imu_.fetch_add(1, std::memory_order_relaxed);
  }
  hal::MagSample mag;
  while (mag_.try_pop(mag)) {
    hwr_lcm::mag_t m;
    m.t_ns = mag.t_ns;
    for (int i = 0; i < 3; ++i) m.field_ut[i] = mag.field_uT[i];
    if (!write_message(kChannelMag, mag.t_ns, m)) return false;
    written_mag_.fetch_add(1, std::memory_order_relaxed);
  }
  hal::GnssFix g;
  while (gnss_.try_pop(g)) {
    hwr_lcm::gnss_t m;
    m.t_ns = g.t_ns;
    m.latitude_deg = g.lat_deg;
    m.longitude_deg = g.lon_deg;
    m.height_m = g.height_m;
    m.fix_type = static_cast<int8_t>(g.fix_type);
    m.num_satellites = static_cast<int8_t>(std::min<int>(g.num_sv, 127));
    m.h_acc_m = g.h_acc_m;
    m.v_acc_m = g.v_acc_m;
    if (!write_message(kChannelGnss, g.t_ns, m)) return false;
    written_gnss_.fetch_add(1, std::memory_order_relaxed);
  }
  FrameSlot* s = nullptr;
  while (frames_.try_pop(s)) {
    const bool ok = write_image(kChannelCamLeft, s->t_ns, s->bgr, kBgr8) &&
                    write_image(kChannelCamDepth, s->t_ns, s->depth_mm, kDepthMm16) &&
                    (!info_.stereo || write_image(kChannelCamRight, s->t_ns, s->right, kMono8));
    slots_.release(s);
    if (!ok) return false;
    written_frames_.fetch_add(1, std::memory_order_relaxed);
  }
  return true;
}

void SensorRecorder::writer_loop() {
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    if (!drain_once()) {
      std::lock_guard<std::mutex> lock(error_mutex_);
      error_ = core::IoError("--record " + path_ +
                             ": writing the log failed (disk full?); the recording stops here");
      failed_.store(true, std::memory_order_relaxed);
      return;
    }
    if (stopping) return;  // drained after the stop request: everything recorded is written
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

core::Status SensorRecorder::close() {
  if (closed_) {
    std::lock_guard<std::mutex> lock(error_mutex_);
    return error_;
  }
  closed_ = true;
  stop_.store(true, std::memory_order_release);
  if (writer_.joinable()) writer_.join();
  if (log_ && log_->good() && std::fflush(log_->getFilePtr()) != 0) {
    std::lock_guard<std::mutex> lock(error_mutex_);
    if (error_.ok()) error_ = core::IoError("--record " + path_ + ": flushing the log failed (disk full?)");
  }
  log_.reset();
  std::lock_guard<std::mutex> lock(error_mutex_);
  return error_;
}

SensorRecorderCounters SensorRecorder::counters() const {
  SensorRecorderCounters c;
  c.imu = written_imu_.load(std::memory_order_relaxed);
  c.mag = written_mag_.load(std::memory_order_relaxed);
  c.gnss = written_gnss_.load(std::memory_order_relaxed);
  c.frames = written_frames_.load(std::memory_order_relaxed);
  c.dropped = dropped_.load(std::memory_order_relaxed);
  c.bytes = bytes_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace hwr::mapio
