#pragma once
// FakeUvcDevice: a PosixIo that plays the kernel's uvcvideo driver for a ZED 2i (V4L2 ioctls, mmap'd
// buffers, poll), so that V4l2Capture and the readers built on it run in the tests without a camera.
// Frames come from a script (ScriptFrame: timestamp, sequence, length, error flag) with a picture the
// test provides; knobs make the driver refuse, round or fail, and unplug the camera mid-stream.
// For tests only (GoogleTest: an unexpected call is a test failure).

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include <linux/videodev2.h>
#include <sys/mman.h>

#include "hwr/hal/hw/posix_io.hpp"

namespace hwr::hal::hw::test {

// One frame the fake driver completes, in the order given.
struct ScriptFrame {
  static constexpr uint32_t kWholeFrame = UINT32_MAX;  // bytesused = the format's sizeimage
  int64_t tv_sec = 0;
  int64_t tv_usec = 0;
  uint32_t sequence = 0;
  uint32_t bytesused = kWholeFrame;
  bool error = false;  // V4L2_BUF_FLAG_ERROR
  uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
};

inline ScriptFrame good(uint32_t sequence, int64_t tv_sec, int64_t tv_usec) {
  ScriptFrame f;
  f.sequence = sequence;
  f.tv_sec = tv_sec;
  f.tv_usec = tv_usec;
  return f;
}

// uvcvideo as seen through the V4L2 ioctls, for one ZED 2i at /dev/video2, in whatever YUYV size
// S_FMT asks for. Buffer ownership follows videobuf2: QBUF moves a buffer to the driver's queue, the
// driver fills queued buffers in FIFO order, DQBUF hands the oldest filled one back. Everything
// called is logged by name.
class FakeUvcDevice : public PosixIo {
 public:
  static constexpr int kFd = 7;
  static constexpr const char* kPath = "/dev/video2";
  enum class Unplug { kPollHangUp, kPollEnodev, kDqbufEnodev };
  enum class State { kUser, kQueued };

  // Knobs.
  uint32_t capabilities =
      V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING | V4L2_CAP_DEVICE_CAPS;
  uint32_t device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  uint32_t granted_pixelformat = V4L2_PIX_FMT_YUYV;
  uint32_t granted_width = 0;  // 0: as asked
  uint32_t granted_height = 0;
  uint32_t granted_fps = 0;  // 0: as asked
  uint32_t max_buffers = 32;
  int open_errno = 0;        // open() fails with this
  bool busy = false;         // S_FMT: another process streams (EBUSY)
  int fail_mmap_index = -1;  // this buffer's mmap fails with ENOMEM
  std::deque<ScriptFrame> script;
  // The picture: copied into each buffer as the driver completes it (as much as fits; empty: the
  // buffer keeps what it held). Then, with stamp_frames, the frame's sequence number goes into its
  // first 4 bytes and sequence * 7 + 1 into its last byte, so that a test can tell which frame a
  // pointer shows.
  std::vector<uint8_t> image;
  bool stamp_frames = true;
  bool unplugged = false;
  Unplug unplug_style = Unplug::kPollHangUp;

  // Observations.
  std::vector<std::string> log;
  int open_flags = 0;
  bool is_open = false;
  bool streaming = false;
  v4l2_pix_format asked_format{};
  v4l2_fract asked_timeperframe{};
  uint32_t asked_buffers = 0;
  uint32_t asked_memory = 0;

  struct Buf {
    std::vector<uint8_t> storage;
    State state = State::kUser;
    bool mapped = false;
  };
  std::vector<Buf> bufs;
  std::deque<uint32_t> incoming;  // queued, in QBUF order

  static uint32_t offset_of(uint32_t index) { return index * 0x400000u; }  // page-aligned, > sizeimage
  size_t mapped_count() const {
    size_t n = 0;
    for (const Buf& b : bufs) n += b.mapped ? 1 : 0;
    return n;
  }

