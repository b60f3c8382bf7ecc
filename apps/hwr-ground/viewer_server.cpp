#include "viewer_server.hpp"

#include <arpa/inet.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <cstring>
#include <filesystem>
#include <map>
#include <thread>
#include <tuple>

#include <httplib.h>

#include "hwr/core/file_io.hpp"
#include "hwr/core/time.hpp"
#include "hwr/mapio/world_cloud.hpp"

namespace hwr::ground {
namespace {

using nlohmann::json;

constexpr const char* kJson = "application/json";

void send_json(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  // Invalid UTF-8 (a robot's text cut mid-character) is replaced, never an exception: the state stays
  // readable.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), kJson);
}

void send_error(httplib::Response& res, int status, const std::string& why) {
  send_json(res, status, {{"error", why}});
}

int http_status(const core::Status& st) {
  switch (st.code()) {
    case core::ErrorCode::kNotFound:
      return 404;
    case core::ErrorCode::kUnavailable:
      return 503;
    case core::ErrorCode::kInvalidArgument:
    case core::ErrorCode::kOutOfRange:
      return 400;
    default:
      return 500;
  }
}

// A decimal integer query parameter within [lo, hi]; false when absent, not an integer or outside.
bool int_param(const httplib::Request& req, const char* name, int64_t lo, int64_t hi, int64_t* out) {
  return req.has_param(name) && parse_decimal_int64(req.get_param_value(name), out) && *out >= lo &&
         *out <= hi;
}

const char* kHelpPage =
    "<!doctype html><html><head><meta charset=\"utf-8\"><title>hwr-ground</title></head><body>"
    "<h1>hwr-ground</h1><p>The viewer's page is not built. Run <code>./toolchain/build-web.sh</code> (after "
    "<code>./toolchain/install-deps.sh --with-web</code>), or start hwr-ground with <code>--web-root "
    "DIR</code>."
    "</p><p>The API works without it: <a href=\"/api/state\">/api/state</a>.</p></body></html>";

}  // namespace

core::Status parse_http_address(const std::string& text, std::string* host, int* port) {
  const size_t colon = text.rfind(':');
  std::string h = colon == std::string::npos ? "127.0.0.1" : text.substr(0, colon);
  const std::string p = colon == std::string::npos ? text : text.substr(colon + 1);
  if (h.size() >= 2 && h.front() == '[' && h.back() == ']') h = h.substr(1, h.size() - 2);
  size_t used = 0;
  long value = -1;
  try {
    value = std::stol(p, &used);
  } catch (...) {
    used = 0;
  }
  if (p.empty() || used != p.size() || value < 0 || value > 65535) {
    return core::InvalidArgument("--http '" + text + "': expected PORT or HOST:PORT with PORT 0..65535");
  }
  if (h.empty())
    return core::InvalidArgument("--http '" + text + "': empty host (expected PORT or HOST:PORT)");
  *host = h;
  *port = static_cast<int>(value);
  return core::Status::Ok();
}

bool is_loopback_host(const std::string& host) {
  if (host == "localhost" || host == "::1") return true;
  in_addr a{};
  return ::inet_pton(AF_INET, host.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

struct ViewerServer::Impl {
  ViewerServerConfig config;
  mapio::GroundStation& station;
  mapio::OperatorConsole& console;
  const mapio::GroundTelemetry& telemetry;
  std::mutex& state_mutex;
  LinkRateMeter rates;  // under state_mutex
  core::MonotonicClock clock;
  httplib::Server server;
  std::thread thread;
  std::atomic<bool> listening_done{false};  // listen_after_bind returned
  int port = 0;

  // Decoded segments: (robot, run, segment, version) -> the revision decoded and the cloud.
  using Key = std::tuple<std::string, int64_t, int32_t, int32_t>;
  struct Cached {
    int64_t revision = -1;
    uint64_t used = 0;
    std::shared_ptr<const mapio::WorldCloud> cloud;
  };
  std::mutex cache_mutex;
  std::map<Key, Cached> cache;  // under cache_mutex
  uint64_t uses = 0;            // under cache_mutex

  Impl(const ViewerServerConfig& c, mapio::GroundStation& s, mapio::OperatorConsole& o,
       const mapio::GroundTelemetry& t, std::mutex& m)
      : config(c), station(s), console(o), telemetry(t), state_mutex(m) {}

  ViewerSources sources() const { return {station, console, telemetry}; }

  core::Expected<std::shared_ptr<const mapio::WorldCloud>> segment_cloud(const Key& key) {
    const auto& [robot, run, segment, version] = key;
    int64_t revision = -1;
    {
      std::lock_guard<std::mutex> lock(state_mutex);
      for (const auto& s : station.store().segments(robot, run))
        if (s.segment_id == segment && s.version == version) revision = s.chunks_stored;
    }
    if (revision < 0)
      return core::NotFound("no segment " + std::to_string(segment) + " version " + std::to_string(version) +
                            " of " + robot + " run " + std::to_string(run));
    {
      std::lock_guard<std::mutex> lock(cache_mutex);
      auto it = cache.find(key);
      if (it != cache.end() && it->second.revision == revision) {
        it->second.used = ++uses;
        return it->second.cloud;
      }
    }
    std::vector<hwr_lcm::map_chunk_t> chunks;
    {
      std::lock_guard<std::mutex> lock(state_mutex);  // the LCM loop writes into the same folders
      HWR_RETURN_IF_ERROR(station.store().load_segment(robot, run, segment, version, &chunks));
    }
    auto cloud = std::make_shared<mapio::WorldCloud>();
    mapio::DecodedChunk scratch;
    HWR_RETURN_IF_ERROR(
        mapio::assemble_world_cloud(chunks, mapio::ChunkDecodeLimits{}, &scratch, cloud.get()));
    std::lock_guard<std::mutex> lock(cache_mutex);
    cache[key] = Cached{static_cast<int64_t>(chunks.size()), ++uses, cloud};
    // Over the budget: the least recently used clouds go (never the one just decoded).
    auto total = [&] {
      int64_t n = 0;
      for (const auto& [k, c] : cache) n += static_cast<int64_t>(c.cloud->size());
      return n;
    };
    while (cache.size() > 1 && total() > config.max_cache_points) {
      auto oldest = cache.end();
      for (auto it = cache.begin(); it != cache.end(); ++it)
        if (it->first != key && (oldest == cache.end() || it->second.used < oldest->second.used)) oldest = it;
      cache.erase(oldest);
    }
    return std::shared_ptr<const mapio::WorldCloud>(cloud);
  }

  void get_segment(const httplib::Request& req, httplib::Response& res) {
    constexpr int64_t kInt32Max = std::numeric_limits<int32_t>::max();
    int64_t run = 0, segment = 0, version = 0, max_points = 0;
    if (!req.has_param("robot") || !int_param(req, "run", 0, INT64_MAX, &run) ||
        !int_param(req, "segment", 0, kInt32Max, &segment) ||
        !int_param(req, "version", 0, kInt32Max, &version)) {
      return send_error(res, 400,
                        "segment: robot, run, segment and version are required (integers but robot)");
    }
    if (req.has_param("max_points") && !int_param(req, "max_points", 0, INT64_MAX, &max_points))
      return send_error(res, 400, "segment: max_points must be an integer");
    auto cloud = segment_cloud(
        {req.get_param_value("robot"), run, static_cast<int32_t>(segment), static_cast<int32_t>(version)});
    if (!cloud.ok()) return send_error(res, http_status(cloud.status()), cloud.status().message());
    mapio::WorldCloud thinned;
    const mapio::WorldCloud* out = cloud.value().get();
    if (max_points > 0 && static_cast<int64_t>(out->size()) > max_points) {
      mapio::thin_world_cloud(*out, max_points, &thinned);
      out = &thinned;
    }
    // "HWRS", format 1, n, total; n x 3 float32 (little-endian hosts: x86-64, aarch64); n x 3 uint8.
    const auto n = static_cast<uint32_t>(out->size()), total = static_cast<uint32_t>(cloud.value()->size());
    std::string body(16 + 12 * static_cast<size_t>(n) + 3 * static_cast<size_t>(n), '\0');
    const uint32_t header[4] = {0x53525748u /* "HWRS" */, 1u, n, total};
    std::memcpy(body.data(), header, sizeof header);
    std::memcpy(body.data() + 16, out->xyz.data(), 12 * static_cast<size_t>(n));
    std::memcpy(body.data() + 16 + 12 * static_cast<size_t>(n), out->rgb.data(), 3 * static_cast<size_t>(n));
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::move(body), "application/octet-stream");
  }

  void get_keyframe(const httplib::Request& req, httplib::Response& res) {
    int64_t t_ns = 0;
    if (!req.has_param("robot") || !int_param(req, "t_ns", 0, INT64_MAX, &t_ns))
      return send_error(res, 400, "keyframe: robot and t_ns are required");
    std::string path;
    {
      std::lock_guard<std::mutex> lock(state_mutex);
      if (const mapio::RobotTelemetry* t = telemetry.robot(req.get_param_value("robot")))
        for (const mapio::KeyframeImageInfo& kf : t->keyframes)
          if (kf.keyframe_t_ns == t_ns) path = kf.path;
    }
    if (path.empty()) return send_error(res, 404, "keyframe: no image of keyframe " + std::to_string(t_ns));
    std::string jpeg;
    const core::Status st = core::read_file(path, &jpeg);
    if (!st.ok()) return send_error(res, http_status(st), st.message());
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::move(jpeg), "image/jpeg");
  }

  void post_command(const httplib::Request& req, httplib::Response& res) {
    // Only a page of this server sends JSON here: a plain form or a no-cors fetch from another site
    // cannot set this type without a CORS preflight, which this server never answers.
    if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0)
      return send_error(res, 415, "command: the body must be sent as application/json");
    auto command = command_from_json(req.body);
    if (!command.ok()) return send_error(res, http_status(command.status()), command.status().message());
    core::Expected<int64_t> id = core::Internal("not sent");
    {
      std::lock_guard<std::mutex> lock(state_mutex);
      id = console.send(command.value());
    }
    if (!id.ok()) return send_error(res, http_status(id.status()), id.status().message());
    send_json(res, 200, {{"command_id", std::to_string(id.value())}});
  }

