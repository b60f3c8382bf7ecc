#include "hwr/mapio/lcm_link.hpp"

#include <lcm/lcm-cpp.hpp>

namespace hwr::mapio {

struct LcmLink::Subscription {
  Handler handler;
  void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& /*channel*/) {
    handler(static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
  }
};

LcmLink::LcmLink(std::unique_ptr<lcm::LCM> lcm) : lcm_(std::move(lcm)) {}
LcmLink::LcmLink(LcmLink&&) noexcept = default;
LcmLink& LcmLink::operator=(LcmLink&&) noexcept = default;
LcmLink::~LcmLink() = default;

core::Expected<LcmLink> LcmLink::open(const std::string& url) {
  auto lcm = std::make_unique<lcm::LCM>(url);
  if (!lcm->good()) {
    return core::IoError("lcm: cannot open '" + url +
                         "' (bad URL, or for udpm:// no multicast route / interface; see docs/mapio.md)");
  }
  return LcmLink(std::move(lcm));
}

core::Status LcmLink::publish_bytes(const char* channel, const void* data, size_t size) {
  if (size > static_cast<size_t>(INT32_MAX)) return core::InvalidArgument("lcm: message too large");
  if (lcm_->publish(channel, data, static_cast<unsigned int>(size)) != 0) {
    return core::IoError(std::string("lcm: publish on ") + channel + " failed (" + std::to_string(size) +
                         " bytes)");
  }
  return core::Status::Ok();
}

void LcmLink::subscribe(const char* channel, Handler handler) {
  auto sub = std::make_unique<Subscription>();
  sub->handler = std::move(handler);
  lcm_->subscribe(channel, &Subscription::on_message, sub.get());
  subscriptions_.push_back(std::move(sub));
}

core::Expected<int> LcmLink::handle(int timeout_ms) {
  const int r = lcm_->handleTimeout(timeout_ms);
  if (r < 0) return core::IoError("lcm: receive failed");
  return r > 0 ? 1 : 0;
}

core::Expected<int> LcmLink::drain() {
  int n = 0;
  for (;;) {
    auto r = handle(0);
    if (!r.ok()) return r.status();
    if (r.value() == 0) return n;
    ++n;
  }
}

}  // namespace hwr::mapio
