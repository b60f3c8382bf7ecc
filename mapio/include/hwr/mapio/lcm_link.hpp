#pragma once
// The LCM transport of the robot <-> ground-station link (docs/mapio.md). A thin owner of one
// lcm::LCM instance: raw-byte publish and subscribe, so every received message goes through the
// project's size-checked decoders (chunk_wire.hpp) instead of LCM's generated decode(), which
// trusts the length fields it reads.
//
// URLs: production is UDP multicast on the wired interface,
//   udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608
// (ttl=0 keeps packets on the local link's route; the multicast route must point at the wired
// interface, and net.core.rmem_max must allow recv_buf_size: docs/mapio.md). Tests use memq://
// (one process), file:// logs, and udpm:// only inside a private network namespace.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"

namespace lcm {
class LCM;
}

namespace hwr::mapio {

// Channel names (docs/mapio.md lists the message type of each).
inline constexpr const char* kChannelMapChunk = "HWR_MAP_CHUNK";
inline constexpr const char* kChannelMapAck = "HWR_MAP_ACK";
inline constexpr const char* kChannelPose = "HWR_POSE";
inline constexpr const char* kChannelStatus = "HWR_STATUS";
inline constexpr const char* kChannelDetection = "HWR_DETECTION";
inline constexpr const char* kChannelOperatorCommand = "HWR_OPERATOR_CMD";
inline constexpr const char* kChannelOperatorAck = "HWR_OPERATOR_ACK";
inline constexpr const char* kChannelKeyframeImage = "HWR_KEYFRAME_IMAGE";
inline constexpr const char* kChannelImu = "HWR_IMU";
inline constexpr const char* kChannelMag = "HWR_MAG";
inline constexpr const char* kChannelGnss = "HWR_GNSS";
inline constexpr const char* kChannelCamLeft = "HWR_CAM_LEFT";
inline constexpr const char* kChannelCamDepth = "HWR_CAM_DEPTH";
inline constexpr const char* kChannelCamRight = "HWR_CAM_RIGHT";
inline constexpr const char* kChannelRecordingInfo = "HWR_RECORDING_INFO";

// Production default (see above).
inline constexpr const char* kDefaultLinkUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class LcmLink {
 public:
  // data/size: the message bytes as received (not decoded); valid only during the call.
  using Handler = std::function<void(const uint8_t* data, size_t size)>;

  // Errors (kIoError): LCM cannot open the URL (bad provider, no multicast route, ...).
  static core::Expected<LcmLink> open(const std::string& url);

  // Publishes an already encoded message. kIoError when LCM refuses (e.g. a message over its
  // size limit, a socket error).
  core::Status publish_bytes(const char* channel, const void* data, size_t size);
  // Encodes an LCM generated type into a reusable buffer and publishes it.
  template <class Msg>
  core::Status publish(const char* channel, const Msg& msg) {
    const int n = msg.getEncodedSize();
    if (n < 0) return core::InvalidArgument(std::string("lcm: cannot size a message for ") + channel);
    if (buffer_.size() < static_cast<size_t>(n)) buffer_.resize(static_cast<size_t>(n));
    if (msg.encode(buffer_.data(), 0, n) != n)
      return core::InvalidArgument(std::string("lcm: cannot encode a message for ") + channel);
    return publish_bytes(channel, buffer_.data(), static_cast<size_t>(n));
  }
  // Handlers run inside handle() on the calling thread.
  void subscribe(const char* channel, Handler handler);
  // Dispatches at most one message, waiting up to timeout_ms. 1: one handled, 0: timed out,
  // error: the LCM socket failed.
  core::Expected<int> handle(int timeout_ms);
  // Dispatches everything already waiting (non-blocking); returns the count.
  core::Expected<int> drain();

  LcmLink(LcmLink&&) noexcept;
  LcmLink& operator=(LcmLink&&) noexcept;
  ~LcmLink();

 private:
  struct Subscription;
  explicit LcmLink(std::unique_ptr<lcm::LCM> lcm);
  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  std::vector<uint8_t> buffer_;
};

}  // namespace hwr::mapio