  int open(const char* path, int flags) override {
    log.push_back("open");
    if (std::string(path) != kPath) return fail(ENOENT);
    if (open_errno != 0) return fail(open_errno);
    open_flags = flags;
    is_open = true;
    return kFd;
  }
  int close(int fd) override {
    log.push_back("close");
    EXPECT_EQ(fd, kFd);
    EXPECT_TRUE(is_open);
    is_open = false;
    return 0;
  }
  int poll(pollfd* fds, nfds_t nfds, int /*timeout_ms*/) override {
    log.push_back("poll");
    EXPECT_EQ(nfds, 1u);
    EXPECT_EQ(fds[0].fd, kFd);
    EXPECT_NE(fds[0].events & POLLIN, 0);
    fds[0].revents = 0;
    if (unplugged && unplug_style == Unplug::kPollEnodev) return fail(ENODEV);
    if (unplugged && unplug_style == Unplug::kPollHangUp) {
      fds[0].revents = POLLERR | POLLHUP;
      return 1;
    }
    if (unplugged) {  // kDqbufEnodev: poll still says readable, DQBUF fails
      fds[0].revents = POLLIN;
      return 1;
    }
    if (!streaming || incoming.empty()) {  // vb2_core_poll: nothing to wait for
      fds[0].revents = POLLERR;
      return 1;
    }
    if (script.empty()) return 0;  // timeout (the fake does not sleep)
    fds[0].revents = POLLIN | POLLRDNORM;
    return 1;
  }
  void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override {
    log.push_back("mmap");
    EXPECT_EQ(addr, nullptr);
    EXPECT_EQ(prot, PROT_READ | PROT_WRITE);
    EXPECT_EQ(flags, MAP_SHARED);
    EXPECT_EQ(fd, kFd);
    for (uint32_t i = 0; i < bufs.size(); ++i) {
      if (offset_of(i) == static_cast<uint32_t>(offset) && static_cast<int>(i) == fail_mmap_index) {
        errno = ENOMEM;
        return MAP_FAILED;
      }
      if (offset_of(i) == static_cast<uint32_t>(offset) && length == bufs[i].storage.size() &&
          !bufs[i].mapped) {
        bufs[i].mapped = true;
        return bufs[i].storage.data();
      }
    }
    ADD_FAILURE() << "mmap of an offset/length QUERYBUF did not give: " << offset << "/" << length;
    errno = EINVAL;
    return MAP_FAILED;
  }
  int munmap(void* addr, size_t length) override {
    log.push_back("munmap");
    for (Buf& b : bufs) {
      if (b.storage.data() == addr && b.mapped) {
        EXPECT_EQ(length, b.storage.size());
        b.mapped = false;
        return 0;
      }
    }
    ADD_FAILURE() << "munmap of memory that is not mapped";
    return fail(EINVAL);
  }

  int ioctl(int fd, unsigned long request, void* arg) override {
    EXPECT_EQ(fd, kFd);
    EXPECT_TRUE(is_open);
    switch (request) {
      case VIDIOC_QUERYCAP:
        return querycap(static_cast<v4l2_capability*>(arg));
      case VIDIOC_S_FMT:
        return s_fmt(static_cast<v4l2_format*>(arg));
      case VIDIOC_S_PARM:
        return s_parm(static_cast<v4l2_streamparm*>(arg));
      case VIDIOC_REQBUFS:
        return reqbufs(static_cast<v4l2_requestbuffers*>(arg));
      case VIDIOC_QUERYBUF:
        return querybuf(static_cast<v4l2_buffer*>(arg));
      case VIDIOC_QBUF:
        return qbuf(static_cast<v4l2_buffer*>(arg));
      case VIDIOC_DQBUF:
        return dqbuf(static_cast<v4l2_buffer*>(arg));
      case VIDIOC_STREAMON:
        return stream(static_cast<int*>(arg), true);
      case VIDIOC_STREAMOFF:
        return stream(static_cast<int*>(arg), false);
      default:
        log.push_back("ioctl?");
        return fail(ENOTTY);
    }
  }

 private:
  static int fail(int err) {
    errno = err;
    return -1;
  }
  int gone() { return unplugged ? fail(ENODEV) : 0; }

