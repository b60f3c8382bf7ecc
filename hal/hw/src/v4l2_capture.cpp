#include "hwr/hal/hw/v4l2_capture.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

namespace hwr::hal::hw {
namespace {

constexpr uint32_t kMaxBuffers = 32;  // VIDEO_MAX_FRAME in videodev2.h

std::string hex(uint32_t v) {
  char s[16];
  std::snprintf(s, sizeof s, "0x%x", v);
  return s;
}

// A fixed-size, possibly unterminated driver string (v4l2_capability.driver/card).
std::string fixed_string(const uint8_t* s, size_t cap) {
  const char* c = reinterpret_cast<const char*>(s);
  return std::string(c, strnlen(c, cap));
}

std::string fourcc(uint32_t f) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((f >> (8 * i)) & 0xFF);
    s[i] = std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return s;
}

// errno of a failed syscall on the device as a Status a person can act on. Arguments that need no
// allocation, so that building them cannot disturb errno before it is read; number >= 0 is appended
// to what (a buffer index, a rate).
core::Status errno_status(const std::string& dev, const char* what, int err, long number = -1) {
  std::string detail = dev + ": " + what;
  if (number >= 0) detail += " " + std::to_string(number);
  detail += std::string(": ") + std::strerror(err);
  switch (err) {
    case ENOENT:
      return core::NotFound(detail + " (is the camera plugged in? find_video_device names its node)");
    case EACCES:
    case EPERM:
      return core::IoError(detail + " (add the user to the video group: toolchain/deploy/99-hwr.rules)");
    case ENODEV:
    case ENXIO:
    case EIO:
      return core::Unavailable(detail + " (unplugged?)");
    case EBUSY:
      return core::Unavailable(detail + " (another process is using the camera: close other viewers)");
    case ENOTTY:
      return core::InvalidArgument(detail + " (not a V4L2 video device)");
    default:
      return core::IoError(detail);
  }
}

const char* timestamp_kind(uint32_t flags) {
  switch (flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) {
    case V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN:
      return "unknown clock";
    case V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC:
      return "monotonic";
    case V4L2_BUF_FLAG_TIMESTAMP_COPY:
      return "copied from the application";
    default:
      return "unrecognised clock";
  }
}

bool starts_with_ignore_case(const std::string& s, const std::string& prefix) {
  if (s.size() < prefix.size()) return false;
  for (size_t i = 0; i < prefix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[i])) !=
        std::tolower(static_cast<unsigned char>(prefix[i]))) {
      return false;
    }
  }
  return true;
}

// First line of a sysfs attribute, or nullopt when it cannot be read.
std::optional<std::string> read_first_line(const std::filesystem::path& p) {
  std::ifstream in(p);
  if (!in) return std::nullopt;
  std::string line;
  std::getline(in, line);
  while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
  return line;
}

// N of "videoN", or -1.
long video_number(const std::string& name) {
  if (name.size() <= 5 || name.compare(0, 5, "video") != 0) return -1;
  long n = 0;
  for (size_t i = 5; i < name.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(name[i])) || n > 1'000'000) return -1;
    n = n * 10 + (name[i] - '0');
  }
  return n;
}

}  // namespace

