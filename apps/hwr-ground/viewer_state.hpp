#pragma once
// What the viewer's page reads and sends (docs/ground_viewer.md): the ground station's state as JSON
// for GET /api/state and GET /api/trajectory, and a page's command (POST /api/command) as an
// operator_command_t. 64-bit ids and timestamps travel as decimal strings (a JavaScript number holds
// integers exactly only up to 2^53, and command ids are CLOCK_REALTIME nanoseconds).

#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "hwr/core/status.hpp"
#include "hwr/mapio/ground_station.hpp"
#include "hwr/mapio/ground_telemetry.hpp"
#include "hwr/mapio/operator_console.hpp"

namespace hwr::ground {

// A decimal integer: digits with an optional leading '-', nothing else, within int64_t (query
// parameters, 64-bit ids given as strings).
bool parse_decimal_int64(const std::string& text, int64_t* out);

// Payload bytes stored per robot over the last window_ns (steady clock): the link rate on the page.
class LinkRateMeter {
 public:
  explicit LinkRateMeter(int64_t window_ns = 5'000'000'000) : window_ns_(window_ns) {}
  // Records a stream's (a robot's run) stored byte count at now_ns and returns bytes/s over the window
  // (0 until two samples span some time; a count that went down starts the stream again).
  double update(const std::string& stream, int64_t bytes_stored, int64_t now_ns);

 private:
  int64_t window_ns_;
  std::map<std::string, std::deque<std::pair<int64_t, int64_t>>> samples_;  // (t_ns, bytes)
};

struct ViewerSources {
  const mapio::GroundStation& station;
  const mapio::OperatorConsole& console;
  const mapio::GroundTelemetry& telemetry;
};

// GET /api/state. now_ns: the steady clock (link ages, the rate meter).
nlohmann::json state_json(const ViewerSources& sources, LinkRateMeter* rates, int64_t now_ns,
                          const std::string& web_root);

// GET /api/trajectory?robot=R: camera positions of the robot's latest run, at most max_poses (evenly
// thinned, the newest kept). kNotFound for a robot without poses.
core::Expected<nlohmann::json> trajectory_json(const mapio::GroundTelemetry& telemetry,
                                               const std::string& robot_id, size_t max_poses = 20'000);

// POST /api/command's body to a command for OperatorConsole::send (which assigns its id). Errors name
// the field: kInvalidArgument / kOutOfRange.
core::Expected<hwr_lcm::operator_command_t> command_from_json(const std::string& body);

}  // namespace hwr::ground