  int querycap(v4l2_capability* cap) {
    log.push_back("QUERYCAP");
    *cap = v4l2_capability{};
    std::strncpy(reinterpret_cast<char*>(cap->driver), "uvcvideo", sizeof cap->driver);
    std::strncpy(reinterpret_cast<char*>(cap->card), "ZED 2i: ZED 2i", sizeof cap->card);
    std::strncpy(reinterpret_cast<char*>(cap->bus_info), "usb-3610000.xhci-2", sizeof cap->bus_info);
    cap->capabilities = capabilities;
    cap->device_caps = device_caps;
    return 0;
  }
  int s_fmt(v4l2_format* f) {
    log.push_back("S_FMT");
    EXPECT_EQ(f->type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    EXPECT_FALSE(streaming);
    asked_format = f->fmt.pix;
    if (busy) return fail(EBUSY);
    v4l2_pix_format& p = f->fmt.pix;
    p.pixelformat = granted_pixelformat;
    if (granted_width != 0) p.width = granted_width;
    if (granted_height != 0) p.height = granted_height;
    p.field = V4L2_FIELD_NONE;
    p.bytesperline = p.width * 2;
    p.sizeimage = p.bytesperline * p.height;
    sizeimage_ = p.sizeimage;
    return 0;
  }
  int s_parm(v4l2_streamparm* s) {
    log.push_back("S_PARM");
    EXPECT_EQ(s->type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    asked_timeperframe = s->parm.capture.timeperframe;
    s->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
    if (granted_fps != 0) s->parm.capture.timeperframe = v4l2_fract{1, granted_fps};
    return 0;
  }
  int reqbufs(v4l2_requestbuffers* r) {
    log.push_back("REQBUFS");
    EXPECT_EQ(r->type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    asked_buffers = r->count;
    asked_memory = r->memory;
    r->count = std::min(r->count, max_buffers);
    bufs.assign(r->count, Buf{});
    for (Buf& b : bufs) b.storage.assign(sizeimage_, 0);
    incoming.clear();
    return 0;
  }
  int querybuf(v4l2_buffer* b) {
    log.push_back("QUERYBUF");
    EXPECT_EQ(b->type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    EXPECT_EQ(b->memory, V4L2_MEMORY_MMAP);
    if (b->index >= bufs.size()) return fail(EINVAL);
    b->length = static_cast<uint32_t>(bufs[b->index].storage.size());
    b->m.offset = offset_of(b->index);
    return 0;
  }
  int qbuf(v4l2_buffer* b) {
    log.push_back("QBUF");
    if (int r = gone(); r != 0) return r;
    EXPECT_EQ(b->type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    EXPECT_EQ(b->memory, V4L2_MEMORY_MMAP);
    if (b->index >= bufs.size()) return fail(EINVAL);
    EXPECT_EQ(bufs[b->index].state, State::kUser) << "QBUF of buffer " << b->index << " already queued";
    if (bufs[b->index].state == State::kQueued) return fail(EINVAL);
    bufs[b->index].state = State::kQueued;
    incoming.push_back(b->index);
    return 0;
  }
  int dqbuf(v4l2_buffer* b) {
    log.push_back("DQBUF");
    if (int r = gone(); r != 0) return r;
    if (!streaming) return fail(EINVAL);
    if (script.empty() || incoming.empty()) return fail(EAGAIN);
    const uint32_t index = incoming.front();
    incoming.pop_front();
    Buf& buf = bufs[index];
    // The driver only ever completes a buffer the application queued.
    EXPECT_EQ(buf.state, State::kQueued);
    const ScriptFrame f = script.front();
    script.pop_front();
    if (!image.empty()) {
      std::memcpy(buf.storage.data(), image.data(), std::min(image.size(), buf.storage.size()));
    }
    if (stamp_frames && buf.storage.size() >= sizeof f.sequence) {
      std::memcpy(buf.storage.data(), &f.sequence, sizeof f.sequence);
      buf.storage.back() = static_cast<uint8_t>(f.sequence * 7 + 1);
    }
    buf.state = State::kUser;
    const uint32_t in_type = b->type;
    const uint32_t in_memory = b->memory;
    *b = v4l2_buffer{};
    b->type = in_type;
    b->memory = in_memory;
    b->index = index;
    b->bytesused = f.bytesused == ScriptFrame::kWholeFrame ? sizeimage_ : f.bytesused;
    b->flags = f.timestamp_flags | V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TSTAMP_SRC_SOE |
               (f.error ? V4L2_BUF_FLAG_ERROR : 0u);
    b->field = V4L2_FIELD_NONE;
    b->timestamp.tv_sec = f.tv_sec;
    b->timestamp.tv_usec = f.tv_usec;
    b->sequence = f.sequence;
    b->m.offset = offset_of(index);
    b->length = static_cast<uint32_t>(buf.storage.size());
    return 0;
  }
  int stream(const int* type, bool on) {
    log.push_back(on ? "STREAMON" : "STREAMOFF");
    EXPECT_EQ(*type, V4L2_BUF_TYPE_VIDEO_CAPTURE);
    if (on && unplugged) return fail(ENODEV);
    streaming = on;
    if (!on) {  // vb2: STREAMOFF returns every buffer to the application
      for (Buf& b : bufs) b.state = State::kUser;
      incoming.clear();
    }
    return 0;
  }

  uint32_t sizeimage_ = 0;
};

}  // namespace hwr::hal::hw::test