  // Whether a request's Host names this server. A loopback server answers only to its loopback names,
  // so that a page from elsewhere whose name was made to resolve to 127.0.0.1 (DNS rebinding) cannot
  // read the state or send commands; a server bound to another address takes any name.
  bool host_allowed(const httplib::Request& req) const {
    if (!is_loopback_host(config.host)) return true;
    const std::string host = req.get_header_value("Host");
    const std::string p = ":" + std::to_string(port);
    for (const std::string& name :
         {std::string("127.0.0.1"), std::string("localhost"), std::string("[::1]"), config.host})
      if (host == name + p) return true;
    return false;
  }

  void routes() {
    server.set_payload_max_length(64u << 10);  // a command is a few hundred bytes
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (host_allowed(req)) return httplib::Server::HandlerResponse::Unhandled;
      send_error(res, 403,
                 "Host '" + req.get_header_value("Host") + "' is not this server's loopback address");
      return httplib::Server::HandlerResponse::Handled;
    });
    server.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
      json body;
      {
        std::lock_guard<std::mutex> lock(state_mutex);
        body = state_json(sources(), &rates, clock.now_ns(), config.web_root);
      }
      send_json(res, 200, body);
    });
    server.Get("/api/trajectory", [this](const httplib::Request& req, httplib::Response& res) {
      if (!req.has_param("robot")) return send_error(res, 400, "trajectory: robot is required");
      core::Expected<json> body = core::Internal("");
      {
        std::lock_guard<std::mutex> lock(state_mutex);
        body = trajectory_json(telemetry, req.get_param_value("robot"));
      }
      if (!body.ok()) return send_error(res, http_status(body.status()), body.status().message());
      send_json(res, 200, body.value());
    });
    server.Get("/api/segment",
               [this](const httplib::Request& req, httplib::Response& res) { get_segment(req, res); });
    server.Get("/api/keyframe",
               [this](const httplib::Request& req, httplib::Response& res) { get_keyframe(req, res); });
    server.Post("/api/command",
                [this](const httplib::Request& req, httplib::Response& res) { post_command(req, res); });
    const bool built = !config.web_root.empty() && std::filesystem::exists(config.web_root + "/index.html");
    if (built) {
      server.set_mount_point("/", config.web_root);
      // Revalidated on each load, so a rebuilt page is never served from a browser's stale copy.
      server.set_file_request_handler([](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-cache");
      });
    } else {
      server.Get("/", [](const httplib::Request&, httplib::Response& res) {
        res.set_content(kHelpPage, "text/html");
      });
    }
  }
};