core::Expected<std::string> find_video_device(const std::string& sysfs_root, uint16_t vendor,
                                              uint16_t product) {
  namespace fs = std::filesystem;
  const fs::path class_dir = fs::path(sysfs_root) / "class" / "video4linux";
  char want[32];
  std::snprintf(want, sizeof want, "usb:v%04Xp%04X", vendor, product);  // modalias: usb:v2B03pF880d…
  char id[16];
  std::snprintf(id, sizeof id, "%04x:%04x", vendor, product);

  struct Node {
    long n;
    std::string seen;  // "video0 usb:v046Dp0825"
    bool match;
    bool primary;  // sysfs index 0 (or absent): the capture node, not uvcvideo's metadata node
  };
  std::vector<Node> nodes;
  std::error_code ec;
  fs::directory_iterator it(class_dir, ec);
  const bool class_dir_ok = !ec;
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long n = video_number(name);
    if (n < 0) continue;
    const std::optional<std::string> modalias = read_first_line(it->path() / "device" / "modalias");
    Node node{n, name, false, true};
    if (!modalias) {
      node.seen += " (no modalias)";
    } else {
      // usb:vVVVVpPPPP is all a person needs to tell devices apart; the rest is class codes.
      node.seen += " " + modalias->substr(0, starts_with_ignore_case(*modalias, "usb:") ? 14 : 24);
      node.match = starts_with_ignore_case(*modalias, want);
    }
    if (const auto index = read_first_line(it->path() / "index")) node.primary = (*index == "0");
    nodes.push_back(std::move(node));
  }
  std::sort(nodes.begin(), nodes.end(), [](const Node& a, const Node& b) { return a.n < b.n; });

  const Node* best = nullptr;
  for (const Node& node : nodes) {
    if (!node.match) continue;
    if (best == nullptr || (node.primary && !best->primary)) best = &node;
  }
  if (best != nullptr) return "/dev/video" + std::to_string(best->n);

  std::string found;
  for (const Node& node : nodes) found += (found.empty() ? "" : ", ") + node.seen;
  if (found.empty()) found = "none";
  if (!class_dir_ok) found += "; " + class_dir.string() + " is not readable: no V4L2 driver loaded?";
  const bool zed = vendor == 0x2b03;
  return core::NotFound(std::string("no video device with USB id ") + id + " under " + class_dir.string() +
                        " (found: " + found +
                        "): " + (zed ? "is the ZED 2i plugged in, on USB 3?" : "is the camera plugged in?"));
}

core::Expected<std::unique_ptr<V4l2Capture>> V4l2Capture::open(const V4l2CaptureConfig& config, PosixIo& io) {
  const std::string& dev = config.device;
  if (dev.empty()) return core::InvalidArgument("V4L2 capture: no device path (find_video_device gives one)");
  if (config.width <= 0 || config.height <= 0 || config.width % 2 != 0 || config.fps <= 0) {
    // YUYV packs two pixels in four bytes, so the width must be even.
    return core::InvalidArgument(dev + ": bad capture size/rate " + std::to_string(config.width) + "x" +
                                 std::to_string(config.height) + "@" + std::to_string(config.fps) +
                                 " (width both eyes and even, e.g. 2560x720@30)");
  }
  if (config.buffers < 2 || config.buffers > static_cast<int>(kMaxBuffers)) {
    return core::InvalidArgument(dev + ": buffers = " + std::to_string(config.buffers) + " (2..32)");
  }
  std::unique_ptr<V4l2Capture> cap(new V4l2Capture(config, io));
  if (core::Status st = cap->start(); !st.ok()) return st;  // the destructor undoes what start() did
  return cap;
}

V4l2Capture::~V4l2Capture() { stop(); }

void V4l2Capture::stop() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    io_.ioctl(fd_, VIDIOC_STREAMOFF, &type);  // fails harmlessly on an unplugged camera
    streaming_ = false;
  }
  for (Buffer& b : buffers_) {
    if (b.data != nullptr) io_.munmap(b.data, b.length);
    b = Buffer{};
  }
  io_.close(fd_);
  fd_ = -1;
}

