#pragma once
// hwr-ground's HTTP server for the browser viewer (issue #9; docs/ground_viewer.md): the built page
// from web_root and the JSON/binary API over the ground station's state. cpp-httplib (Debian
// libcpp-httplib-dev) runs the requests on its own threads; every read of the state and every
// command takes `state_mutex`, which the ground station's LCM loop holds while it changes the state.
// Segment clouds are decoded outside that lock and cached per segment revision.

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "hwr/core/status.hpp"
#include "viewer_state.hpp"

namespace hwr::ground {

struct ViewerServerConfig {
  std::string host = "127.0.0.1";  // loopback unless the operator asks for more
  int port = 8080;                 // 0: any free port (port() tells which)
  std::string web_root;            // the built page (toolchain/build-web.sh); "" or absent: a help page
  int64_t max_cache_points = 20'000'000;  // decoded segment points kept for the page
};

// "PORT" (loopback) or "HOST:PORT" -> host and port; kInvalidArgument naming what is wrong.
core::Status parse_http_address(const std::string& text, std::string* host, int* port);
// Whether a host string is a loopback address (127.0.0.0/8, ::1, localhost).
bool is_loopback_host(const std::string& host);

class ViewerServer {
 public:
  // Binds (kUnavailable when the address is taken or cannot be bound) and starts serving on a thread.
  static core::Expected<std::unique_ptr<ViewerServer>> start(const ViewerServerConfig& config,
                                                             mapio::GroundStation& station,
                                                             mapio::OperatorConsole& console,
                                                             const mapio::GroundTelemetry& telemetry,
                                                             std::mutex& state_mutex);
  ~ViewerServer();  // stops serving and joins the thread
  int port() const;
  const std::string& web_root() const;

  ViewerServer(const ViewerServer&) = delete;
  ViewerServer& operator=(const ViewerServer&) = delete;

 private:
  struct Impl;
  explicit ViewerServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hwr::ground