ViewerServer::ViewerServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

core::Expected<std::unique_ptr<ViewerServer>> ViewerServer::start(const ViewerServerConfig& config,
                                                                  mapio::GroundStation& station,
                                                                  mapio::OperatorConsole& console,
                                                                  const mapio::GroundTelemetry& telemetry,
                                                                  std::mutex& state_mutex) {
  auto impl = std::make_unique<Impl>(config, station, console, telemetry, state_mutex);
  impl->routes();
  if (config.port == 0) {
    impl->port = impl->server.bind_to_any_port(config.host);
    if (impl->port <= 0) return core::Unavailable("http: cannot bind " + config.host + " to any port");
  } else {
    if (!impl->server.bind_to_port(config.host, config.port)) {
      return core::Unavailable("http: cannot bind " + config.host + ":" + std::to_string(config.port) +
                               " (in use, or not an address of this machine)");
    }
    impl->port = config.port;
  }
  Impl* raw = impl.get();
  impl->thread = std::thread([raw] {
    raw->server.listen_after_bind();
    raw->listening_done = true;
  });
  return std::unique_ptr<ViewerServer>(new ViewerServer(std::move(impl)));
}

ViewerServer::~ViewerServer() {
  // stop() does nothing before the listen loop runs, so it is repeated until the loop has returned.
  while (!impl_->listening_done) {
    impl_->server.stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (impl_->thread.joinable()) impl_->thread.join();
}

int ViewerServer::port() const { return impl_->port; }
const std::string& ViewerServer::web_root() const { return impl_->config.web_root; }

}  // namespace hwr::ground