core::Status V4l2Capture::start() {
  const std::string& dev = config_.device;
  const uint32_t width = static_cast<uint32_t>(config_.width);
  const uint32_t height = static_cast<uint32_t>(config_.height);
  // Non-blocking: DQBUF answers EAGAIN instead of waiting; poll() does the waiting, with a timeout.
  fd_ = io_.open(dev.c_str(), O_RDWR | O_NONBLOCK);
  if (fd_ < 0) return errno_status(dev, "open", errno);

  v4l2_capability cap{};
  if (io_.ioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0) return errno_status(dev, "VIDIOC_QUERYCAP", errno);
  // capabilities describes the whole physical device; device_caps this node (videodev2.h).
  const uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  const uint32_t need = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  if ((caps & need) != need) {
    std::string missing;
    if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) missing += " VIDEO_CAPTURE";
    if ((caps & V4L2_CAP_STREAMING) == 0) missing += " STREAMING";
    return core::InvalidArgument(dev + " (driver '" + fixed_string(cap.driver, sizeof cap.driver) +
                                 "', card '" + fixed_string(cap.card, sizeof cap.card) +
                                 "') cannot stream video: lacks" + missing + " (caps " + hex(caps) +
                                 "; a UVC camera's metadata node looks like this: use its capture node)");
  }

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = width;
  fmt.fmt.pix.height = height;
  fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_YUYV;  // hardware.md: the ZED 2i sends YUYV
  fmt.fmt.pix.field = V4L2_FIELD_ANY;
  const std::string asked = "YUYV " + std::to_string(width) + "x" + std::to_string(height);
  if (io_.ioctl(fd_, VIDIOC_S_FMT, &fmt) != 0)
    return errno_status(dev, "VIDIOC_S_FMT YUYV width", errno, config_.width);
  // S_FMT adjusts rather than fails: read back what was granted.
  if (fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_YUYV || fmt.fmt.pix.width != width ||
      fmt.fmt.pix.height != height) {
    return core::InvalidArgument(dev + ": asked for " + asked + ", the driver granted " +
                                 fourcc(fmt.fmt.pix.pixelformat) + " " + std::to_string(fmt.fmt.pix.width) +
                                 "x" + std::to_string(fmt.fmt.pix.height) +
                                 " (ZED 2i frames, both eyes: 4416x1242, 3840x1080, 2560x720, 1344x376; "
                                 "on USB 2 only 1344x376)");
  }
  stride_bytes_ = std::max<size_t>(fmt.fmt.pix.bytesperline, size_t{width} * 2);
  frame_bytes_ = stride_bytes_ * height;

  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  parm.parm.capture.timeperframe.numerator = 1;
  parm.parm.capture.timeperframe.denominator = static_cast<uint32_t>(config_.fps);
  if (io_.ioctl(fd_, VIDIOC_S_PARM, &parm) != 0) {
    return errno_status(dev, "VIDIOC_S_PARM fps", errno, config_.fps);
  }
  const v4l2_fract granted = parm.parm.capture.timeperframe;
  if ((parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0 && granted.numerator != 0) {
    granted_fps_ = static_cast<double>(granted.denominator) / granted.numerator;
  }

  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(config_.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (io_.ioctl(fd_, VIDIOC_REQBUFS, &req) != 0) return errno_status(dev, "VIDIOC_REQBUFS", errno);
  if (req.count < 2 || req.count > kMaxBuffers) {
    return core::Unavailable(dev + ": asked for " + std::to_string(config_.buffers) +
                             " mmap buffers, the driver granted " + std::to_string(req.count) +
                             " (2..32 needed: one held by the caller while the driver fills another; "
                             "out of memory?)");
  }
  buffers_.resize(req.count);
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.index = i;
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (io_.ioctl(fd_, VIDIOC_QUERYBUF, &buf) != 0) {
      return errno_status(dev, "VIDIOC_QUERYBUF", errno, i);
    }
    if (buf.length < frame_bytes_) {
      return core::IoError(dev + ": buffer " + std::to_string(i) + " holds " + std::to_string(buf.length) +
                           " bytes, a " + asked + " frame needs " + std::to_string(frame_bytes_));
    }
    void* p = io_.mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (p == MAP_FAILED) return errno_status(dev, "mmap buffer", errno, i);
    buffers_[i].data = static_cast<uint8_t*>(p);
    buffers_[i].length = buf.length;
  }
  for (uint32_t i = 0; i < req.count; ++i) HWR_RETURN_IF_ERROR(queue(i));

  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (io_.ioctl(fd_, VIDIOC_STREAMON, &type) != 0) return errno_status(dev, "VIDIOC_STREAMON", errno);
  streaming_ = true;
  return core::Status::Ok();
}

core::Status V4l2Capture::queue(uint32_t index) {
  v4l2_buffer buf{};
  buf.index = index;
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (io_.ioctl(fd_, VIDIOC_QBUF, &buf) != 0) {
    return errno_status(config_.device, "VIDIOC_QBUF", errno, index);
  }
  buffers_[index].queued = true;
  return core::Status::Ok();
}

core::Status V4l2Capture::requeue(const V4l2Frame& frame) {
  if (frame.index >= buffers_.size() || buffers_[frame.index].queued ||
      frame.data != buffers_[frame.index].data) {
    return core::InvalidArgument(
        config_.device + ": requeue of buffer " + std::to_string(frame.index) +
        " that the caller does not hold (requeued twice, or a frame of another capture?)");
  }
  return queue(frame.index);
}

core::Expected<std::optional<V4l2Frame>> V4l2Capture::dequeue(int timeout_ms) {
  const std::string& dev = config_.device;
  const bool any_queued =
      std::any_of(buffers_.begin(), buffers_.end(), [](const Buffer& b) { return b.queued; });
  if (!any_queued) {
    // vb2 answers poll() with POLLERR when nothing is queued, which would look like an unplug.
    return core::InvalidArgument(dev + ": all " + std::to_string(buffers_.size()) +
                                 " buffers are held by the caller: requeue() frames before dequeue()");
  }
  pollfd p{fd_, POLLIN, 0};
  const int r = io_.poll(&p, 1, timeout_ms);
  if (r < 0) return errno_status(dev, "poll", errno);
  if (r == 0) return std::optional<V4l2Frame>{};
  // vb2 reports a queue error (uvcvideo on disconnect) as POLLERR, an unregistered node as POLLHUP.
  if ((p.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
    return core::Unavailable(dev + ": the camera stopped streaming (poll revents " +
                             hex(uint32_t(p.revents)) + "): unplugged? reopen it");
  }
  if ((p.revents & POLLIN) == 0) return std::optional<V4l2Frame>{};

  // Buffers that are ready are examined without waiting again, at most one pass over the buffers
  // per call so that a driver completing only bad buffers cannot keep the caller here.
  for (size_t attempt = 0; attempt < buffers_.size(); ++attempt) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (io_.ioctl(fd_, VIDIOC_DQBUF, &buf) != 0) {
      const int err = errno;
      if (err == EAGAIN) return std::optional<V4l2Frame>{};
      return errno_status(dev, "VIDIOC_DQBUF", err);
    }
    if (buf.index >= buffers_.size() || !buffers_[buf.index].queued) {
      return core::Internal(dev + ": VIDIOC_DQBUF returned buffer " + std::to_string(buf.index) +
                            " that was not queued");
    }
    buffers_[buf.index].queued = false;

    // The driver numbers every frame it starts, so a gap is frames it had no buffer for (or lost).
    // A backwards step (counter restart) resynchronises without counting.
    if (have_sequence_ && buf.sequence != last_sequence_ + 1) {
      const uint32_t gap = buf.sequence - last_sequence_ - 1;
      if (gap < (1u << 31)) counters_.dropped += gap;
    }
    have_sequence_ = true;
    last_sequence_ = buf.sequence;

    // hardware.md: accept a buffer only when it is whole; uvcvideo marks a frame with lost or
    // corrupt packets V4L2_BUF_FLAG_ERROR, and a short one has a smaller bytesused.
    if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0 || buf.bytesused != frame_bytes_) {
      ++counters_.incomplete;
      HWR_RETURN_IF_ERROR(queue(buf.index));
      continue;
    }
    if ((buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
      ++counters_.bad_timestamps;
      HWR_RETURN_IF_ERROR(queue(buf.index));
      return core::CorruptData(
          dev + ": frame timestamps are not CLOCK_MONOTONIC: buffer flags " + hex(buf.flags) + " (" +
          timestamp_kind(buf.flags) +
          "); frames cannot be placed on the IMU clock (uvcvideo stamps CLOCK_MONOTONIC: "
          "check the driver and its clock parameter)");
    }
    V4l2Frame frame;
    frame.data = buffers_[buf.index].data;
    frame.bytes = buf.bytesused;
    frame.width = config_.width;
    frame.height = config_.height;
    frame.stride_bytes = stride_bytes_;
    frame.t_ns = static_cast<int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                 static_cast<int64_t>(buf.timestamp.tv_usec) * 1'000;
    frame.sequence = buf.sequence;
    frame.index = buf.index;
    ++counters_.frames;
    return std::optional<V4l2Frame>(frame);
  }
  return std::optional<V4l2Frame>{};
}

}  // namespace hwr::hal::hw
